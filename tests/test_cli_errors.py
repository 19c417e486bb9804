"""Misuse of the CLI: each bad argument or bad file is one ``error:`` line, exit code 2,
checked before the work starts (no traceback, no hang)."""
from __future__ import annotations

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from robointel.cli import app
from robointel.planning.scene import SCENES

runner = CliRunner()


def _one_line_error(args: list[str]) -> str:
    r = runner.invoke(app, args)
    assert r.exception is None or isinstance(r.exception, SystemExit), repr(r.exception)
    lines = [ln for ln in (r.stdout + r.stderr).splitlines() if ln.strip()]
    assert r.exit_code == 2, (args, r.exit_code, lines)
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    return lines[0]


@pytest.fixture()
def table71() -> dict:
    return yaml.safe_load((SCENES / "table71.yaml").read_text())


def test_teleop_port_out_of_range_is_refused_at_once():
    assert "--port" in _one_line_error(["teleop", "--port", "99999"])
    assert "--stream-port" in _one_line_error(["teleop", "--stream-port", "0"])


def test_guide_negative_duration_is_refused_at_once():
    assert "--duration" in _one_line_error(["guide", "--duration", "-1"])
    assert "--scenario" in _one_line_error(["guide", "--scenario", "7"])


def test_imitate_negative_latency_is_refused_at_once(tmp_path):
    out = tmp_path / "imitation"
    assert "--latency" in _one_line_error(["imitate", "synthetic", "--scara", "--latency", "-5", "--out", str(out)])
    assert not out.exists()                         # refused before any work


@pytest.mark.parametrize("edit, words", [
    (lambda d: d.update(steps="abc"), "steps"),
    (lambda d: d["waypoints"].__setitem__(1, {"name": "pick", "pose": 5}), "pose"),
    (lambda d: d.update(limits=[1, 2]), "limits"),
    (lambda d: d.update(d_min=int("1" + "0" * 400)), "d_min"),
])
def test_plan_bad_scene_files(table71, tmp_path, edit, words):
    edit(table71)
    p = tmp_path / "bad.yaml"
    p.write_text(yaml.safe_dump(table71))
    assert words in _one_line_error(["plan", str(p), "--no-plots", "--out", str(tmp_path / "t.npz")])


def test_plan_refuses_a_waypoint_inside_the_table(table71, tmp_path):
    table71["waypoints"][1] = {"name": "under", "q_deg": [0, 86, 0, 0, -29, 0]}   # TCP 0.13 m under the top
    p = tmp_path / "under.yaml"
    p.write_text(yaml.safe_dump(table71))
    line = _one_line_error(["plan", str(p), "--no-plots", "--out", str(tmp_path / "t.npz")])
    assert "under is in collision" in line and "link 'link_" in line and "'table'" in line


def test_grasp_transfer_db_not_hdf5(tmp_path):
    db = tmp_path / "notdb.h5"
    db.write_text("hello, not an HDF5 file\n")
    out = tmp_path / "transfer.png"
    assert "not a readable HDF5" in _one_line_error(["grasp", "transfer", "--db", str(db), "--out", str(out)])
    assert "does not exist" in _one_line_error(["grasp", "transfer", "--db", str(tmp_path / "none.h5")])
    assert not out.exists()


def test_learn_insertion_refuses_a_truncated_demonstration_file_before_the_work(tmp_path):
    from robointel.io.demonstrations import DemonstrationFile
    from robointel.learning.demonstration import Demonstration

    n = 50
    d = Demonstration.create(np.arange(n) * 0.01, np.tile(np.eye(4), (n, 1, 1)), np.zeros((n, 6)), name="d0")
    good = tmp_path / "demos.h5"
    DemonstrationFile(good).append(d)
    raw = good.read_bytes()
    bad = tmp_path / "truncated.h5"
    bad.write_bytes(raw[: len(raw) // 2])
    assert "truncated" in _one_line_error(["learn", "insertion", "--save", str(bad)])


def test_plan_execute_checks_the_table_even_when_the_scene_leaves_it_out(tmp_path):
    scene = {"name": "no_table", "robot": "lrmate200id7l", "table": False, "dt": 0.1, "steps": 10,
             "waypoints": [{"name": "home", "q_deg": [0, 0, -20, 0, -70, 0]},
                           {"name": "under", "q_deg": [0, 86, 0, 0, -29, 0]}]}
    p = tmp_path / "no_table.yaml"
    p.write_text(yaml.safe_dump(scene))
    r = runner.invoke(app, ["plan", str(p), "--no-plots", "--out", str(tmp_path / "t.npz"), "--execute"])
    lines = [ln for ln in (r.stdout + r.stderr).splitlines() if ln.strip()]
    assert r.exit_code == 2 and r.exception is None or isinstance(r.exception, SystemExit)
    assert lines[-1].startswith("error: planned trajectory rejected") and "'table'" in lines[-1]
    assert "MuJoCo" not in r.stdout                   # never tracked
