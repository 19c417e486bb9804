"""The fanuc backend against airo-fanuc's FakeCRXController (strict conformance, 127.0.0.1 only)."""
import math
import time

import numpy as np
import pytest
from airo_fanuc.controller_facts import MEASURED_FACTS

from robointel.errors import ConnectionLost, ControllerFault, UnsafeCommand
from robointel.interface import RobotInterface, RobotMode, open_robot
from robointel.interface.fanuc import FanucRobot
from robointel.testing.emulator import fanuc_url, running_fake

from ._waits import settled, wait_until

PERIOD = 0.008


def _stream_until_error(robot, targets, *, at=None, inject=None):
    """Stream ``targets`` at the period (a late cycle is skipped, not sent in a burst); call
    ``inject()`` before cycle ``at``; it returns the emulator's time of the injection. Return (error, t_inject)."""
    t0, t_inj, k = time.perf_counter(), None, 0
    for i, q in enumerate(targets):
        if i == at:
            t_inj = inject()
        try:
            robot.stream(q)
        except ControllerFault as exc:
            return exc, t_inj
        k = max(k + 1, int((time.perf_counter() - t0) / PERIOD) + 1)
        time.sleep(max(0.0, t0 + k * PERIOD - time.perf_counter()))
    return None, t_inj


def _commands_after_the_stop_was_reported(robot, fake, t_inj):
    """Commands this process sent after the emulator's first status that reported the stop injected at ``t_inj``.

    The host can only know of a stop from a status packet; a loaded host may delay the emulator's next
    tick, so the stop's report, not its injection, is when commanding must end (the cycle in flight
    aside)."""
    t_rep = fake.first_stop_status_after(t_inj)
    assert t_rep is not None, "the emulator never reported the stop"
    return [t for t in robot.sent_times if t > t_rep]


def _ramp(q0, amplitude_rad=0.2, seconds=3.0):
    k = np.arange(int(seconds / PERIOD))
    return q0 + amplitude_rad * (1 - np.cos(2 * np.pi * 0.5 * k * PERIOD))[:, None] * np.ones(6) / 2


def test_frmp_segment_follows_within_the_plant_lag(frmp_segment):
    tr = frmp_segment
    with running_fake(tr.q[0]) as fake:
        with open_robot(fanuc_url(fake)) as robot:
            assert isinstance(robot, RobotInterface) and robot.period == pytest.approx(PERIOD)
            np.testing.assert_allclose(robot.state().q, tr.q[0], atol=1e-6)
            res = robot.execute(tr)
            assert res.completed, res.extra
            assert len(res.q_cmd) >= len(tr.resample(PERIOD).t) - 2
            # the plant's first-order lag closes on the goal (8 time constants on time; longer when ticks are late)
            wait_until(lambda: np.max(np.abs(robot.state().q - tr.q[-1])) <= math.radians(0.05))
            final = robot.state()
        assert fake.violations == []
    # the emulated joints reach the goal
    np.testing.assert_allclose(final.q, tr.q[-1], atol=math.radians(0.05))
    # the controller commanded the planned path and ended on its goal
    np.testing.assert_allclose(res.q_cmd[-1], tr.q[-1], atol=1e-6)
    # and the emulated joints follow the commands like the plant's first-order lag (tau) would
    tau = MEASURED_FACTS.tracking_lag_s
    a = 1 - math.exp(-PERIOD / tau)
    errs = []
    for delay in (0, 1, 2):  # status packets and the tick are up to a period or two apart
        u = np.vstack([np.repeat(res.q_cmd[:1], delay, 0), res.q_cmd])[:len(res.q_cmd)]
        model, x = np.empty_like(u), tr.q[0].copy()
        for k in range(len(u)):
            x = x + (u[k] - x) * a
            model[k] = x
        errs.append(np.sqrt(np.mean((res.q - model) ** 2)))
    lag_err = min(errs)
    raw_err = res.tracking_rms_rad
    assert raw_err > 0.01  # the lag is visible: measured != commanded
    assert lag_err < 0.15 * raw_err, (lag_err, raw_err)


def test_estop_mid_stream_stops_commanding(fanuc, fake_controller):
    q0 = fanuc.state().q
    exc, t_inj = _stream_until_error(fanuc, _ramp(q0), at=60, inject=lambda: fake_controller.timed("press_estop")[1])
    assert exc is not None and not isinstance(exc, ConnectionLost)
    late = _commands_after_the_stop_was_reported(fanuc, fake_controller, t_inj)
    assert len(late) <= 2, f"{len(late)} commands after the e-stop was reported"
    st = fanuc.state()
    assert st.mode is RobotMode.FAULTED and "e_stop" in st.faults and "e-stop" in st.why_stopped
    assert isinstance(exc.value, type(st)) and exc.reason == st.why_stopped
    n = len(fanuc.sent_times)
    with pytest.raises(ControllerFault, match="e-stop"):
        fanuc.stream(st.q_cmd)
    assert len(fanuc.sent_times) == n
    # still pressed: the recovery ladder is retried until its deadline, then refused with the reason
    with pytest.raises(ControllerFault, match="recovery failed.*e-stop"):
        fanuc.recover()
    assert len(fanuc.sent_times) == n and fanuc.state().mode is RobotMode.FAULTED
    # released and recovered: it streams again
    fake_controller.release_estop()
    time.sleep(0.1)
    fanuc.recover()
    q1 = fanuc.state().q_cmd
    exc, _ = _stream_until_error(fanuc, _ramp(q1, 0.05, 0.5))
    assert exc is None and fanuc.state().mode is RobotMode.STREAMING


def test_fault_mid_stream_then_recover(fanuc, fake_controller):
    q0 = fanuc.state().q
    alarm = ("inject_alarm", "SRVO-050", "Collision detect")
    exc, t_inj = _stream_until_error(fanuc, _ramp(q0), at=40, inject=lambda: fake_controller.timed(*alarm)[1])
    assert exc is not None
    assert len(_commands_after_the_stop_was_reported(fanuc, fake_controller, t_inj)) <= 2
    st = fanuc.state()
    assert st.mode is RobotMode.FAULTED and "in_error" in st.faults
    fanuc.recover()  # the controller's alarm reset ladder
    assert fanuc.state().mode is RobotMode.IDLE
    exc, _ = _stream_until_error(fanuc, _ramp(fanuc.state().q_cmd, 0.05, 0.4))
    assert exc is None


def test_lost_connection_reports_last_state_then_reconnects(fanuc, fake_controller):
    q0 = fanuc.state().q
    exc, _ = _stream_until_error(fanuc, _ramp(q0), at=30, inject=lambda: fake_controller.timed("drop_status", 40)[1])
    assert isinstance(exc, ConnectionLost)
    st = fanuc.state()
    assert st.mode is RobotMode.DISCONNECTED and "connection lost" in st.why_stopped
    assert np.all(np.isfinite(exc.value.q))
    n = len(fanuc.sent_times)
    time.sleep(0.1)
    with pytest.raises(ConnectionLost):
        fanuc.stream(exc.value.q_cmd)
    assert len(fanuc.sent_times) == n
    assert fanuc.state().mode is RobotMode.DISCONNECTED  # nothing retried it into motion
    time.sleep(0.3)  # the status stream is back
    fanuc.reconnect()
    assert fanuc.state().mode is RobotMode.IDLE
    exc, _ = _stream_until_error(fanuc, _ramp(fanuc.state().q_cmd, 0.05, 0.4))
    assert exc is None


def test_gate_refuses_before_the_controller(fanuc, fake_controller):
    st = fanuc.state()
    n = len(fanuc.sent_times)
    for bad in (np.full(6, np.nan), st.q + np.array([0, 0, 0, 0, 0, 10.0]), st.q + np.r_[0.5, np.zeros(5)],
                np.zeros(5), [10 ** 400, 0, 0, 0, 0, 0], [st.q.tolist()], [str(v) for v in st.q], [True] * 6):
        with pytest.raises(UnsafeCommand):
            fanuc.stream(bad)
    assert len(fanuc.sent_times) == n
    time.sleep(0.1)
    np.testing.assert_allclose(np.radians(fake_controller.q_meas_deg[:6]), st.q, atol=1e-9)


def test_stalled_stream_stops_the_robot(fake_controller):
    # 25 periods (200 ms beyond the 100 ms look-ahead): at load 13 the streaming test itself once stalled
    # 5 periods past the look-ahead mid-ramp and was (rightly) stopped before the stall under test
    with FanucRobot("127.0.0.1", rmi_port=fake_controller.rmi_port, sm_port=fake_controller.sm_port,
                    stall_periods=25) as robot:
        q0 = robot.state().q
        exc, _ = _stream_until_error(robot, _ramp(q0, 0.1, 0.3))
        assert exc is None
        deadline = time.monotonic() + 10.0  # > 5 periods (and the look-ahead) without a target
        while robot.state().mode is not RobotMode.STOPPED and time.monotonic() < deadline:
            time.sleep(0.01)
        st = robot.state()
        assert st.mode is RobotMode.STOPPED and "stalled" in st.why_stopped
        assert st.faults == ("stream_stalled",)
        with pytest.raises(ControllerFault, match="stalled"):
            robot.stream(st.q_cmd)
        robot.recover()
        robot.stream(robot.state().q_cmd)
        robot.hold()
        time.sleep(0.1)  # holding is not a stall
        assert robot.state().mode is RobotMode.HOLDING


def test_teleop_targets_through_the_follower_and_the_deadman_stop(fake_controller):
    """Operator targets jump; the jerk-limited follower turns them into per-period targets the gate
    accepts; releasing the deadman (no more targets) stops the robot at the controller."""
    from robointel.control import JerkLimitedFollower
    from robointel.robot import Robot

    lr = Robot.load("lrmate200id7l")
    with FanucRobot("127.0.0.1", rmi_port=fake_controller.rmi_port, sm_port=fake_controller.sm_port,
                    stall_periods=5) as robot:
        fol = JerkLimitedFollower(0.5 * lr.velocity_limit, lr.acceleration_limit, 20 * lr.acceleration_limit,
                                  dt=PERIOD, lower=lr.lower, upper=lr.upper)
        q0 = robot.state().q
        fol.reset(q0)
        goals = [q0 + np.radians([15, -10, 10, 20, 15, 30]), q0 + np.radians([-10, 5, -5, -20, 0, -30])]
        t0 = time.perf_counter()
        for k in range(150):  # 1.2 s, the operator's target jumps at 0.6 s
            robot.stream(fol.step(goals[k // 75])[0])
            time.sleep(max(0.0, t0 + (k + 1) * PERIOD - time.perf_counter()))
        # deadman released: no targets; the stall stop comes 5 periods after the 100 ms look-ahead ran out
        wait_until(lambda: robot.state().mode is not RobotMode.STREAMING, timeout=10.0)
        st = robot.state()
        assert st.mode is RobotMode.STOPPED and "stalled" in st.why_stopped
        cmd_a = settled(lambda: robot.state().q_cmd, 0.0, 0.2)  # the core's brake (stop_j) has finished
        time.sleep(1.0)  # 8 time constants of the plant
        cmd_b = robot.state().q_cmd
        wait_until(lambda: np.max(np.abs(np.radians(fake_controller.q_meas_deg[:6]) - cmd_b)) <= np.radians(0.05))
        q_b = np.radians(fake_controller.q_meas_deg[:6])
    np.testing.assert_allclose(cmd_b, cmd_a, atol=1e-9)  # the controller is commanded to stand still
    np.testing.assert_allclose(q_b, cmd_b, atol=np.radians(0.05))  # and the emulated arm stands there
    assert np.max(np.abs(q_b - q0)) > np.radians(2)  # it did move before


def test_an_aborted_execution_stops_the_core(frmp_segment):
    tr = frmp_segment
    with running_fake(tr.q[0]) as fake:
        with open_robot(fanuc_url(fake)) as robot:
            def boom(k, state):
                if k == 30:
                    raise RuntimeError("operator abort")

            with pytest.raises(RuntimeError, match="operator abort"):
                robot.execute(tr, on_cycle=boom)
            st = robot.state()
            assert st.mode is RobotMode.STOPPED and "operator abort" in st.why_stopped
            # the core brakes and re-anchors its command on the lagging arm: wait for the arm at rest
            a = settled(lambda: robot.state().q, 1e-3, 0.3)
            time.sleep(0.3)
            np.testing.assert_allclose(robot.state().q, a, atol=2e-3)  # the arm is at rest
            assert np.max(np.abs(a - tr.q[-1])) > 0.05  # well before the goal: playback stopped
            from airo_fanuc import Mode

            assert Mode(int(robot.driver.core.get_snapshot()["mode"])) != Mode.TRAJECTORY
        assert fake.violations == []


def test_the_first_state_after_open_is_the_controllers():
    """open_robot returns once a controller status was read: the first state is the arm's, never zeros."""
    q0 = np.radians([0.0, 0.3, -23.8, 0.0, -65.8, 0.0])
    for _ in range(3):  # the race it guards against showed in 1-3 of 8 opens
        with running_fake(q0) as fake:
            with open_robot(fanuc_url(fake)) as robot:
                np.testing.assert_allclose(robot.state().q, q0, atol=1e-6)
