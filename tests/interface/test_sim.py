"""The sim backend (MuJoCo workcell) behind the same interface, and the shared safety gate."""
import time

import numpy as np
import pytest

from robointel.errors import ControllerFault, InvalidInput, UnsafeCommand
from robointel.interface import RobotInterface, RobotMode, SafetyGate, open_robot
from robointel.interface.sim import SimRobot

from ._waits import wait_until


@pytest.fixture(scope="module")
def sim():
    with open_robot("sim") as robot:
        yield robot


def test_frmp_segment_tracks_in_the_workcell(frmp_segment):
    tr = frmp_segment
    with SimRobot(q0=tr.q[0]) as robot:
        assert isinstance(robot, RobotInterface)
        res = robot.execute(tr)
        assert res.completed and res.missed_cycles == 0
        st = robot.idle(0.3)
    assert res.tracking_rms_rad < 0.01
    np.testing.assert_allclose(st.q, tr.q[-1], atol=2e-3)
    assert st.wrench is not None and st.wrench.shape == (6,) and np.all(np.isfinite(st.wrench))
    assert st.mode is RobotMode.HOLDING


def test_gate_refuses_bad_targets_and_the_robot_holds(sim):
    st = sim.state()
    t0 = st.t
    for bad in (np.full(6, np.nan), np.r_[st.q[:5], 7.0], st.q + 0.3, [1, 2], "x"):
        with pytest.raises(UnsafeCommand):
            sim.stream(bad)
    assert sim.state().t == t0  # nothing reached the simulation
    assert sim.state().mode is RobotMode.HOLDING
    sim.stream(st.q + 0.001)  # a small step is fine
    with pytest.raises(UnsafeCommand, match="sample"):
        from robointel.trajectory import Trajectory

        q = np.vstack([st.q, st.q + 1.0])
        sim.execute(Trajectory([0, 0.01], q, np.zeros_like(q), np.zeros_like(q)))


def test_stop_refuses_until_recover(sim):
    q = sim.state().q_cmd
    sim.stop("operator pressed stop")
    st = sim.state()
    assert st.mode is RobotMode.STOPPED and st.why_stopped == "operator pressed stop"
    assert np.linalg.norm(st.qd) < 1e-2
    with pytest.raises(ControllerFault, match="operator pressed stop"):
        sim.stream(q)
    sim.recover()
    sim.stream(sim.state().q_cmd)


def test_stalled_stream_stops_the_simulated_robot():
    with SimRobot(paced=True, stall_periods=5) as robot:
        q = robot.state().q
        for k in range(20):
            robot.stream(q + 1e-3 * k)
            time.sleep(0.008)
        wait_until(lambda: robot.state().mode is not RobotMode.STREAMING, timeout=10.0)  # the watchdog's turn
        st = robot.state()
        assert st.mode is RobotMode.STOPPED and st.faults == ("stream_stalled",)
        with pytest.raises(ControllerFault, match="stalled"):
            robot.stream(st.q_cmd)


def test_gate_and_open_robot_reject_bad_setup():
    with pytest.raises(InvalidInput):
        SafetyGate(["a"], [0.0], [1.0], [0.0], 0.008)
    with pytest.raises(InvalidInput):
        open_robot("ur://x")
    with pytest.raises(InvalidInput):
        SimRobot(period=0.0025)
