import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from robointel.cli import app
from robointel.errors import InvalidInput
from robointel.geometry import obstacle_from_dict
from robointel.outcome import Failure
from robointel.program import (
    STEP_KINDS,
    GraspCell,
    ProgramRejected,
    SimCell,
    check_program,
    load_program,
    program_from_dict,
    run_program,
)
from robointel.sim import Workcell

BOX = {"type": "box", "name": "wall", "center": [0.50, 0.00, 0.15], "size": [0.30, 0.10, 0.30]}
HOME = [0.0, 0.3, -23.8, 0.0, -65.8, 0.0]


def small_program(steps, obstacles=(BOX,)):
    return program_from_dict({
        "name": "t", "scene": {"robot": "lrmate200id7l", "d_min": 0.03, "obstacles": list(obstacles),
                               "limits": {"velocity_scale": 0.5, "acceleration_scale": 0.5}},
        "waypoints": {"home": {"q_deg": HOME}, "left": {"q_deg": [35.0, 56.3, -11.0, 0.0, -22.7, -0.6]},
                      "right": {"q_deg": [-24.4, 55.9, -12.1, 0.0, -22.0, 1.5]}},
        "steps": steps})


@pytest.fixture(scope="module")
def example_run():
    prog = load_program("moves")
    q0 = prog.initial_configuration()
    cell = SimCell(prog, q0)
    return prog, cell, run_program(prog, cell)


def test_example_program_runs_every_step_and_reaches_its_targets(example_run):
    prog, cell, run = example_run
    assert run.success, run.outcome
    assert [r.name for r in run.steps] == [s.name for s in prog.steps]
    assert {r.kind for r in run.steps} == {"move", "path", "wait", "set_io"}
    assert cell.io == {"gripper": 0.0}
    # the robot ends at the last waypoint (servo tracking, not teleported)
    assert np.max(np.abs(cell.q - prog.waypoints["back"])) < 0.01
    # every planned motion keeps its clearance on the dense check
    for s, p in zip(prog.steps, run.check.plans):
        if p.trajectory is not None:
            assert p.min_clearance_m >= prog.scene.d_min - 1e-3, s.name
    # the path step passes its key points: the TCP comes within 1 cm of each
    i = prog.index("scan")
    tcp = np.array([prog.robot.fk(q)[:3, 3] for q in run.steps[i].executed[::10]])
    for point in prog.steps[i].args["points"]:
        assert np.min(np.linalg.norm(tcp - point, axis=1)) < 0.01


def test_pose_target_is_solved_by_ik_and_reached():
    T = {"xyz": [0.45, 0.25, 0.35], "rpy_deg": [0, 90, 0]}
    prog = small_program([{"move": "home"}, {"move": {"pose": T}, "name": "to_pose"}], obstacles=())
    q0 = prog.waypoints["home"]
    cell = SimCell(prog, q0)
    run = run_program(prog, cell)
    assert run.success
    assert np.linalg.norm(prog.robot.fk(cell.q)[:3, 3] - np.array(T["xyz"])) < 0.005


def test_unreachable_pose_is_refused_before_anything_moves():
    prog = small_program([{"move": "home"}, {"move": {"pose": {"xyz": [2.5, 0, 0.3]}}, "name": "too_far"}])
    cell = SimCell(prog, prog.waypoints["home"])
    q_before, t_before = cell.q, cell.workcell.time
    with pytest.raises(ProgramRejected, match="too_far"):
        run_program(prog, cell)
    assert cell.workcell.time == t_before and np.array_equal(cell.q, q_before)


def test_target_inside_an_obstacle_is_refused_naming_the_step_link_and_obstacle():
    prog = small_program([{"move": "home"}, {"move": {"pose": {"xyz": [0.5, 0.0, 0.2], "rpy_deg": [0, 180, 0]}},
                                             "name": "into_wall"}])
    with pytest.raises(ProgramRejected, match=r"into_wall.*wall") as err:
        check_program(prog, prog.waypoints["home"])
    assert err.value.value["step"] == 1


def test_unknown_waypoint_and_bad_steps_are_refused():
    with pytest.raises(ProgramRejected, match="nowhere"):
        check_program(small_program([{"move": "nowhere"}]), np.radians(HOME))
    with pytest.raises(InvalidInput, match="unknown step kind"):
        small_program([{"weld": {"seam": 1}}])
    with pytest.raises(InvalidInput, match="unknown insert keys"):
        small_program([{"insert": {"skill": "peg.h5", "force": 3}}])
    with pytest.raises(InvalidInput, match="exactly one kind"):
        small_program([{"move": "home", "wait": 1}])
    with pytest.raises(InvalidInput, match="wait seconds"):
        small_program([{"wait": -1}])


def test_a_collision_mid_run_stops_the_robot_and_names_the_step():
    # the program's scene does not know a post the real cell has: the check passes, the run must stop
    prog = small_program([{"move": "home"}, {"move": "left", "name": "to_left"}, {"move": "right", "name": "swing"}],
                         obstacles=())
    post = obstacle_from_dict({"type": "box", "name": "post", "center": [0.45, 0.0, 0.25], "size": [0.1, 0.1, 0.5]})
    wc = Workcell(prog.robot, obstacles=[post], ft_sensor=False, q0=prog.waypoints["home"])
    cell = SimCell(prog, prog.waypoints["home"], workcell=wc)
    run = run_program(prog, cell)
    assert not run.success
    failed = run.steps[-1]
    assert run.failed_step == failed.index and failed.kind == "move" and not failed.outcome.success
    assert run.outcome.reason is Failure.COLLISION and repr(failed.name) in run.outcome.detail
    assert "post" in run.outcome.detail
    assert len(run.steps) < len(prog.steps)  # nothing after the failed step ran
    assert not wc.contacts()  # it backed off the post
    q_stop = wc.q
    wc.hold(1.0)
    assert np.max(np.abs(wc.q - q_stop)) < 0.05  # held where it stopped
    assert np.max(np.abs(wc.qd)) < 0.05


def test_changed_scene_replans_the_motion(example_run):
    prog = small_program([{"move": "home"}, {"move": "left"}], obstacles=())
    q0 = prog.waypoints["home"]
    chk = check_program(prog, q0)
    prog.scene.obstacles.append(obstacle_from_dict({"type": "sphere", "name": "ball", "center": [0.3, 0.3, 0.3],
                                                    "radius": 0.05}))
    wc = Workcell(prog.robot, obstacles=prog.scene.obstacles, ft_sensor=False, q0=q0)
    run = run_program(prog, SimCell(prog, q0, workcell=wc), check=chk)
    assert run.success and run.steps[1].replanned


def test_program_file_round_trip(tmp_path):
    prog = load_program("moves")
    path = prog.save(tmp_path / "p.yaml")
    back = load_program(path)
    assert [s.to_dict() for s in back.steps] == [s.to_dict() for s in prog.steps]
    assert set(back.waypoints) == set(prog.waypoints)


def test_from_step_resumes_and_bad_step_name_errors():
    prog = load_program("moves")
    assert prog.index("lift") == 4
    with pytest.raises(InvalidInput, match="no step named"):
        prog.index("fly")


def test_cli_run_and_refusal(tmp_path):
    runner = CliRunner()
    res = runner.invoke(app, ["run", "moves", "--report", str(tmp_path / "rep"), "--record", str(tmp_path / "r.mcap")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "rep" / "index.html").exists() and "home_again" in res.output
    from mcap.reader import make_reader

    with open(tmp_path / "r.mcap", "rb") as f:
        topics = [c.topic for _, c, _ in make_reader(f).iter_messages()]
    assert topics.count("/joint_states") > 500 and "/planned_trajectory" in topics
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"scene": "table71", "steps": [{"move": "home"},
                                                                 {"move": {"pose": {"xyz": [3, 0, 0]}}}]}))
    res = runner.invoke(app, ["run", str(bad)])
    out = " ".join(res.output.split())
    assert res.exit_code == 2 and "refused before moving" in out and "step 1" in out
    res = runner.invoke(app, ["run", str(tmp_path / "missing.yaml")])
    assert res.exit_code == 2 and "not found" in " ".join(res.output.split())


def test_a_program_with_every_step_kind_runs_in_the_simulated_cell(skill_files):
    d = yaml.safe_load(open(load_program("pick_place").source))
    d["steps"] += [{"path": {"points": [[0.45, 0.0, 0.50], [0.45, 0.08, 0.50]], "speed": 0.1}, "name": "scan"},
                   {"wait": 0.1, "name": "settle"}, {"set_io": {"lamp": 1}, "name": "lamp_on"},
                   {"guide": {"timeout": 5.0}, "name": "teach"},
                   {"grind": {"skill": str(skill_files["grind"])}, "name": "grind_plate"},
                   {"insert": {"skill": str(skill_files["insert"]), "time_limit": 3.0}, "name": "insert_peg"}]
    prog = program_from_dict(d)
    assert {s.kind for s in prog.steps} == set(STEP_KINDS)
    q0 = prog.initial_configuration()
    cell = GraspCell(prog, q0, seed=2)
    run = run_program(prog, cell)
    names = [r.name for r in run.steps]
    assert names == [s.name for s in prog.steps], run.outcome  # every step ran
    assert all(r.outcome.success for r in run.steps[:-1]), run.outcome
    # the part was picked, carried around the fixtures and set down at its target
    at = prog.steps[prog.index("place_part")].args["at"]
    p = cell.object_position(0)
    assert np.hypot(p[0] - at[0], p[1] - at[1]) < 0.03 and p[2] < 0.02  # resting on the table at the target
    assert cell.held is None and cell.io["gripper"] == 0.0 and cell.io["lamp"] == 1.0
    guided = run.steps[prog.index("teach")]
    assert guided.outcome.figures["guided_s"] > 0.5 and len(guided.executed) > 50
    assert run.steps[prog.index("grind_plate")].outcome.figures["rms_rel_setpoint"] < 0.15
    ins = run.steps[-1].outcome  # a real trial of the learned skill: seated, or stopped with the reason named
    assert ins.success or (ins.reason.value in ("wedged", "force_limit", "timeout") and "insert_peg" in
                           run.outcome.detail and ins.figures["held_speed_rad_s"] < 0.05)


def test_a_part_lost_mid_run_fails_the_place_step_and_stops():
    prog = load_program("pick_place")
    q0 = prog.initial_configuration()
    cell = GraspCell(prog, q0, seed=2)

    def knock_the_part_out(index, name):  # injected fault just before the carry: the part is gone from the hand
        if name == "place_part":
            a = cell._objq[0]
            cell.data.qpos[a:a + 3] = [0.75, 0.3, 0.05]
            cell.data.qvel[:] = 0.0

    run = run_program(prog, cell, progress=knock_the_part_out)
    assert not run.success and run.steps[-1].name == "place_part" and run.steps[1].outcome.success
    assert run.outcome.reason is Failure.SLIP and "place_part" in run.outcome.detail
    q = cell.q
    cell.hold(0.5)
    assert np.max(np.abs(cell.q - q)) < 0.01  # the robot holds still after the failed step
