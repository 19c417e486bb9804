"""``--robot fanuc://... --record run.mcap`` on the commands that move a robot, against the emulator."""
import socket
import threading
import time

import numpy as np
from mcap.reader import make_reader
from typer.testing import CliRunner

from robointel.cli import app
from robointel.io.mcap_log import COMMAND, JOINT_STATES, WRENCH
from robointel.teach.stream_client import StreamClient
from robointel.testing.emulator import fanuc_url, running_fake

from ._waits import settled

READY = np.array([0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0])


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _topics(path):
    counts = {}
    with open(path, "rb") as f:
        for _schema, channel, _msg in make_reader(f).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return counts


def _connect(url, timeout=120.0):
    """Connect once the command's server is up (it imports and starts on a loaded machine)."""
    end = time.monotonic() + timeout
    while True:
        try:
            return StreamClient(url, timeout=10.0)
        except OSError:
            if time.monotonic() > end:
                raise
            time.sleep(0.1)


def test_teleop_streams_to_the_fanuc_emulator_and_records(tmp_path):
    port, stream_port = _free_port(), _free_port()
    target = READY + np.array([0.3, 0.0, 0.1, 0.0, 0.0, 0.0])
    result = {}
    with running_fake(READY) as fake:
        args = ["teleop", "--robot", fanuc_url(fake), "--record", str(tmp_path / "teleop.mcap"), "--port", str(port),
                "--stream-port", str(stream_port), "--duration", "6", "--program", str(tmp_path / "p.yaml")]
        th = threading.Thread(target=lambda: result.update(out=CliRunner().invoke(app, args)))
        th.start()
        try:
            with _connect(f"ws://127.0.0.1:{stream_port}") as client:
                assert client.acquire(wait=10.0)["type"] == "ok"
                t_end = time.monotonic() + 2.5
                while time.monotonic() < t_end:  # the operator holds the deadman: targets at 50 Hz
                    client.joint_target(target)
                    time.sleep(0.02)
                q_reached = np.radians(fake.q_meas_deg[:6])
        finally:
            th.join(timeout=120)
        assert fake.violations == []
    out = result["out"]
    assert out.exit_code == 0, out.output
    np.testing.assert_allclose(q_reached, target, atol=np.radians(0.5))
    topics = _topics(tmp_path / "teleop.mcap")
    assert topics[COMMAND] > 100 and topics[JOINT_STATES] == topics[COMMAND]
    assert WRENCH not in topics  # Stream Motion v3 carries no wrench and no F/T sensor was given


def _run_on_fake(args, tmp_path, q0=READY):
    with running_fake(q0) as fake:
        out = CliRunner().invoke(app, [*args, "--robot", fanuc_url(fake), "--record", str(tmp_path / "run.mcap")])
        # the emulated plant's lag closes (8 time constants on time; longer when its ticks are late)
        q_end = settled(lambda: np.radians(fake.q_meas_deg[:6]), 1e-5, 0.2)
        assert fake.violations == []
    assert out.exit_code == 0, out.output
    return out.output, q_end, _topics(tmp_path / "run.mcap")


def test_imitation_executes_on_the_fanuc_emulator(tmp_path):
    from robointel.robot import Robot
    from robointel.teach.imitation import kinematic_imitation
    from robointel.teach.skeleton import synthetic_wave

    plan = kinematic_imitation(synthetic_wave(), Robot.load("lrmate200id7l"))
    output, q_end, topics = _run_on_fake(["imitate", "synthetic", "--out", str(tmp_path)], tmp_path)
    assert "moving to the trajectory's start" in output or "at the start" in output
    assert "missed cycles" in output
    # the human's arm is still moving at the end (up to 1.1 rad/s): the controller brakes to rest just past it
    assert np.max(np.abs(plan.trajectory.qd[-1])) > 0.5
    np.testing.assert_allclose(q_end, plan.trajectory.q[-1], atol=0.03)
    assert topics[COMMAND] > plan.trajectory.duration / 0.008 and "/planned_trajectory" in topics


def test_keypoint_reproduction_executes_on_the_fanuc_emulator(tmp_path):
    output, q_end, topics = _run_on_fake(["keypoints", "--scenario", "2", "--duration", "3", "--out", str(tmp_path)],
                                         tmp_path)
    assert "key points from" in output and "missed cycles" in output
    assert (tmp_path / "keypoints_s2.png").exists()
    assert topics[COMMAND] > 100 and topics[JOINT_STATES] == topics[COMMAND]


def test_guide_on_fanuc_with_a_wrist_sensor_records_the_wrench(tmp_path):
    from .test_ft_sensor import SimulatedNetFT

    box = SimulatedNetFT(lambda t: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # nobody pushes: the arm holds still
    try:
        output, q_end, topics = _run_on_fake(["guide", "--duration", "1", "--ft", f"netft://127.0.0.1:{box.port}"],
                                             tmp_path, q0=np.array([0.0, 0.2, -0.3, 0.0, -0.8, 0.0]))
    finally:
        box.close()
    assert "guided 125 cycles" in output
    np.testing.assert_allclose(q_end, [0.0, 0.2, -0.3, 0.0, -0.8, 0.0], atol=1e-3)
    assert topics[JOINT_STATES] == topics[COMMAND] == 125
    assert 100 < topics[WRENCH] <= 125  # one per state with a fresh sensor reading
