"""Teleoperation logic without a browser: IK on hand moves, unreachable not sent, program files."""
from __future__ import annotations

import time

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.teach.streaming import StreamingController
from robointel.teach.teleop import TeleopApp, load_program, save_program


@pytest.fixture()
def app(lrmate):
    ctrl = StreamingController(lrmate)
    a = TeleopApp(ctrl)   # not started: no page, the controller is stepped by hand
    yield a


def _wxyz_down():
    return np.array([np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0])  # Ry(pi/2): tool pointing down


def test_reachable_move_is_sent_unreachable_is_not(lrmate):
    # the deadman counts wall-clock time from the last send, but the loop is stepped by hand here: a loaded
    # host steps it slower than real time, so the page's keep-alive is sent between steps (a generous deadman
    # covers this process being descheduled in between), as the browser's keep-alive stream does
    app = TeleopApp(StreamingController(lrmate, deadman=5.0))
    assert app.move_hand([0.45, 0.1, 0.4], _wxyz_down())
    q1 = app.desired.copy()
    np.testing.assert_allclose(lrmate.fk(q1)[:3, 3], [0.45, 0.1, 0.4], atol=1e-9)
    assert app.sent == 1 and app.controller.accepted == 1
    assert not app.move_hand([2.0, 0.0, 0.4], _wxyz_down())
    assert app.sent == 1 and app.controller.accepted == 1 and app.unreachable_moves == 1
    np.testing.assert_array_equal(app.desired, q1)
    for _ in range(150):  # 1.5 s of control: the robot reaches the reachable target
        app.controller.heartbeat(app.client, time.perf_counter())
        app.controller.advance(10)
    np.testing.assert_allclose(app.controller.wc.q, q1, atol=2e-3)


def test_record_save_load_roundtrip(app, lrmate, tmp_path):
    for p in ([0.45, 0.1, 0.4], [0.40, -0.15, 0.3]):
        app.move_hand(p, _wxyz_down())
        app.record()
    path = app.save(tmp_path / "prog.yaml")
    prog = load_program(path)
    assert prog["robot"] == "lrmate200id7l" and prog["waypoints"].shape == (2, 6)
    np.testing.assert_allclose(prog["waypoints"], np.array(app.waypoints))
    import yaml
    doc = yaml.safe_load(path.read_text())
    np.testing.assert_allclose(doc["waypoints"][1]["tcp"]["position"], [0.40, -0.15, 0.3], atol=1e-9)
    # the planning scene loader (what `robointel plan` reads) accepts it
    from robointel.planning.scene import load_scene
    scene = load_scene(path)
    np.testing.assert_allclose(scene.waypoints, np.array(app.waypoints))
    assert scene.robot.name == "lrmate200id7l" and len(scene.steps) == 1
    app.clear()
    assert app.waypoints == []
    with pytest.raises(InvalidInput):
        app.save(tmp_path / "empty.yaml")


def test_save_rejects_out_of_limit_waypoint(lrmate, tmp_path):
    with pytest.raises(InvalidInput):
        save_program(tmp_path / "bad.yaml", lrmate, [np.zeros(6), np.array([4.0, 0, 0, 0, 0, 0])])
    with pytest.raises(InvalidInput, match="at least 2"):
        save_program(tmp_path / "one.yaml", lrmate, [np.zeros(6)])


def test_page_bind_needs_token(lrmate):
    with pytest.raises(InvalidInput, match="token"):
        TeleopApp(StreamingController.__new__(StreamingController), host="0.0.0.0")


def test_replay_reaches_waypoints_headless(app):
    app.controller.start()
    try:
        for p in ([0.45, 0.1, 0.4], [0.40, -0.15, 0.3]):
            app.move_hand(p, _wxyz_down())
            app.record()
        errs = app.replay(timeout_per_waypoint=5.0, dwell=0.05)
        assert len(errs) == 2 and max(errs) < 2e-3
    finally:
        app.controller.stop()


def test_cli_teleop_serves_and_refuses_remote_without_token():
    import socket

    from typer.testing import CliRunner

    from robointel.cli import app

    ports = []
    for _ in range(2):
        s = socket.socket()
        s.bind(("127.0.0.1", 0))
        ports.append(s.getsockname()[1])
        s.close()
    res = CliRunner().invoke(app, ["teleop", "--port", str(ports[0]), "--stream-port", str(ports[1]),
                                   "--duration", "0.5", "--program", "/tmp/never-written.yaml"])
    assert res.exit_code == 0, res.output
    assert f"http://127.0.0.1:{ports[0]}" in res.output and f"ws://127.0.0.1:{ports[1]}" in res.output
    res = CliRunner().invoke(app, ["teleop", "--host", "0.0.0.0", "--duration", "0.1"])
    assert res.exit_code == 2 and "token" in res.output


def test_saved_program_plans_with_robointel_plan(lrmate, tmp_path):
    from typer.testing import CliRunner

    from robointel.cli import app

    path = save_program(tmp_path / "prog.yaml", lrmate,
                        [np.array([0.0, 0.0, 0.0, 0.0, -1.57, 0.0]), np.array([0.5, 0.3, -0.2, 0.0, -1.2, 0.3])])
    res = CliRunner().invoke(app, ["plan", str(path), "--out", str(tmp_path / "traj.npz"), "--no-plots"])
    assert res.exit_code == 0, res.output
    traj = np.load(tmp_path / "traj.npz")
    np.testing.assert_allclose(traj["q"][-1], [0.5, 0.3, -0.2, 0.0, -1.2, 0.3], atol=1e-6)


def test_hand_under_the_table_is_not_sent(app, lrmate):
    """Probe 4 on the teleoperation page: a reachable pose under the table top is refused, named."""
    assert app.move_hand([0.45, 0.1, 0.4], _wxyz_down())
    sent = app.sent
    q_before = app.desired.copy()
    assert not app.move_hand([0.55, 0.0, -0.10], _wxyz_down())   # IK finds it; the guard refuses it
    assert app.sent == sent and app.refused >= 1
    np.testing.assert_array_equal(app.desired, q_before)          # neither streamed nor recordable
    assert "table" in app.last_error and "link_" in app.last_error
    assert lrmate.fk(app.controller.state()["target"] or app.controller.q_ref)[2, 3] > 0.0
