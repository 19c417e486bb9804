"""The ``fanuc`` backend: a FANUC controller over Stream Motion + RMI through ``airo-fanuc``.

Targets go out with ``FanucDriver.servo_j(q, period)`` (the driver's compiled real-time core owns
the 8 ms Stream Motion timeline). By default the driver runs in a streaming process of its own
(:class:`~robointel.interface.stream_process.StreamProcess`) that plays the streamed targets at the
controller's ticks ``lookahead_s`` after they arrive, so the caller's interpreter lock (a planner
thread) cannot delay a controller window; inside :meth:`FanucRobot.low_latency` (the force loops,
teleoperation) it submits each target as soon as it arrives. The controller is polled every period by the interface's
watchdog thread and before every target: an e-stop, an alarm or a lost status stream stops
commanding at once (``stop_j``), and the next call raises :class:`~robointel.errors.ControllerFault`
(:class:`~robointel.errors.ConnectionLost` for a lost link) with the last known state. The
driver's automatic recovery is off: only :meth:`FanucRobot.recover` or :meth:`FanucRobot.reconnect`
re-arms motion.
"""
from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import numpy.typing as npt
from airo_fanuc import DriverConfig, DriverPolicy, FanucDriver, FaultReason, MotionResult, RobotProfile
from airo_fanuc.exceptions import (
    FanucConnectionError,
    FanucError,
    RobotFaultedError,
    TrajectoryValidationError,
)

from robointel.errors import ConnectionLost, ControllerFault, InvalidInput, UnsafeCommand
from robointel.interface import stream_state as ss
from robointel.interface.backend import Backend, ExecutionResult, Recorder, sleep_until
from robointel.interface.fanuc_faults import bringup_cause, probe_rmi, read_alarms
from robointel.interface.fanuc_registers import RegisterIO
from robointel.interface.ft_sensor import WrenchSource, open_ft_sensor
from robointel.interface.profile import lrmate_profile
from robointel.interface.protocol import CycleCallback
from robointel.interface.realtime import realtime_thread
from robointel.interface.recovery import recover_until_clear
from robointel.interface.state import RobotMode, RobotState
from robointel.interface.stream_child import stop_core_between_ticks
from robointel.interface.stream_process import StreamProcess, check_lookahead
from robointel.trajectory import Trajectory

DEFAULT_RMI_PORT = 16001
DEFAULT_SM_PORT = 60015
DEFAULT_LOOKAHEAD_S = 0.1
"""Look-ahead of the streaming process, s (docs/design/streaming.md: the caller's stalls under load)."""
STALE_STATUS_PERIODS = 12
"""Status older than this many periods counts as a lost connection (the core's own RX-silence hold
starts earlier)."""


class FanucRobot(RegisterIO, Backend):
    """A :class:`~robointel.interface.protocol.RobotInterface` on a FANUC controller.

    Args:
        host: controller address.
        rmi_port: RMI port (16001 on a controller).
        sm_port: Stream Motion UDP port (60015 on a controller).
        profile: the arm's motion envelope (default :func:`~robointel.interface.profile.lrmate_profile`).
        robot: the :class:`robointel.robot.Robot` for joint names (default: the LR Mate).
        stall_periods: stop when a stream gives no target for this many controller periods.
        recorder: optional recorder of states and commands.
        connect_timeout: RMI connect timeout, s.
        lock_path: ``airo-fanuc`` single-owner lock file (None: no ownership lock).
        deadman_s: during :meth:`execute` the controller's core stops the trajectory when this process
            has not fed its deadman for this long, s (the core plays the trajectory back by itself, so a
            busy interpreter must not stop it, a dead one must).
        sched_fifo: run the driver's 125 Hz real-time thread under ``SCHED_FIFO`` (ignored without
            the privilege, ``CAP_SYS_NICE``), so a loaded machine does not delay its packets.
        gripper: bring the gripper dispatcher up too (``driver.gripper``; see
            :class:`~robointel.interface.gripper.FanucGripper`); the driver then runs in this
            process (``stream_process`` is ignored).
        ft_sensor: the wrist F/T sensor whose wrench the state reports when Stream Motion carries
            none (a :class:`~robointel.interface.ft_sensor.WrenchSource`, or a ``netft://HOST[:PORT]``
            URL opened here and closed with the robot); None: no wrench (lead-through is refused).
        stream_process: run the driver in a streaming process of its own, fed through a look-ahead
            queue (:class:`~robointel.interface.stream_process.StreamProcess`), so heavy work in the
            caller's process (a planner) cannot delay a controller window; a plain stream is delayed
            by ``lookahead_s``, the force loops and teleoperation stream inside :meth:`low_latency`
            (each target at once). False: the driver in this process, each target submitted by the
            caller's thread.
        lookahead_s: the streaming process plays a target this long after it arrived, s: a stall of
            the streaming caller shorter than this costs no controller window; it is added latency.
            0: every target is submitted as soon as it arrives.
        force_lookahead_s: the look-ahead inside :meth:`low_latency` (the force loops and
            teleoperation), s; 0 (default): each target is submitted as soon as it arrives.
        recover_timeout_s: :meth:`recover` retries the controller's recovery ladder until a status
            shows no fault, for up to this long, s.

    Raises:
        InvalidInput: a bad look-ahead, stall count or profile.
        ConnectionLost: bring-up failed (the controller is unreachable or refuses motion).
    """

    clocked = True
    """The state advances at the controller's ticks."""

    def __init__(self, host: str, *, rmi_port: int = DEFAULT_RMI_PORT, sm_port: int = DEFAULT_SM_PORT,
                 profile: RobotProfile | None = None, robot: Any = None, stall_periods: int | None = 10,
                 recorder: Recorder | None = None, connect_timeout: float = 5.0,
                 lock_path: str | None = None, deadman_s: float = 0.5, sched_fifo: bool = True,
                 gripper: bool = False, ft_sensor: WrenchSource | str | None = None, stream_process: bool = True,
                 lookahead_s: float = DEFAULT_LOOKAHEAD_S, force_lookahead_s: float = 0.0,
                 recover_timeout_s: float = 3.0) -> None:
        if robot is None:
            from robointel.robot import Robot

            robot = Robot.load("lrmate200id7l")
        profile = profile if profile is not None else lrmate_profile(robot)
        if profile.ndof != robot.nq:
            raise InvalidInput(f"profile has {profile.ndof} joints, the robot {robot.nq}", value=profile)
        config = DriverConfig(profile=profile, sm_port=int(sm_port), rmi_port=int(rmi_port),
                              rmi_connect_timeout=float(connect_timeout), sched_fifo=bool(sched_fifo))
        kw: dict[str, Any] = {"enable_ownership": lock_path is not None}
        if lock_path is not None:
            kw["lock_path"] = lock_path
        self.policy = DriverPolicy(config=config, enable_gripper=bool(gripper), auto_recover=False, connect_retries=2,
                                   bringup_settle_s=0.2, hold_wait_s=2.0, recovery_delay_s=0.0,
                                   recovery_motion_probe_s=2.0, ready_wait_s=5.0, **kw)
        super().__init__(robot.joint_names, profile.position_limits_lower, profile.position_limits_upper,
                         profile.velocity_limits, config.itp_s, paced=True, stall_periods=stall_periods,
                         recorder=recorder)
        self.host = host
        if not (np.isfinite(deadman_s) and deadman_s > 0):
            raise InvalidInput(f"deadman_s must be > 0 s, got {deadman_s}", value=deadman_s)
        self.deadman_s = float(deadman_s)
        if not (np.isfinite(recover_timeout_s) and recover_timeout_s > 0):
            raise InvalidInput(f"recover_timeout_s must be > 0 s, got {recover_timeout_s}", value=recover_timeout_s)
        self.recover_timeout_s = float(recover_timeout_s)
        self._owns_ft = isinstance(ft_sensor, str)
        self.ft_sensor: WrenchSource | None = (open_ft_sensor(ft_sensor) if isinstance(ft_sensor, str)
                                               else ft_sensor)
        if self.ft_sensor is not None and not isinstance(self.ft_sensor, WrenchSource):
            raise InvalidInput("ft_sensor must have a read() method returning a (6,) wrench", value=ft_sensor)
        self._snap_d: dict[str, Any] | None = {}  # None: build it from _vals (the _snap property)
        self._vals: tuple[float, ...] | None = None  # the streaming process's block at the last read
        self._read_ns = 0
        self._stale_ms = STALE_STATUS_PERIODS * self.period * 1e3
        self._last_state: RobotState | None = None
        self.stream_process = bool(stream_process) and not gripper
        check_lookahead(lookahead_s)
        self.lookahead_s = float(lookahead_s) if self.stream_process else 0.0
        self._stall_extra_s = self.lookahead_s  # a target is played lookahead_s after it arrived
        check_lookahead(force_lookahead_s)
        self.force_lookahead_s = float(force_lookahead_s)
        self.rmi_port = int(rmi_port)
        self.driver: Any = self._open_driver()

    def _open_driver(self) -> Any:
        """Bring up a driver session (in the streaming process or here).

        The RMI port is probed first (an unreachable host or a closed port is named in a few seconds); a
        failed bring-up is reported as one sentence naming the cause (:func:`~.fanuc_faults.bringup_cause`).

        Raises:
            ConnectionLost: the controller cannot be brought up; the message names the cause.
        """
        where = f"could not bring up the FANUC controller at {self.host}:{self.rmi_port}"
        why = probe_rmi(self.host, self.rmi_port)
        if why is not None:
            raise ConnectionLost(f"{where}: {why}", value=self.host, reason=why)
        try:
            if self.stream_process:
                return StreamProcess(self.host, self.policy, period=self.period, lookahead_s=self.lookahead_s,
                                     stall_periods=self.stall_periods if self.stall_periods is not None else 10**9)
            return FanucDriver(self.host, self.policy)
        except (FanucError, ConnectionLost, OSError, ValueError) as exc:
            cause = bringup_cause(str(exc) if not isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}",
                                  host=self.host, rmi_port=self.rmi_port, sm_port=self.policy.config.sm_port)
            raise ConnectionLost(f"{where}: {cause}", value=self.host, reason=cause) from exc

    # ------------------------------------------------------------------ backend hooks
    def _read(self) -> RobotState:
        if self.stream_process and not self._closed:
            return self._read_shared()
        core = self.driver.core if not self._closed else None
        if core is None:
            if self._last_state is not None:
                return self._make_state(self._last_state.t, self._last_state.q, self._last_state.qd,
                                        self._last_state.wrench, self._last_state.q_cmd)
            z = np.zeros(self.n)
            return self._make_state(0.0, z, z.copy(), None, None)
        s = core.get_snapshot()
        self._snap_d, self._vals = s, None
        wrench = (np.array([s["fx"], s["fy"], s["fz"], s["mx"], s["my"], s["mz"]], dtype=float)
                  if s.get("wrench_valid") else self._ft_wrench())
        st = self._make_state(int(s["rx_mono_ns"]) * 1e-9, np.array(s["q_meas"], dtype=float),  # type: ignore
                              np.array(s["qd_est"], dtype=float), wrench,  # type: ignore[arg-type]
                              np.array(s["q_cmd"], dtype=float))  # type: ignore[arg-type]
        self._last_state = st
        return st

    def _read_shared(self) -> RobotState:
        """:meth:`_read` from the streaming process's block, without building the snapshot dict.

        The per-target path (docs/design/streaming.md): one seqlock copy, the state's arrays made
        from it; :attr:`_snap` builds the dict from the same copy only when something asks for it.
        """
        v = self.driver.head()
        base = self.driver.base_ns
        self._vals, self._snap_d, self._read_ns = v, None, time.monotonic_ns()
        wrench = np.array(v[ss.WR:ss.WR + 6]) if v[ss.WRENCH_VALID] else self._ft_wrench()
        st = self._make_state((base + int(v[ss.RX] * 1e9)) * 1e-9, np.array(v[ss.QM:ss.QM + 6]),
                              np.array(v[ss.QD:ss.QD + 6]), wrench, np.array(v[ss.QC:ss.QC + 6]))
        self._last_state = st
        return st

    @property
    def _snap(self) -> dict[str, Any]:
        """The core's snapshot behind the last state read (``core.get_snapshot()``; {} before any)."""
        if self._snap_d is None:
            v = self._vals
            self._snap_d = ss.snapshot(v, self.driver.base_ns, self._read_ns) if v is not None else {}
        return self._snap_d

    def _ft_wrench(self) -> npt.NDArray[np.float64] | None:
        """The wrist sensor's (6,) wrench, or None (no sensor, no fresh reading, not six finite numbers)."""
        if self.ft_sensor is None:
            return None
        w = self.ft_sensor.read()
        if w is None:
            return None
        w = np.asarray(w, dtype=float).reshape(-1)
        return w if w.shape == (6,) and np.all(np.isfinite(w)) else None

    @property
    def has_wrench(self) -> bool:
        """True when the state carries a wrench: a force block on Stream Motion or a wrist F/T sensor."""
        return self.ft_sensor is not None or bool(self._snap.get("wrench_valid", False))

    def _fault_of(self, state: RobotState) -> tuple[RobotMode, str, tuple[str, ...]] | None:
        v = self._vals  # the streaming process's block: a quiet one (the usual case) needs no snapshot
        if v is not None and ss.quiet(v, self.driver.base_ns, self._read_ns, self._stale_ms) and self.driver.alive():
            return None
        s = self._snap
        core = self.driver.core
        if core is None or not core.running:
            return RobotMode.DISCONNECTED, "connection lost: the Stream Motion session is down", ("disconnected",)
        age = float(s.get("rx_age_ms", 0.0))
        fault = FaultReason(int(s.get("fault", 0)))  # type: ignore[call-overload]
        if age > self._stale_ms or fault == FaultReason.RX_SILENT:
            return (RobotMode.DISCONNECTED, f"connection lost: no controller status for {age:.0f} ms",
                    ("rx_silent",))
        faults = []
        if s.get("e_stopped"):
            faults.append("e_stop")
        if s.get("in_error"):
            faults.append("in_error")
        if s.get("tp_enabled"):
            faults.append("teach_pendant_enabled")
        if fault != FaultReason.NONE and fault.name.lower() not in faults:
            faults.append(fault.name.lower())
        if not s.get("motion_possible", False):
            faults.append("motion_not_possible")
        if s.get("refused") and not faults:
            faults.append("faulted")
        if not faults and s.get("stalled"):
            why = (f"command stream stalled: no target to play for {float(s.get('stall_gap_s', 0.0)) * 1e3:.0f} ms "
                   f"(> {self.stall_periods} periods; the look-ahead is {self._stall_extra_s * 1e3:.0f} ms)")
            return RobotMode.STOPPED, why, ("stream_stalled",)
        if not faults:
            return None
        why = {"e_stop": "e-stop pressed", "in_error": "controller alarm (in error)",
               "teach_pendant_enabled": "teach pendant enabled",
               "faulted": "controller refused motion"}.get(faults[0], faults[0].replace("_", " "))
        return RobotMode.FAULTED, f"controller stopped: {why} [{', '.join(faults)}]", tuple(faults)

    def _needs_monitor(self) -> bool:
        return True

    def _latch_fault(self, mode: RobotMode, why: str, faults: tuple[str, ...]) -> None:
        """Stop commanding (the base class), then name the controller's active alarms in the reason.

        A fault always carries a reason: the fault names when the caller gave none, and for an alarm or an
        e-stop the alarm texts the controller reports over RMI (``FRC_ReadError``), e.g. ``SRVO-002 Teach
        pendant E-stop``; a failed read leaves the reason as it was.
        """
        super()._latch_fault(mode, why or f"controller fault [{', '.join(faults) or 'unknown'}]", faults)
        if mode is RobotMode.FAULTED and {"in_error", "e_stop", "motion_not_possible"} & set(faults):
            texts = read_alarms(self.driver, streaming=self.stream_process)
            if texts:
                self._why = f"{self._why}; controller alarms: {'; '.join(texts)}"


    def _send(self, q: npt.NDArray[np.float64]) -> None:
        try:
            self.driver.servo_j(q, self.period)
        except RobotFaultedError as exc:
            self._latch_fault(RobotMode.FAULTED, f"controller refused motion: {exc}", ("faulted",))
            raise ControllerFault(self._why, value=self._read(), reason=self._why) from exc
        except FanucConnectionError as exc:
            self._latch_fault(RobotMode.DISCONNECTED, f"connection lost: {exc}", ("disconnected",))
            raise ConnectionLost(self._why, value=self._read(), reason=self._why) from exc

    @contextlib.contextmanager
    def low_latency(self, lookahead_s: float | None = None) -> Iterator[None]:
        """Stream the ``with`` block's targets with a force loop's look-ahead (default ``force_lookahead_s``).

        With the streaming process a stream that is running is held first (its queue plays out), the
        streaming process then submits every target of the block as soon as it arrives (look-ahead 0)
        or with the look-ahead asked, and the look-ahead given at construction comes back after the
        block (a running stream is held again). With the driver in this process targets always go
        out at once: nothing changes.

        Raises:
            InvalidInput: ``lookahead_s`` outside [0, 1] s.
        """
        lookahead_s = self.force_lookahead_s if lookahead_s is None else lookahead_s
        check_lookahead(lookahead_s)
        if not self.stream_process:
            yield
            return
        with self._lookahead_section(lambda: self.driver, lookahead_s, self.lookahead_s):
            yield

    def _hold(self) -> None:
        try:
            self.driver.hold()
        except FanucError:  # the fault is reported by the next state check
            pass

    def _halt(self) -> None:
        self.driver.stop_j()  # never raises; the core brakes within one tick

    def _recover(self) -> None:
        """The controller's recovery ladder, retried until a status shows no fault (``recover_until_clear``)."""
        def ladder() -> bool:
            ok = bool(self.driver.recover(escalate_reconnect=False))
            self.driver.arm()
            return ok

        def fault() -> str | None:
            f = self._fault_of(self._read())
            return None if f is None else f[1]

        why = recover_until_clear(ladder, fault, period=self.period, timeout_s=self.recover_timeout_s)
        if why is not None:
            raise ControllerFault(f"recovery failed after {self.recover_timeout_s:.1f} s: {why}",
                                  value=self._read(), reason=why)

    def _close(self) -> None:
        try:
            if not self.stream_process:  # the streaming process does this itself
                self._stop_core_between_ticks()
            self.driver.close()
        finally:
            if self._owns_ft and self.ft_sensor is not None:
                self.ft_sensor.close()  # type: ignore[attr-defined]

    def _stop_core_between_ticks(self) -> None:
        """End the Stream Motion session between two ticks (``stream_child.stop_core_between_ticks``).

        ``FanucDriver.close`` alone may double-send (measured in 6 of 40 closes at load 24).
        """
        with realtime_thread(freeze_gc=False):
            stop_core_between_ticks(self.driver, self.period)

    def _commanded(self) -> npt.NDArray[np.float64] | None:
        self._read()
        return np.array(self._snap["q_cmd"], dtype=float) if self._snap else None

    def execute(self, trajectory: Trajectory, *, on_cycle: CycleCallback | None = None) -> ExecutionResult:
        """Play ``trajectory`` back on the controller's real-time core, supervised every period.

        The trajectory is resampled at the period (``Trajectory.resample``) and checked whole by the
        safety gate; the knots (t, q, qd) go to ``FanucDriver.move_trajectory`` (Hermite playback in
        the 8 ms core, so the commanded path is the planned one, not a servo's lagging chase of it).
        Every period this process feeds the core's deadman (``deadman_s``: if this process dies or
        hangs, the core stops), reads the state, stops at once on a fault and calls ``on_cycle``.

        Returns:
            The :class:`ExecutionResult`; ``q_cmd`` is the core's commanded position each period.

        Raises:
            InvalidInput: wrong joint count. UnsafeCommand: the gate or the driver refused the path.
            ControllerFault, ConnectionLost: the robot stopped mid-run (``.value`` is (state, partial result)).
        """
        if not isinstance(trajectory, Trajectory) or trajectory.q.shape[1] != self.n:
            raise InvalidInput(f"execute needs a Trajectory with {self.n} joints", value=trajectory)
        with realtime_thread():  # entered before the core starts playing
            return self._play(trajectory, on_cycle)

    def _play(self, trajectory: Trajectory, on_cycle: CycleCallback | None) -> ExecutionResult:
        """Submit the checked knots to the core and supervise the playback (see :meth:`execute`)."""
        rs = trajectory.resample(self.period)
        times_ns = np.round((rs.t - rs.t[0]) * 1e9).astype(np.int64)
        with self._lock:
            self._refuse_if_stopped()
            st = self._read()
            fault = self._fault_of(st)
            if fault is not None:
                self._latch_fault(*fault)
                self._refuse_if_stopped()
            ref = self._last_cmd if self._last_cmd is not None else self._commanded()
            self.gate.check_path(rs.q, ref)
            if self.recorder is not None:
                self.recorder.trajectory(st.t, trajectory)
            try:
                handle = self.driver.move_trajectory(times_ns, rs.q, rs.qd, deadman_s=self.deadman_s,
                                                     asynchronous=True)
            except TrajectoryValidationError as exc:
                raise UnsafeCommand(f"the controller driver refused the trajectory: {exc}", value=rs.q) from exc
            except RobotFaultedError as exc:
                self._latch_fault(RobotMode.FAULTED, f"controller refused motion: {exc}", ("faulted",))
                raise ControllerFault(self._why, value=self._read(), reason=self._why) from exc
            self._mode, self._last_cmd, self._last_cmd_wall = RobotMode.STREAMING, None, time.perf_counter()
            self._stall_check = False  # the core's deadman supervises this process during playback
            self._ensure_watchdog()
        try:
            return self._supervise(handle, rs, on_cycle)
        except ControllerFault:
            raise
        except BaseException as exc:  # on_cycle raised or the caller interrupted: the core must not play on
            self.stop(f"execution aborted: {type(exc).__name__}: {exc}")
            raise
        finally:
            self._stall_check = True

    def _supervise(self, handle: Any, rs: Trajectory, on_cycle: CycleCallback | None) -> ExecutionResult:
        """Feed the deadman, read and record the state, stop on a fault, once per period."""
        K = len(rs.t) + int(2.0 / self.period)  # playback plus up to 2 s of capture and settle
        ts, qs, qc, cyc = np.zeros(K), np.zeros((K, self.n)), np.zeros((K, self.n)), np.zeros(K)
        missed, k = 0, 0
        t0 = time.perf_counter()
        while k < K:
            sleep_until(t0 + k * self.period)
            c0 = time.perf_counter()
            with self._lock:
                self.driver.kick()
                st = self._read()
                fault = self._fault_of(st) if self._mode is RobotMode.STREAMING else (self._mode, self._why, ())
                if fault is not None:
                    if self._mode is RobotMode.STREAMING:
                        self._latch_fault(*fault)
                    cls = ConnectionLost if self._mode is RobotMode.DISCONNECTED else ControllerFault
                    part = ExecutionResult(ts[:k], qc[:k], qs[:k], cyc[:k], missed, False)
                    raise cls(f"execution stopped: {self._why}", value=(self._read(), part), reason=self._why)
                self._last_cmd_wall = time.perf_counter()
                if self.recorder is not None:
                    self.recorder.joint_state(st)
                    if st.q_cmd is not None:
                        self.recorder.command(st.t, st.q_cmd)
            c1 = time.perf_counter()
            ts[k], qs[k], qc[k], cyc[k] = st.t, st.q, st.q_cmd if st.q_cmd is not None else st.q, (c1 - c0) * 1e6
            if c1 > t0 + (k + 1) * self.period:
                missed += 1
            k += 1
            if on_cycle is not None:
                on_cycle(k - 1, st)
            if handle.done():
                break
        result = handle.result()
        self.hold()
        return ExecutionResult(ts[:k], qc[:k], qs[:k], cyc[:k], missed, result is MotionResult.DONE,
                               extra={"motion_result": str(result.value if result is not None else "running")})

    # ------------------------------------------------------------------ FANUC only
    def reconnect(self) -> None:
        """Close the Stream Motion + RMI session and bring a new one up; the robot holds.

        Raises:
            ConnectionLost: the controller cannot be brought up.
        """
        with self._lock:
            if self._closed:
                raise ConnectionLost("the robot interface is closed; open a new one", reason="closed")
            try:
                self.driver.close()
            except FanucError:
                pass  # the old session is gone either way
            try:
                self.driver = self._open_driver()
            except ConnectionLost as exc:
                self._latch_fault(RobotMode.DISCONNECTED, f"reconnect failed: {exc}", ("disconnected",))
                raise ConnectionLost(self._why, value=self._read(), reason=self._why) from exc
            self._mode, self._why, self._faults, self._last_cmd = RobotMode.IDLE, "", (), None
            self._vals, self._snap_d = None, {}

    def timing_stats(self) -> dict[str, Any]:
        """The driver's real-time core statistics (tick intervals, TX counts, missed RX ticks).

        With the streaming process, also its window counters: ``stream_windows``, ``stream_fresh``,
        ``stream_starved`` (the caller late by more than the look-ahead), ``stream_late`` (the
        streaming process after the tick), ``stream_submits`` and ``lookahead_s``.
        """
        return dict(self.driver.timing_stats())
