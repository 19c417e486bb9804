"""``robointel plan`` and the planning demo stage."""
from __future__ import annotations

import numpy as np
from typer.testing import CliRunner

from robointel.io.trajectory import load_trajectory


def test_plan_command_writes_trajectory_and_plots(tmp_path):
    from robointel.cli import app

    out = tmp_path / "traj.npz"
    r = CliRunner().invoke(app, ["plan", "table71", "--out", str(out)])
    assert r.exit_code == 0, r.output
    tr = load_trajectory(out)
    assert tr.q.shape[1] == 6 and tr.duration < 15.0
    assert (tmp_path / "traj_profiles.png").stat().st_size > 10_000
    assert (tmp_path / "traj_path3d.png").stat().st_size > 10_000
    np.testing.assert_allclose(tr.qd[[0, -1]], 0.0, atol=1e-12)


def test_plan_command_reports_bad_scene(tmp_path):
    from robointel.cli import app

    bad = tmp_path / "bad.yaml"
    bad.write_text("robot: lrmate200id7l\ndt: 0.1\nwaypoints:\n  - {q_deg: [0, 0, 0, 0, .nan, 0]}\n"
                   "  - {q_deg: [0, 0, 0, 0, 0, 0]}\n")
    r = CliRunner().invoke(app, ["plan", str(bad), "--out", str(tmp_path / "t.npz")])
    assert r.exit_code == 2 and "error" in r.output


def test_demo_stage_quick(tmp_path):
    from robointel.commands.planning import demo_stage
    from robointel.report.demo import StageContext

    res = demo_stage(StageContext(out=tmp_path, quick=True, advance=lambda f, s="": None))
    names = [f.name for f in res.figures]
    assert any("blocked segment 3" in n for n in names) and any("operational time" in n for n in names)
    assert all(p.exists() for p in res.images)
