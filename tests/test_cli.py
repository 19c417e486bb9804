"""The robointel command: info, errors, and the demo's HTML report."""
from __future__ import annotations

from typer.testing import CliRunner

from robointel.cli import app

runner = CliRunner()


def test_info_lists_joints_limits_and_spheres():
    res = runner.invoke(app, ["info", "lrmate200id7l"])
    assert res.exit_code == 0, res.output
    for name in ("joint_1", "joint_6", "-170.0", "213.0", "spheres", "27.00 kg"):
        assert name in res.output


def test_info_unknown_robot_is_a_clear_error():
    res = runner.invoke(app, ["info", "no_such_robot"])
    assert res.exit_code == 2
    assert "unknown robot" in res.output


def test_core_demo_stage_writes_report(tmp_path):
    from robointel.commands import core
    from robointel.report.demo import run_demo

    index = run_demo([core.demo_stage], tmp_path, quick=True)
    html = index.read_text()
    assert "Robot core" in html and "tracking RMS" in html and "data:image/png;base64" in html
