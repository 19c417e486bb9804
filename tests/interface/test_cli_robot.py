"""``robointel plan --execute --robot fanuc://... --record run.mcap`` against the fake controller."""
from mcap.reader import make_reader
from typer.testing import CliRunner

from robointel.cli import app
from robointel.io.mcap_log import COMMAND, JOINT_STATES, TRAJECTORY
from robointel.planning.scene import load_scene
from robointel.testing.emulator import fanuc_url, running_fake


def test_plan_execute_on_fanuc_with_record(tmp_path):
    start = load_scene("table71").waypoints[0]
    with running_fake(start) as fake:
        out = CliRunner().invoke(app, ["plan", "table71", "--out", str(tmp_path / "t.npz"), "--no-plots", "--execute",
                                       "--robot", fanuc_url(fake), "--record", str(tmp_path / "run.mcap")])
        assert fake.violations == []
    assert out.exit_code == 0, out.output
    assert "missed cycles" in out.output
    with open(tmp_path / "run.mcap", "rb") as f:
        topics = {c.topic for c in make_reader(f).get_summary().channels.values()}
    assert topics == {JOINT_STATES, COMMAND, TRAJECTORY}


def test_bad_robot_url_is_a_clear_error(tmp_path):
    out = CliRunner().invoke(app, ["plan", "table71", "--out", str(tmp_path / "t.npz"), "--no-plots", "--execute",
                                   "--robot", "ur5://x"])
    assert out.exit_code == 2 and "unknown robot" in out.output


def test_guide_on_fanuc_without_force_telemetry_says_why():
    with running_fake() as fake:
        out = CliRunner().invoke(app, ["guide", "--robot", fanuc_url(fake), "--duration", "1"])
        assert fake.violations == []
    assert out.exit_code == 2 and "no F/T wrench" in out.output
