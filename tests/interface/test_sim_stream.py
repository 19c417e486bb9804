"""The paced sim whose physics runs in a streaming process of its own (SimStreamRobot).

No assertion on timing: every wait is for the state the property needs, with a generous timeout (load 20).
"""
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from robointel.errors import ConnectionLost, ControllerFault, InvalidInput
from robointel.interface import RobotInterface, RobotMode, open_robot
from robointel.interface.sim import SimRobot
from robointel.interface.sim_stream import SimStreamProcess, SimStreamRobot

from ._waits import settled, wait_until

PERIOD = 0.008


def _ramp(q0, n, rate=0.2):
    """(n, 6) targets moving every joint at ``rate`` rad/s."""
    return q0 + rate * PERIOD * np.arange(1, n + 1)[:, None] * np.ones(6)


def _stream_paced(robot, targets):
    t0 = time.perf_counter()
    for k, q in enumerate(targets):
        robot.stream(q)
        time.sleep(max(0.0, t0 + (k + 1) * PERIOD - time.perf_counter()))


def _gone(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    with open(f"/proc/{pid}/stat") as f:  # a zombie (not yet reaped by its parent) runs nothing
        return f.read().split(")")[-1].split()[0] == "Z"


def test_a_trajectory_ends_where_the_in_process_paced_sim_ends(frmp_segment):
    tr = frmp_segment
    with SimRobot(q0=tr.q[0], paced=True) as ref:
        ref.execute(tr)
        q_ref = ref.idle(0.5).q
    with open_robot("sim", stream_process=True, q0=tr.q[0], stall_periods=None) as robot:
        assert isinstance(robot, (RobotInterface, SimStreamRobot))
        np.testing.assert_allclose(robot.state().q, tr.q[0], atol=1e-9)
        res = robot.execute(tr)
        assert res.completed and len(res.q_cmd) == len(tr.resample(PERIOD).q)
        assert robot.driver.held()  # every queued target was played before execute returned
        st = robot.idle(0.5)
        stats = robot.timing_stats()
    # both hold the trajectory's last sample with the same 1 kHz servo (at rest: the last windows of the
    # path move < 1e-4 rad); half a second later each is within the servo's settling of it
    np.testing.assert_allclose(st.q_cmd, tr.q[-1], atol=1e-4)
    np.testing.assert_allclose(st.q, tr.q[-1], atol=2e-3)
    np.testing.assert_allclose(st.q, q_ref, atol=2e-3)
    assert st.mode is RobotMode.HOLDING and st.wrench is not None and np.all(np.isfinite(st.wrench))
    # every window of the stream is counted once, in the child
    assert stats["stream_fresh"] > 0
    assert stats["stream_windows"] == sum(stats[f"stream_{k}"] for k in ("fresh", "starved", "late", "core_late"))


def test_the_child_stops_a_stalled_stream_by_itself():
    """The caller's process plays no part: the child stops the arm after stall_periods windows without a target."""
    proc = SimStreamProcess({}, None, period=PERIOD, lookahead_s=0.05, stall_periods=5)
    try:
        q0 = np.array(proc.read_state()["q_meas"])
        for q in _ramp(q0, 25):
            proc.servo_j(q, PERIOD)
            time.sleep(PERIOD)
        assert wait_until(lambda: proc.read_state()["stalled"] == 1.0, timeout=15.0)
        s = proc.read_state()
        assert s["starved"] >= 5 and s["stall_gap_s"] >= 4 * PERIOD
        # it brakes where the arm was and commands nothing more
        q = settled(lambda: proc.read_state()["q_meas"], tol=1e-5, still_s=0.2)
        np.testing.assert_allclose(proc.read_state()["q_cmd"], q, atol=2e-3)
        submits = proc.read_state()["submits"]
        time.sleep(0.1)
        assert proc.read_state()["submits"] == submits
    finally:
        proc.close()


def test_a_stalled_stream_stops_the_robot_with_a_named_fault():
    # a caller stall under load shorter than 10 periods + the 0.3 s look-ahead stops nothing mid-stream
    with SimStreamRobot(stall_periods=10, lookahead_s=0.3) as robot:
        _stream_paced(robot, _ramp(robot.state().q, 20))
        assert wait_until(lambda: robot.state().mode is not RobotMode.STREAMING, timeout=15.0)
        st = robot.state()
        assert st.mode is RobotMode.STOPPED and st.faults == ("stream_stalled",)
        assert "stalled" in st.why_stopped
        with pytest.raises(ControllerFault, match="stalled"):
            robot.stream(st.q_cmd)
        robot.recover()
        robot.stream(robot.state().q_cmd)  # streams again after recover


def test_stop_reaches_the_child_and_refuses_until_recover():
    # at the stop, ~0.3 s of targets are queued, not played; no stall stop (a loaded caller's pause)
    with SimStreamRobot(lookahead_s=0.3, stall_periods=None) as robot:
        targets = _ramp(robot.state().q, 60, rate=0.5)
        _stream_paced(robot, targets[:40])
        robot.stop("operator pressed stop")
        submits = robot.driver.read_state()["submits"]
        # the queued targets were dropped: the arm brakes short of the last one queued and stays there
        q = settled(lambda: robot.state().q, tol=1e-5, still_s=0.2)
        assert np.max(np.abs(q - targets[39])) > 1e-3
        st = robot.state()
        assert st.mode is RobotMode.STOPPED and st.why_stopped == "operator pressed stop"
        assert np.linalg.norm(st.qd) < 1e-2
        assert robot.driver.read_state()["submits"] == submits
        with pytest.raises(ControllerFault, match="operator pressed stop"):
            robot.stream(targets[40])
        assert robot.driver.read_state()["submits"] == submits  # nothing reached the child
        robot.recover()
        q_cmd = robot.state().q_cmd
        _stream_paced(robot, _ramp(q_cmd, 20))
        robot.hold()
        assert wait_until(robot.driver.held, timeout=15.0)
        assert robot.driver.read_state()["submits"] > submits


def test_a_dead_child_is_a_lost_connection_with_the_last_state():
    with SimStreamRobot(stall_periods=None) as robot:  # no stall stop: a loaded caller's pause must not stop it
        targets = _ramp(robot.state().q, 30)
        _stream_paced(robot, targets[:20])
        last = robot.state()
        os.kill(robot.driver._proc.pid, signal.SIGKILL)
        assert wait_until(lambda: not robot.driver.alive(), timeout=15.0)
        with pytest.raises(ConnectionLost, match="simulation process") as err:
            robot.stream(targets[20])
        st = err.value.value
        assert st.mode is RobotMode.DISCONNECTED and st.faults == ("disconnected",)
        assert st.t >= last.t and np.all(np.isfinite(st.q))
        np.testing.assert_allclose(st.q, robot.state().q)  # the last state the child published
        with pytest.raises(ConnectionLost):
            robot.stream(targets[21])


def test_close_leaves_no_process():
    robot = SimStreamRobot(stall_periods=None)
    pid = robot.driver._proc.pid
    _stream_paced(robot, _ramp(robot.state().q, 10))
    robot.close()
    assert robot.driver._proc.poll() is not None and _gone(pid)
    robot.close()  # idempotent
    with pytest.raises(ConnectionLost, match="closed"):
        robot.stream(robot.state().q_cmd)


def test_the_child_ends_when_its_caller_dies(tmp_path):
    script = textwrap.dedent("""
        import os, sys
        from robointel.interface.sim_stream import SimStreamRobot
        robot = SimStreamRobot()
        print(robot.driver._proc.pid, flush=True)
        os._exit(0)
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300,
                         env=dict(os.environ))
    assert out.returncode == 0, out.stderr
    pid = int(out.stdout.split()[0])
    assert wait_until(lambda: _gone(pid), timeout=30.0)


def test_a_force_loop_submits_each_target_at_once():
    with SimStreamRobot(stall_periods=None) as robot:
        q0 = robot.state().q
        with robot.low_latency():
            _stream_paced(robot, _ramp(q0, 20))
            robot.hold()
        s = robot.timing_stats()
        assert s["direct_submits"] >= 1 and s["lookahead_s"] == pytest.approx(0.1)
        assert wait_until(robot.driver.held, timeout=15.0)


def test_bad_setups_are_refused():
    with pytest.raises(InvalidInput):
        SimStreamRobot(period=0.0025)
    with pytest.raises(InvalidInput):
        SimStreamRobot(lookahead_s=2.0)
    with pytest.raises(InvalidInput):
        open_robot("sim", stream_process=True, paced=False)
    with pytest.raises(InvalidInput, match="timestep"):
        SimStreamRobot(workcell_kwargs={"timestep": 0.0003})


def test_a_child_that_dies_while_it_plays_the_queue_fails_the_execution(frmp_segment):
    tr = frmp_segment
    K = len(tr.resample(PERIOD).q)
    with SimStreamRobot(q0=tr.q[0], stall_periods=None) as robot:
        def kill_at_the_end(k, st):
            if k == K - 1:  # every target queued, ~100 ms of them not played yet
                os.kill(robot.driver._proc.pid, signal.SIGKILL)

        with pytest.raises(ConnectionLost, match="execution stopped") as err:
            robot.execute(tr, on_cycle=kill_at_the_end)
        st, res = err.value.value
        assert st.mode is RobotMode.DISCONNECTED and res.completed and len(res.q_cmd) == K


def test_a_cell_built_by_a_factory_in_the_child_and_its_own_figures():
    """``workcell_factory`` builds the skill's cell in the child; the child reports its wake-ups and memory lock."""
    from robointel.skills.cells import HoleTask, PegTool

    peg, hole = PegTool(), HoleTask()
    with SimStreamRobot(workcell_factory="robointel.skills.cells:peg_hole_workcell",
                        factory_args=(peg, hole), lock_memory=True, stall_periods=None) as robot:
        assert robot.has_wrench  # the peg cell's wrist sensor, read through the block
        t0 = robot.state().t
        assert wait_until(lambda: robot.state().t > t0 + 0.2, timeout=60.0)
        st = robot.timing_stats()
    assert isinstance(st["memory_locked"], bool)  # True where mlockall is allowed (root here), else False
    w = st["wake_after_tick_ms"]
    assert w["reads"] > 0 and 0.0 <= w["p50"] <= w["p99"] <= w["max"] and 0 <= w["over_period"] <= w["reads"]
    assert all(len(s) == 3 for s in st["slow_steps"])


def test_a_factory_that_is_not_there_is_refused():
    with pytest.raises(InvalidInput, match="no_such_cell"):
        SimStreamRobot(workcell_factory="robointel.skills.cells:no_such_cell")
