"""The insert, grind and guide steps, skill files, teaching into programs, and programs on a robot interface."""
import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from robointel.cli import app
from robointel.errors import InvalidInput
from robointel.learning.insertion import PegHole, RobotCell
from robointel.program import (
    ProgramRejected,
    PushOperator,
    SimCell,
    check_program,
    load_program,
    load_skill,
    path_step_from_guided,
    program_from_dict,
    program_from_teleop,
    run_program,
)
from robointel.teach.teleop_program import save_program
from robointel.testing.emulator import EmulatorProcess, protocol_violations

HOME = [0.0, 0.3, -23.8, 0.0, -65.8, 0.0]
LEFT = [35.0, 56.3, -11.0, 0.0, -22.7, -0.6]
SCENE = {"robot": "lrmate200id7l", "d_min": 0.03, "limits": {"velocity_scale": 0.5, "acceleration_scale": 0.5}}


def program(steps, tmp_path=None):
    d = {"name": "t", "scene": SCENE, "waypoints": {"home": {"q_deg": HOME}, "left": {"q_deg": LEFT}}, "steps": steps}
    if tmp_path is None:
        return program_from_dict(d)
    p = tmp_path / "prog.yaml"
    p.write_text(yaml.safe_dump(d))
    return load_program(p)


def test_skill_files_round_trip_the_fitted_skills(skill_files, tmp_path):
    ins, grind = skill_files["skills"]
    w = np.random.default_rng(0).normal(size=(20, 6)) * 5
    np.testing.assert_allclose(load_skill(skill_files["insert"]).predict(w), ins.predict(w), atol=1e-12)
    xy = np.random.default_rng(1).uniform(-0.08, 0.08, (20, 2))
    np.testing.assert_allclose(load_skill(skill_files["grind"]).predict(xy), grind.predict(xy), atol=1e-12)
    with pytest.raises(InvalidInput, match="not found"):
        load_skill(tmp_path / "none.h5")
    (tmp_path / "bad.h5").write_text("not hdf5")
    with pytest.raises(InvalidInput, match="cannot read"):
        load_skill(tmp_path / "bad.h5")


def test_a_missing_or_wrong_skill_file_is_refused_before_anything_moves(skill_files):
    prog = program([{"move": "home"}, {"insert": {"skill": "/nonexistent/peg.skill.h5"}, "name": "insert_peg"}])
    cell = SimCell(prog, prog.waypoints["home"])
    t0 = cell.workcell.time
    with pytest.raises(ProgramRejected, match=r"insert_peg.*not found") as err:
        run_program(prog, cell)
    assert err.value.value["step"] == 1 and cell.workcell.time == t0
    wrong = program([{"move": "home"}, {"grind": {"skill": str(skill_files["insert"])}, "name": "grind_plate"}])
    with pytest.raises(ProgramRejected, match=r"grind_plate.*insertion skill, not grinding"):
        check_program(wrong, wrong.waypoints["home"])
    with pytest.raises(InvalidInput, match="insert needs"):
        program([{"insert": "peg.h5"}])


def test_an_insertion_that_wedges_stops_the_robot_and_names_the_step(skill_files):
    prog = program([{"move": "home"}, {"insert": {"skill": str(skill_files["insert"]), "time_limit": 1.5},
                                       "name": "insert_peg"}, {"move": "left", "name": "after"}])
    cell = SimCell(prog, prog.waypoints["home"])
    cell.stations["insert"] = RobotCell(PegHole(), interference=5e-5)  # injected: an oversize peg cannot go in
    run = run_program(prog, cell)
    assert not run.success and run.steps[-1].name == "insert_peg" and len(run.steps) == 2
    assert "insert_peg" in run.outcome.detail and "insertion stopped" in run.outcome.detail
    assert run.steps[-1].outcome.figures["held_speed_rad_s"] < 0.05  # the station's arm stands still
    assert cell.stopped == "insert"


def test_the_insert_step_runs_at_its_fit_with_its_start_error_budget(skill_files):
    step = {"skill": str(skill_files["insert"]), "time_limit": 1.0}
    default = program([{"insert": step}]).steps[0].args  # the learning benchmark's task
    assert (default["clearance_mm"], default["lateral_error_mm"], default["tilt_error_deg"]) == (0.02, 2.0, 5.0)
    for bad in ({"clearance_mm": 2.0}, {"clearance_mm": 0}, {"tilt_error_deg": -1}, {"fit": 1}):
        with pytest.raises(InvalidInput, match="insert_peg") as err:
            program([{"insert": {**step, **bad}, "name": "insert_peg"}])
        assert err.value.value is not None
    budget = {"clearance_mm": 0.1, "lateral_error_mm": 0.5, "tilt_error_deg": 0.25}
    prog = program([{"insert": {**step, **budget}, "name": "insert_peg"}])
    assert program_from_dict(prog.to_dict()).steps[0].args == prog.steps[0].args  # round-trips
    run = run_program(prog, SimCell(prog, prog.waypoints["home"], seed=5))
    fig = run.steps[0].outcome.figures  # one real trial (seated or not within its 1 s): its station and start
    assert fig["clearance_um"] == pytest.approx(100.0)
    assert fig["start_tilt_deg"] <= 0.25 and fig["start_lateral_mm"] <= 0.5 * np.sqrt(2)


def test_guide_step_follows_the_operator_and_the_guided_path_becomes_a_path_step(tmp_path):
    prog = program([{"move": "home"}, {"guide": {"timeout": 5.0}, "name": "teach"}])
    q0 = prog.waypoints["home"]
    cell = SimCell(prog, q0, operator=PushOperator(force_n=(0.0, 20.0, 0.0), push_s=0.5, rest_s=0.4))
    run = run_program(prog, cell)
    assert run.success, run.outcome
    p0, p1 = prog.robot.fk(q0)[:3, 3], prog.robot.fk(cell.q)[:3, 3]
    d = p1 - p0
    assert d[1] > 0.02 and abs(d[0]) < 0.5 * d[1] and abs(d[2]) < 0.5 * d[1]  # moved along the push
    lead = cell.guided[0].lead
    assert 0.8 < run.steps[1].outcome.figures["guided_s"] < 1.0  # ended when continue was pressed
    step = path_step_from_guided(prog.robot, lead.t, lead.q, name="taught")
    P = step.args["points"]
    assert len(P) >= 2 and np.linalg.norm(P[-1] - P[0]) > 0.02
    # the taught path goes into a program, round-trips through its file and runs
    d = prog.to_dict()
    d["steps"] = [{"move": {"q": q0.tolist()}, "name": "start"}, step.to_dict()]
    path = tmp_path / "taught.yaml"
    path.write_text(yaml.safe_dump(d))
    back = load_program(path)
    np.testing.assert_allclose(back.steps[1].args["points"], P, atol=1e-9)
    run2 = run_program(back, SimCell(back, q0))
    assert run2.success, run2.outcome
    tcp = np.array([back.robot.fk(q)[:3, 3] for q in run2.steps[1].executed[::10]])
    assert np.min(np.linalg.norm(tcp - P[-1], axis=1)) < 0.01


def test_a_guide_the_operator_never_ends_times_out_and_stops():
    prog = program([{"move": "home"}, {"guide": {"timeout": 0.3}, "name": "teach"}])
    cell = SimCell(prog, prog.waypoints["home"], operator=PushOperator(push_s=0.1, rest_s=5.0))
    run = run_program(prog, cell)
    assert not run.success and run.failed_step == 1 and "continue" in run.outcome.detail


def test_a_teleop_recorded_program_round_trips_and_runs(tmp_path):
    from robointel.robot import Robot

    robot = Robot.load("lrmate200id7l")
    wps = [np.radians(HOME), np.radians(LEFT), np.radians([-24.4, 55.9, -12.1, 0.0, -22.0, 1.5])]
    tele = save_program(tmp_path / "teleop_program.yaml", robot, wps)  # what the teleoperation page writes
    prog = program_from_teleop(tele)
    assert [s.kind for s in prog.steps] == ["move"] * 3
    out = prog.save(tmp_path / "program.yaml")
    back = load_program(out)
    assert [s.to_dict() for s in back.steps] == [s.to_dict() for s in prog.steps]
    for k in ("wp0", "wp1", "wp2"):
        np.testing.assert_allclose(back.waypoints[k], prog.waypoints[k])
    cell = SimCell(back, back.initial_configuration())
    run = run_program(back, cell)
    assert run.success, run.outcome
    assert np.max(np.abs(cell.q - wps[-1])) < 0.01
    res = CliRunner().invoke(app, ["program-from-teleop", str(tele), str(tmp_path / "cli.yaml")])
    assert res.exit_code == 0 and load_program(tmp_path / "cli.yaml").steps[2].name == "to_wp2"


def test_run_on_the_fanuc_emulator_records_and_resumes(tmp_path):
    d = {"name": "t", "scene": SCENE, "waypoints": {"home": {"q_deg": HOME}, "left": {"q_deg": LEFT}},
         "steps": [{"move": "home", "name": "start"}, {"move": "left", "name": "reach"}, {"wait": 0.1},
                   {"move": "home", "name": "back"}]}
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump(d))
    runner = CliRunner()
    with EmulatorProcess(np.radians(HOME)) as emu:
        res = runner.invoke(app, ["run", str(path), "--robot", emu.url, "--record", str(tmp_path / "run.mcap"),
                                  "--report", str(tmp_path / "rep")])
        assert res.exit_code == 0, res.output
        q = np.radians(emu.call("q_meas_deg"))[:6]
        np.testing.assert_allclose(q, np.radians(HOME), atol=0.01)
        res = runner.invoke(app, ["run", str(path), "--robot", emu.url, "--from", "back", "--report",
                                  str(tmp_path / "rep2")])
        assert res.exit_code == 0, res.output
        assert "reach" not in res.output  # resumed at 'back'
        violations = protocol_violations(emu.call("violations"))
    assert violations == []
    from mcap.reader import make_reader

    with open(tmp_path / "run.mcap", "rb") as f:
        topics = {c.topic for _, c, _ in make_reader(f).iter_messages()}
    assert any("joint" in t for t in topics)


def test_a_program_with_simulated_cell_steps_is_refused_on_an_interface(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump({"scene": SCENE, "waypoints": {"home": {"q_deg": HOME}},
                                    "steps": [{"move": "home"}, {"guide": {}, "name": "teach"}]}))
    res = CliRunner().invoke(app, ["run", str(path), "--robot", "fanuc://127.0.0.1:1?sm_port=2"])
    assert res.exit_code == 2 and "teach" in " ".join(res.output.split())
