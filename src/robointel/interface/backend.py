"""What every backend shares: the safety gate, the stall watchdog, execution of a trajectory, recording.

A backend subclasses :class:`Backend` and implements the few ``_``-methods that talk to its robot
(``_send``, ``_read``, ``_hold``, ``_halt``, ``_recover``, ``_close``). Everything that decides whether
a command may go out lives here, once.
"""
from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from types import TracebackType
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from robointel.errors import ConnectionLost, ControllerFault, InvalidInput, UnsafeCommand
from robointel.interface.approach import approach_trajectory
from robointel.interface.gate import SafetyGate
from robointel.interface.protocol import CycleCallback
from robointel.interface.realtime import realtime_thread, sleep_until
from robointel.interface.state import RobotMode, RobotState
from robointel.trajectory import Trajectory

MONITOR_PERIODS = 5
"""Without a stall watchdog, a backend that must be polled for faults is polled every this many periods."""

__all__ = ["Backend", "ExecutionResult", "Recorder", "MONITOR_PERIODS", "sleep_until"]


class Recorder(Protocol):
    """Receives everything a run produces (see :class:`robointel.io.mcap_log.McapRecorder`)."""

    def joint_state(self, state: RobotState) -> None:
        """A state reading (joint state, and the wrench when there is one)."""

    def command(self, t: float, q: npt.NDArray[np.float64]) -> None:
        """A joint position command sent at time ``t`` s."""

    def trajectory(self, t: float, trajectory: Trajectory) -> None:
        """A trajectory about to be executed at time ``t`` s."""


@dataclass
class ExecutionResult:
    """What :meth:`Backend.execute` measured.

    Attributes:
        t: (K,) time of each cycle's state, s.
        q_cmd: (K, n) the targets sent, rad.
        q: (K, n) the measured positions after each cycle, rad.
        cycle_us: (K,) robointel's own compute per command (gate, state read, send, record), µs.
        missed_cycles: cycles whose target went out after the end of its period (paced backends).
        completed: the whole trajectory was sent.
    """

    t: npt.NDArray[np.float64]
    q_cmd: npt.NDArray[np.float64]
    q: npt.NDArray[np.float64]
    cycle_us: npt.NDArray[np.float64]
    missed_cycles: int
    completed: bool
    extra: dict[str, object] = field(default_factory=dict)

    @property
    def tracking_rms_rad(self) -> float:
        """RMS of measured minus commanded joint position over all cycles and joints, rad."""
        return float(np.sqrt(np.mean((self.q - self.q_cmd) ** 2)))


class Backend:
    """The shared half of every :class:`~robointel.interface.protocol.RobotInterface` backend.

    Args:
        joint_names: n joint names.
        lower: (n,) lower joint limits, rad.
        upper: (n,) upper joint limits, rad.
        velocity_limit: (n,) maximum joint speeds, rad/s.
        period: controller period, s.
        paced: execute in wall-clock time (one target per period); False steps as fast as possible.
        stall_periods: stop the robot when a stream gives no target for this many periods
            (None: no watchdog).
        recorder: optional :class:`Recorder` that receives states, commands and trajectories.
    """

    clocked = False
    """The state advances on the robot's own clock, at its ticks (a controller, a streaming process), not
    when a target is sent: a force loop paces itself on those ticks
    (:class:`~robointel.interface.tick_pacer.TickPacer`)."""

    def __init__(self, joint_names: Sequence[str], lower: npt.ArrayLike, upper: npt.ArrayLike,
                 velocity_limit: npt.ArrayLike, period: float, *, paced: bool, stall_periods: int | None = 10,
                 recorder: Recorder | None = None) -> None:
        self.joint_names = list(joint_names)
        self.n = len(self.joint_names)
        self.gate = SafetyGate(self.joint_names, lower, upper, velocity_limit, period)
        if stall_periods is not None and stall_periods < 1:
            raise InvalidInput(f"stall_periods must be >= 1 or None, got {stall_periods}", value=stall_periods)
        self.paced = bool(paced)
        self.stall_periods = stall_periods
        self.recorder = recorder
        self._lock = threading.RLock()
        self._mode = RobotMode.IDLE
        self._why = ""
        self._faults: tuple[str, ...] = ()
        self._last_cmd: npt.NDArray[np.float64] | None = None
        self._last_cmd_wall = 0.0
        self._closed = False
        self._watch_stop = threading.Event()
        self._watch: threading.Thread | None = None
        self._stall_check = True  # off while a backend's own deadman supervises (fanuc execute)
        self._stall_extra_s = 0.0  # added to the stall limit: a backend that plays targets later (look-ahead)
        self.sent_times: list[float] = []
        """Wall (``time.perf_counter``) times of every command that reached the backend."""

    # ------------------------------------------------------------------ backend hooks
    def _send(self, q: npt.NDArray[np.float64]) -> None:
        raise NotImplementedError

    def _read(self) -> RobotState:
        raise NotImplementedError

    def _hold(self) -> None:
        raise NotImplementedError

    def _halt(self) -> None:
        """Stop motion at once (brake to rest where the robot is)."""
        raise NotImplementedError

    def _recover(self) -> None:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError

    def _commanded(self) -> npt.NDArray[np.float64] | None:
        """The position the robot currently holds or heads to (the jump reference), rad."""
        return None

    def _fault_of(self, state: RobotState) -> tuple[RobotMode, str, tuple[str, ...]] | None:
        """(FAULTED or DISCONNECTED, why, fault names) if ``state`` shows a controller-side fault, else None."""
        return None

    def _make_state(self, t: float, q: npt.NDArray[np.float64], qd: npt.NDArray[np.float64],
                    wrench: npt.NDArray[np.float64] | None, q_cmd: npt.NDArray[np.float64] | None,
                    faults: tuple[str, ...] = ()) -> RobotState:
        """A :class:`RobotState` carrying the interface's own mode and stop reason."""
        return RobotState(t=t, q=q, qd=qd, wrench=wrench, mode=self._mode, faults=faults or self._faults,
                          why_stopped=self._why, q_cmd=q_cmd)

    # ------------------------------------------------------------------ the interface
    @property
    def period(self) -> float:
        """The controller period, s."""
        return self.gate.period

    @property
    def has_wrench(self) -> bool:
        """True when :meth:`state` carries the F/T wrench (an F/T sensor on the wrist)."""
        return False

    def state(self) -> RobotState:
        """The latest state (never raises)."""
        return self._read()

    def _refuse_if_stopped(self) -> None:
        if self._closed:
            raise ConnectionLost("the robot interface is closed; open a new one", value=self._read(),
                                 reason="closed")
        if self._mode in (RobotMode.STOPPED, RobotMode.FAULTED, RobotMode.DISCONNECTED):
            cls = ConnectionLost if self._mode is RobotMode.DISCONNECTED else ControllerFault
            raise cls(f"the robot is {self._mode.value}: {self._why}; call recover() once the cause is cleared"
                      + ("" if cls is ControllerFault else " (or reconnect)"),
                      value=self._read(), reason=self._why)

    def stream(self, q_target: npt.ArrayLike) -> RobotState:
        """Send one joint position target (n,) rad through the safety gate; return the state.

        Raises:
            UnsafeCommand: the gate refused the target (the robot holds the previous one).
            ControllerFault: the robot is stopped or faulted; ConnectionLost: the link is lost.
        """
        with self._lock:
            self._refuse_if_stopped()
            st = self._read()
            fault = self._fault_of(st)
            if fault is not None:
                self._latch_fault(*fault)
                self._refuse_if_stopped()
            ref = self._last_cmd if self._last_cmd is not None else self._commanded()
            if ref is None:
                ref = st.q
            try:
                q = self.gate.check(q_target, ref)
            except UnsafeCommand:
                self._hold()
                self._mode = RobotMode.HOLDING
                raise
            self._send(q)
            now = time.perf_counter()
            self.sent_times.append(now)
            self._last_cmd, self._last_cmd_wall = q, now
            self._mode = RobotMode.STREAMING
            if self.recorder is not None:
                self.recorder.command(st.t, q)
                self.recorder.joint_state(st)
            self._ensure_watchdog()
            return st

    def _latch_fault(self, mode: RobotMode, why: str, faults: tuple[str, ...]) -> None:
        """Stop commanding after a fault the backend reported (called under the lock)."""
        self._mode, self._why, self._faults, self._last_cmd = mode, why, faults, None
        self._halt()

    def execute(self, trajectory: Trajectory, *, on_cycle: CycleCallback | None = None) -> ExecutionResult:
        """Stream ``trajectory`` resampled at the period (``Trajectory.resample``), then hold.

        The whole resampled path is checked by the gate before the first target goes out, and its
        first sample must be within one period's reach of where the robot is.

        Args:
            trajectory: a :class:`~robointel.io.trajectory.Trajectory` with n joints, rad.
            on_cycle: called after each target with (cycle index, state); raising from it holds and
                re-raises.

        Returns:
            The :class:`ExecutionResult`.

        Raises:
            InvalidInput: wrong joint count. UnsafeCommand: the path fails the gate (nothing sent).
            ControllerFault, ConnectionLost: the robot stopped on its side mid-run (the robot is left
                stopped; the partial result is on ``.value`` as ``(state, result)``).
        """
        if not isinstance(trajectory, Trajectory) or trajectory.q.shape[1] != self.n:
            raise InvalidInput(f"execute needs a Trajectory with {self.n} joints", value=trajectory)
        path = trajectory.resample(self.period).q
        with self._lock:
            self._refuse_if_stopped()
            ref = self._last_cmd if self._last_cmd is not None else self._commanded()
            self.gate.check_path(path, self._read().q if ref is None else ref)
        if self.recorder is not None:
            self.recorder.trajectory(self._read().t, trajectory)
        K = len(path)
        ts, qs, cyc = np.zeros(K), np.zeros((K, self.n)), np.zeros(K)
        missed, done = 0, 0
        with realtime_thread() if self.paced else contextlib.nullcontext():  # paced: a real-time section
            t0 = time.perf_counter()
            try:
                for k in range(K):
                    if self.paced:
                        sleep_until(t0 + k * self.period)
                    c0 = time.perf_counter()
                    st = self.stream(path[k])
                    c1 = time.perf_counter()
                    cyc[k] = (c1 - c0) * 1e6
                    if self.paced and c1 > t0 + (k + 1) * self.period:
                        missed += 1
                    ts[k], qs[k] = st.t, st.q
                    done = k + 1
                    if on_cycle is not None:
                        on_cycle(k, st)
            except ControllerFault as exc:
                res = ExecutionResult(ts[:done], path[:done], qs[:done], cyc[:done], missed, False)
                exc.value = (exc.value, res)
                raise
            except BaseException:
                self.hold()
                raise
        self.hold()
        # the state after each target is the one read before it went out: shift by one cycle
        return ExecutionResult(ts, path, np.vstack([qs[1:], self._read().q[None]]), cyc, missed, True)

    def move_to(self, q_goal: npt.ArrayLike, *, fraction: float = 0.2) -> ExecutionResult:
        """Bring the robot to ``q_goal`` (n,) rad by a quintic joint move at ``fraction`` of its limits.

        The acceleration limit is the robot core's (3 x the speed limit per second).

        Returns:
            The :class:`ExecutionResult` of the move (an empty move when already there).

        Raises:
            InvalidInput: a bad goal or fraction. UnsafeCommand: the goal is outside the limits.
            ControllerFault, ConnectionLost: as :meth:`execute`.
        """
        with self._lock:
            self._refuse_if_stopped()
            ref = self._last_cmd if self._last_cmd is not None else self._commanded()
            here = self._read().q if ref is None else ref
        self.gate.check(q_goal, None)  # inside the limits and finite
        move = approach_trajectory(here, q_goal, self.gate.velocity_limit, 3.0 * self.gate.velocity_limit,
                                   fraction=fraction, period=self.period, joint_names=self.joint_names)
        return self.execute(move)

    @contextlib.contextmanager
    def low_latency(self, lookahead_s: float | None = None) -> Iterator[None]:
        """Stream the targets of the ``with`` block with the look-ahead of a force loop.

        A force loop closed over the stream (lead-through, the skills' admittance, teleoperation)
        must see its target go out at once, not after a look-ahead queue. Backends without a
        look-ahead (``sim``, the FANUC driver in this process) stream that way always; this does
        nothing there.

        Args:
            lookahead_s: the look-ahead for the block, s (0: each target at once); None: the
                backend's own for force loops (``FanucRobot(force_lookahead_s=...)``, default 0).

        Yields:
            None.
        """
        yield

    @contextlib.contextmanager
    def _lookahead_section(self, ring: Callable[[], Any], lookahead_s: float, base_s: float) -> Iterator[None]:
        """:meth:`low_latency`'s body for a backend fed through a streaming process's look-ahead ring.

        A stream that is running is held first (its queue plays out), ``ring().set_lookahead(lookahead_s)``
        applies to the block's targets (0: each at once), and ``base_s`` comes back after the block (a
        running stream is held again). The stall watchdog's limit follows the look-ahead.
        """
        with self._lock:
            if self._mode is RobotMode.STREAMING:
                self.hold()
            ring().set_lookahead(lookahead_s)
            self._stall_extra_s = float(lookahead_s)
        try:
            yield
        finally:
            with self._lock:
                if self._mode is RobotMode.STREAMING:
                    self.hold()
                if not self._closed:
                    ring().set_lookahead(base_s)
                self._stall_extra_s = float(base_s)

    @contextlib.contextmanager
    def force_loop(self) -> Iterator[None]:
        """The section a force loop closed over the stream runs in (lead-through, the skills' admittance).

        Its targets go out at once (:meth:`low_latency`), and on a paced backend the calling thread
        runs as a real-time thread (:func:`~robointel.interface.realtime.realtime_thread`).

        Yields:
            None.
        """
        with realtime_thread() if self.paced else contextlib.nullcontext(), self.low_latency():
            yield

    def hold(self) -> None:
        """Hold the last commanded position; the stall watchdog disarms."""
        with self._lock:
            if self._closed or self._mode in (RobotMode.STOPPED, RobotMode.FAULTED, RobotMode.DISCONNECTED):
                return
            self._hold()
            self._mode = RobotMode.HOLDING

    def stop(self, reason: str) -> None:
        """Stop at once; every later target is refused with ``reason`` until :meth:`recover`."""
        with self._lock:
            if self._closed:
                return
            self._halt()
            self._mode = RobotMode.STOPPED
            self._why = str(reason)
            self._last_cmd = None

    def recover(self) -> None:
        """Clear a stop or a fault whose cause is gone; the robot holds where it is.

        Raises:
            ControllerFault: the controller still reports a fault.
        """
        with self._lock:
            if self._closed:
                raise ConnectionLost("the robot interface is closed; open a new one", reason="closed")
            self._recover()
            self._mode, self._why, self._faults, self._last_cmd = RobotMode.IDLE, "", (), None

    def close(self) -> None:
        """Stop the watchdog, hold, and release the robot (idempotent)."""
        self._watch_stop.set()
        if self._watch is not None and self._watch is not threading.current_thread():
            self._watch.join(timeout=2.0)
        with self._lock:
            if self._closed:
                return
            try:
                self._close()
            finally:
                self._closed = True
                self._mode = RobotMode.DISCONNECTED
                self._why = self._why or "closed"

    def __enter__(self) -> Backend:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    # ------------------------------------------------------------------ watchdog
    def _ensure_watchdog(self) -> None:
        if self._watch is None and (self.stall_periods is not None or self._needs_monitor()):
            self._watch = threading.Thread(target=self._watch_loop, name="robointel-watchdog", daemon=True)
            self._watch.start()

    def _needs_monitor(self) -> bool:
        """True when the backend must be polled for faults between commands."""
        return False

    def _watch_loop(self) -> None:
        """Stop a stalled stream (checking the backend for a fault first, to report the right cause).

        The thread sleeps until the stall deadline of the last command, so while targets arrive on
        time it does not run at all: a watchdog woken every period would take the interpreter
        lock (and the interface lock) every period, and when the scheduler preempts it while it
        holds them, the streaming thread waits a whole scheduling latency. Each target's own
        fault check (:meth:`stream`) covers faults while streaming; backends that must be polled
        between commands (``fanuc``) are polled at the stall deadline, or every
        :data:`MONITOR_PERIODS` periods without a stall watchdog.
        """
        period = self.period

        def stall_limit() -> float:  # read each turn: low_latency() changes the look-ahead
            return (self.stall_periods * period + self._stall_extra_s if self.stall_periods is not None
                    else MONITOR_PERIODS * period)

        timeout = stall_limit()
        while not self._watch_stop.wait(timeout):
            timeout = limit = stall_limit()
            if not self._lock.acquire(timeout=period):
                continue  # a command (with its own fault check) is going out right now
            try:
                if self._closed:
                    return
                if self._mode is not RobotMode.STREAMING:
                    continue
                gap = time.perf_counter() - self._last_cmd_wall
                if gap < limit and self._stall_check:
                    timeout = max(0.001, limit - gap + 0.1 * period)
                    continue
                if self._needs_monitor():
                    fault = self._fault_of(self._read())
                    if fault is not None:
                        self._latch_fault(*fault)
                        continue
                if self.stall_periods is not None and self._stall_check:
                    self._halt()
                    self._mode = RobotMode.STOPPED
                    self._faults = ("stream_stalled",)
                    self._why = (f"command stream stalled: no target for {gap * 1e3:.0f} ms "
                                 f"(> {self.stall_periods} periods)")
                    self._last_cmd = None
            finally:
                self._lock.release()
