"""Closing a FANUC session never double-sends (the terminal packet goes out between the core's ticks)."""
import numpy as np

from robointel.interface import open_robot
from robointel.testing.emulator import fanuc_url


def test_repeated_sessions_close_without_a_double_send(fake_controller):
    """Ten sessions stream, hold and close; the fixture asserts zero strict-conformance violations.

    Without the aligned stop, 4-6 of 40 closes double-sent at load ~22 (docs/design/streaming.md).
    """
    for _ in range(10):
        robot = open_robot(fanuc_url(fake_controller))
        q = robot.state().q
        for _k in range(5):
            robot.stream(q)
        robot.hold()
        robot.close()
        assert robot.state().mode.value == "disconnected"
    assert np.all(np.isfinite(np.asarray(fake_controller.q_meas_deg, dtype=float)))
