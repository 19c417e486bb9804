"""The FANUC streaming process: the look-ahead queue, a stalled caller, a caller that dies."""
import os
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from robointel.errors import ConnectionLost, InvalidInput
from robointel.interface import RobotMode
from robointel.interface.fanuc import FanucRobot

PERIOD = 0.008


def _open(fake, **kw):
    return FanucRobot("127.0.0.1", rmi_port=fake.rmi_port, sm_port=fake.sm_port, **{"stream_process": True, **kw})


def _ramp(q0, n, rate=0.2):
    """(n, 6) targets moving every joint at ``rate`` rad/s."""
    return q0 + rate * PERIOD * np.arange(1, n + 1)[:, None] * np.ones(6)


def test_a_target_is_played_no_earlier_than_the_lookahead(fake_controller):
    with _open(fake_controller, lookahead_s=0.3) as robot:
        assert robot.stream_process
        q0 = robot.state().q_cmd
        targets = _ramp(q0, 80)
        t0 = time.perf_counter()
        seen = []
        for k, q in enumerate(targets):
            robot.stream(q)
            seen.append((time.perf_counter(), robot.state().q_cmd.copy()))
            time.sleep(max(0.0, t0 + (k + 1) * PERIOD - time.perf_counter()))
        robot.hold()
        deadline = time.perf_counter() + 10.0
        while time.perf_counter() < deadline and robot.timing_stats()["stream_windows"] < 60:
            time.sleep(0.05)
        stats = robot.timing_stats()
    moved = [t for t, q_cmd in seen if np.max(np.abs(q_cmd - q0)) > 1e-9]
    assert moved, "the commanded position never moved"
    assert moved[0] >= t0 + 0.3 - 2 * PERIOD  # the first target was played a look-ahead after it came
    # every window is counted once; a submission that missed its tick on a loaded machine counts as late
    assert stats["stream_fresh"] > 0 and stats["stream_submits"] >= stats["stream_fresh"]
    assert stats["stream_windows"] == sum(stats[f"stream_{k}"] for k in ("fresh", "starved", "late", "core_late"))


def test_a_caller_stall_shorter_than_the_lookahead_costs_no_window(fake_controller):
    """The caller stops for 5 periods, then sends the targets it owes at once (as a thread that got
    the interpreter lock back would): every controller window still gets a target in time."""
    with _open(fake_controller, lookahead_s=0.5, stall_periods=3) as robot:
        q0 = robot.state().q_cmd
        targets = _ramp(q0, 150)
        t0 = time.perf_counter()
        for k, q in enumerate(targets):
            if k == 60:
                time.sleep(5 * PERIOD)  # the stall: no target for 40 ms, then a burst
            robot.stream(q)
            time.sleep(max(0.0, t0 + (k + 1) * PERIOD - time.perf_counter()))
        assert robot.state().mode is RobotMode.STREAMING
        robot.hold()
        deadline = time.perf_counter() + 10.0
        while time.perf_counter() < deadline and robot.timing_stats()["stream_windows"] < 140:
            time.sleep(0.05)
        st = robot.state()
        stats = robot.timing_stats()
    assert st.mode is RobotMode.HOLDING, st.why_stopped  # no stall stop: the queue never ran dry
    assert stats["stream_starved"] == 0, stats
    assert stats["stream_windows"] >= 140


def test_a_killed_streaming_process_is_a_lost_connection_at_the_next_target(fake_controller):
    """Liveness is read from the child's publish time without a system call; once that is stale the
    interface asks waitpid, so a child killed mid-stream is reported, never streamed into silently."""
    with _open(fake_controller) as robot:
        q0 = robot.state().q_cmd
        targets = _ramp(q0, 200)
        t0 = time.perf_counter()
        for k, q in enumerate(targets[:150]):  # > GC_TICKS windows: the serve loop has collected once
            robot.stream(q)
            time.sleep(max(0.0, t0 + (k + 1) * PERIOD - time.perf_counter()))
        deadline = time.perf_counter() + 10.0
        while time.perf_counter() < deadline and robot.timing_stats()["gc_max_ms"] == 0.0:
            time.sleep(0.05)
        assert robot.timing_stats()["gc_max_ms"] > 0.0
        robot.driver._proc.kill()
        robot.driver._proc.wait(10.0)
        time.sleep(0.1)  # longer than ALIVE_FRESH_S: the last publish is stale
        with pytest.raises(ConnectionLost, match="connection lost"):
            robot.stream(targets[150])
        assert robot.state().mode is RobotMode.DISCONNECTED


def test_the_streaming_process_stops_when_its_caller_dies(fake_controller):
    """A caller killed mid-stream: the streaming process ends the session and exits by itself."""
    script = textwrap.dedent(f"""
        import os, sys, time
        import numpy as np
        from robointel.interface.fanuc import FanucRobot
        robot = FanucRobot("127.0.0.1", rmi_port={fake_controller.rmi_port}, sm_port={fake_controller.sm_port},
                           stream_process=True)
        print(robot.driver._proc.pid, flush=True)
        q = robot.state().q_cmd
        for k in range(50):
            robot.stream(q + 0.001 * k)
            time.sleep({PERIOD})
        os._exit(3)
    """)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, env=env)
    assert proc.returncode == 3, proc.stderr
    child = int(proc.stdout.split()[0])
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline and os.path.exists(f"/proc/{child}") and not _zombie(child):
        time.sleep(0.05)
    assert not os.path.exists(f"/proc/{child}") or _zombie(child), "the streaming process outlived its caller"


def _zombie(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(") ")[1].startswith("Z")
    except OSError:
        return True


def test_a_force_loop_streams_each_target_at_once_then_the_queue_comes_back(fake_controller):
    """Inside ``low_latency()`` the streaming process submits every target as it arrives (no queue, no
    interpolation); after the block the construction's look-ahead applies again."""
    with _open(fake_controller, lookahead_s=0.3) as robot:
        q0 = robot.state().q_cmd
        targets = _ramp(q0, 60)
        with robot.low_latency():
            assert robot.driver.lookahead_s == 0.0
            t0 = time.perf_counter()
            for k, q in enumerate(targets):
                robot.stream(q)
                time.sleep(max(0.0, t0 + (k + 1) * PERIOD - time.perf_counter()))
        assert robot.driver.lookahead_s == 0.3 and robot.state().mode is RobotMode.HOLDING
        stats = robot.timing_stats()
        q_end = _settled(robot)
        # a queued stream after the block is played a look-ahead after it came, as before
        first = None
        t1 = time.perf_counter()
        for k, q in enumerate(_ramp(q_end, 60)):
            robot.stream(q)
            if first is None and np.max(np.abs(robot.state().q_cmd - q_end)) > 1e-9:
                first = time.perf_counter()
            time.sleep(max(0.0, t1 + (k + 1) * PERIOD - time.perf_counter()))
        robot.hold()
        deadline = time.perf_counter() + 10.0
        while first is None and time.perf_counter() < deadline:
            if np.max(np.abs(robot.state().q_cmd - q_end)) > 1e-9:
                first = time.perf_counter()
            time.sleep(0.002)
    # every target of the block went straight to the core (the newest of any that came together)
    assert 0 < stats["direct_submits"] <= len(targets) and stats["stream_submits"] == stats["direct_submits"]
    assert stats["stream_windows"] > 0
    assert np.max(np.abs(q_end - q0)) > 0.5 * np.max(np.abs(targets[-1] - q0))  # it moved along the ramp
    assert first is not None and first >= t1 + 0.3 - 2 * PERIOD


def _settled(robot, timeout=10.0):
    """The core's command once it has stopped changing (50 ms without a change)."""
    q, still = robot.state().q_cmd, 0.0
    deadline = time.perf_counter() + timeout
    while still < 0.05 and time.perf_counter() < deadline:
        time.sleep(0.004)
        q1 = robot.state().q_cmd
        still = still + 0.004 if np.array_equal(q1, q) else 0.0
        q = q1
    return q


def test_low_latency_changes_nothing_with_the_driver_in_process(fake_controller):
    with FanucRobot("127.0.0.1", rmi_port=fake_controller.rmi_port, sm_port=fake_controller.sm_port,
                    stream_process=False) as robot:
        q0 = robot.state().q_cmd
        with robot.low_latency():
            for q in _ramp(q0, 10):
                robot.stream(q)
                time.sleep(PERIOD)
        assert robot.lookahead_s == 0.0 and robot.state().mode is RobotMode.STREAMING  # not even held
        robot.hold()


@pytest.mark.parametrize("bad", [-0.1, float("nan"), 2.0])
@pytest.mark.parametrize("name", ["lookahead_s", "force_lookahead_s"])
def test_a_bad_lookahead_is_refused_before_bring_up(bad, name):
    with pytest.raises(InvalidInput, match="lookahead_s") as err:
        FanucRobot("127.0.0.1", rmi_port=1, sm_port=1, stream_process=True, **{name: bad})
    assert err.value.value == bad or np.isnan(err.value.value)
