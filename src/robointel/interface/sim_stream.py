"""The paced ``sim`` backend whose physics runs in a streaming process of its own.

``SimRobot(paced=True)`` steps MuJoCo inside the caller's ``stream()``: a planner thread of the
caller's process holding the interpreter lock in a long C call makes the stream miss windows
(priority inversion on the lock, docs/design/streaming.md). :class:`SimStreamRobot` moves the
physics out of the caller's interpreter, as ``FanucRobot(stream_process=True)`` moves the FANUC
driver: a child process (:mod:`robointel.interface.sim_child`) owns the workcell, built there from
picklable arguments, and steps it one controller period per tick of the wall clock from the targets
of the shared look-ahead ring (:class:`~robointel.interface.stream_ring.RingProcess`); its state
(time, q, qd, the wrench, the commanded target, a divergence, the stall stop) comes back through the
seqlock block. Each window is counted fresh, starved or late in the child, as on the FANUC.

The safety stays in this process: the gate before anything is written into the ring, ``hold``,
``stop``, ``recover``, the stall watchdog; the child adds its own stall stop (``stall_periods``
windows without a target to play). A target is played ``lookahead_s`` after it arrived (default
0.1 s); :meth:`SimStreamRobot.low_latency` (the force loops) plays each one at once.
"""
from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from robointel.errors import ConnectionLost, ControllerFault, InvalidInput, RobointelError
from robointel.interface import stream_layout as layout
from robointel.interface import stream_state as ss
from robointel.interface.backend import Backend, ExecutionResult, Recorder
from robointel.interface.protocol import CycleCallback
from robointel.interface.sim import substeps_of
from robointel.interface.state import RobotMode, RobotState
from robointel.interface.stream_ring import REPLY_TIMEOUT_S, RingProcess, check_lookahead
from robointel.robot import Robot
from robointel.sim.workcell import CONTROL_DT
from robointel.trajectory import Trajectory

DEFAULT_LOOKAHEAD_S = 0.1
"""Look-ahead of the sim's streaming process, s (the FANUC's default)."""
START_TIMEOUT_S = 300.0
"""The child's bring-up (an interpreter importing MuJoCo, Pinocchio and robointel, the workcell built):
~3 s on an idle machine, 14 s measured at load 6, s."""
SETTLE_TIMEOUT_S = 30.0
"""How long :meth:`SimStreamRobot.execute` waits for its queue to be played, beyond the look-ahead, s."""
_SCRIPT = str(Path(__file__).with_name("sim_child.py"))
_ROOT = str(Path(__file__).resolve().parents[2])  # the directory holding this robointel package
_SETUP_ERRORS = ("InvalidInput", "ShapeError", "NotFinite", "LimitViolation", "UnknownRobot", "DataMissing",
                 "DescriptionError", "TypeError", "ValueError")
_TICK, _FAULT, _STALLED, _REFUSED = ss.R["cmd_tick"], ss.R["fault"], ss.R["stalled"], ss.R["refused"]
_PUBLISHED = layout.STATE_INDEX["published_s"].start


class SimStreamProcess(RingProcess):
    """The sim's streaming process (the caller's end): a workcell stepped at wall-clock ticks in a child.

    Args:
        workcell_kwargs: keyword arguments of :class:`~robointel.sim.Workcell` (picklable; {}: the
            default cell, the LR Mate on its table with the F/T sensor).
        q0: (6,) start configuration, rad (None: the workcell's own).
        period: controller period, s.
        lookahead_s: a target is played this long after it arrived, s (0: at once).
        stall_periods: the child stops the arm after this many consecutive windows without a target.
        workcell_factory: ``"module:function"`` building the workcell in the child from ``factory_args``
            (picklable) instead of ``Workcell(**workcell_kwargs)`` (a cell whose model is edited after it
            is built, e.g. :func:`~robointel.skills.cells.plate_workcell`).
        factory_args: the factory's positional arguments.
        lock_memory: the child locks its memory (``mlockall``; refused without CAP_IPC_LOCK or a large
            RLIMIT_MEMLOCK, and then it goes on unlocked: ``timing_stats()["memory_locked"]``).

    Raises:
        InvalidInput: bad arguments (the child's refusal of the workcell's arguments included).
        ConnectionLost: the child did not come up.
    """

    LOST: ClassVar[type[Exception]] = ConnectionLost
    ERRORS: ClassVar[tuple[type[Exception], ...]] = (RobointelError,)
    START_S: ClassVar[float] = START_TIMEOUT_S

    def __init__(self, workcell_kwargs: Mapping[str, Any], q0: npt.ArrayLike | None, *, period: float,
                 lookahead_s: float, stall_periods: int, workcell_factory: str | None = None,
                 factory_args: tuple[Any, ...] = (), lock_memory: bool = False) -> None:
        q = None if q0 is None else [float(x) for x in np.asarray(q0, dtype=float).reshape(-1)]
        hello = (dict(workcell_kwargs), q, workcell_factory, tuple(factory_args), bool(lock_memory))
        super().__init__(_SCRIPT, hello, period=period, lookahead_s=lookahead_s, stall_periods=stall_periods,
                         path=_ROOT)
        self.t0 = float(self.hello_reply["t0"])
        """The workcell's simulated time at tick 0, s."""
        self.has_ft = bool(self.hello_reply["has_ft"])

    def remote_error(self, kind: str, message: str) -> Exception:
        """InvalidInput for a refused setup, else ConnectionLost naming the child's error."""
        if kind in _SETUP_ERRORS:
            return InvalidInput(f"the simulation process refused its setup: {kind}: {message}", value=message)
        return ConnectionLost(f"the simulation process failed: {kind}: {message}", reason=message)

    def recover(self) -> None:
        """Clear a divergence and the stall flag in the child; the queue starts empty, the arm holds.

        Returns once the child has published its state after the recovery (it answers first), so the
        next read does not see the flags it cleared.
        """
        self._last_slot = None
        self.call("recover")
        answered = (time.monotonic_ns() - self.base_ns) * 1e-9
        deadline = time.monotonic() + REPLY_TIMEOUT_S
        while self._mv[_PUBLISHED] <= answered and self.alive() and time.monotonic() < deadline:
            time.sleep(0.0005)

    def timing_stats(self) -> dict[str, Any]:
        """The child's physics figures and window counters.

        ``tick_count``, ``step_max_ms`` (the longest window's physics), ``catch_up_max_windows`` (the most
        windows stepped at one wake-up), and :meth:`~robointel.interface.stream_ring.RingProcess.window_stats`.
        """
        out = dict(self.call("timing_stats"))
        out.update(self.window_stats())
        return out

    def held(self) -> bool:
        """True once the child has played every target up to the last :meth:`hold` and holds."""
        return int(self.read_state()["holds"]) >= int(self._buf[layout.H_HOLD_GEN])


class SimStreamRobot(Backend):
    """A :class:`~robointel.interface.protocol.RobotInterface` on a workcell stepped in a streaming process.

    ``open_robot("sim", stream_process=True)``. Paced always: the child steps the physics against the
    wall clock whether or not targets arrive (a window without one holds the last target).

    Args:
        period: controller period, s (a multiple of the workcell's control period; default 8 ms).
        stall_periods: stop when a stream gives no target for this many periods (the watchdog here
            adds the look-ahead; the child counts windows without a target to play); None: no stall stop.
        recorder: optional recorder of states and commands.
        q0: (6,) start configuration, rad (default: the workcell's).
        workcell_kwargs: :class:`~robointel.sim.Workcell`'s keyword arguments, picklable (``robot`` a
            name, not a ``Robot``); the workcell is built in the child.
        lookahead_s: the child plays a target this long after it arrived, s: a stall of the
            streaming caller shorter than this costs no window; it is added latency.
        force_lookahead_s: the look-ahead inside :meth:`low_latency`, s (0: each target at once).
        workcell_factory: ``"module:function"`` building the workcell in the child from ``factory_args``
            instead of ``Workcell(**workcell_kwargs)`` (see :class:`SimStreamProcess`).
        factory_args: the factory's positional arguments (picklable).
        lock_memory: the child locks its memory (``mlockall``, when allowed; see :class:`SimStreamProcess`).

    Raises:
        InvalidInput: a bad period, look-ahead, robot or workcell argument.
        ConnectionLost: the streaming process did not come up.
    """

    clocked = True
    """The state advances at the streaming process's ticks."""

    def __init__(self, *, period: float = 0.008, stall_periods: int | None = 10, recorder: Recorder | None = None,
                 q0: npt.ArrayLike | None = None, workcell_kwargs: Mapping[str, Any] | None = None,
                 lookahead_s: float = DEFAULT_LOOKAHEAD_S, force_lookahead_s: float = 0.0,
                 workcell_factory: str | None = None, factory_args: tuple[Any, ...] = (),
                 lock_memory: bool = False) -> None:
        kw = dict(workcell_kwargs or {})
        name = kw.get("robot")
        if name is not None and not isinstance(name, str):
            raise InvalidInput("workcell_kwargs['robot'] must be a robot name (the workcell is built in the child)",
                               value=name)
        robot = Robot.load(name or "lrmate200id7l")
        if robot.nq != layout.NDOF:
            raise InvalidInput(f"the streaming process carries {layout.NDOF} joints, the robot has {robot.nq}",
                               value=robot.nq)
        super().__init__(robot.joint_names, robot.lower, robot.upper, robot.velocity_limit, period, paced=True,
                         stall_periods=stall_periods, recorder=recorder)
        check_lookahead(lookahead_s)
        check_lookahead(force_lookahead_s)
        timestep = kw.get("timestep", CONTROL_DT)  # the workcell's control period, as Workcell sets it
        if isinstance(timestep, float | int) and timestep > 0:
            substeps_of(self.period, max(float(timestep), CONTROL_DT))  # refused here, before a child starts
        self.stream_process = True
        self.lookahead_s, self.force_lookahead_s = float(lookahead_s), float(force_lookahead_s)
        self._stall_extra_s = self.lookahead_s  # a target is played lookahead_s after it arrived
        self._vals: tuple[float, ...] | None = None
        self._read_ns = 0
        self._stale_ms = 12 * self.period * 1e3
        self.driver = SimStreamProcess(kw, q0, period=self.period, lookahead_s=self.lookahead_s,
                                       stall_periods=stall_periods if stall_periods is not None else 10**9,
                                       workcell_factory=workcell_factory, factory_args=factory_args,
                                       lock_memory=lock_memory)

    @property
    def has_wrench(self) -> bool:
        """True when the workcell has its wrist F/T sensor."""
        return self.driver.has_ft

    # ------------------------------------------------------------------ backend hooks
    def _read(self) -> RobotState:
        d = self.driver
        v = d.head()
        self._vals, self._read_ns = v, time.monotonic_ns()
        n = self.n
        wrench = np.array(v[ss.WR:ss.WR + 6]) if v[ss.WRENCH_VALID] else None
        return self._make_state(d.t0 + v[_TICK] * self.period, np.array(v[ss.QM:ss.QM + n]),
                                np.array(v[ss.QD:ss.QD + n]), wrench, np.array(v[ss.QC:ss.QC + n]))

    def _fault_of(self, state: RobotState) -> tuple[RobotMode, str, tuple[str, ...]] | None:
        v, d = self._vals, self.driver
        if v is not None and ss.quiet(v, d.base_ns, self._read_ns, self._stale_ms) and d.alive():
            return None
        if not d.alive():
            return (RobotMode.DISCONNECTED, f"connection lost: the simulation process ended (exit status "
                    f"{d.returncode})", ("disconnected",))
        if v is None:
            return None
        if v[_FAULT] or v[_REFUSED]:
            return RobotMode.FAULTED, "the simulation diverged (the arm is back at rest)", ("sim_unstable",)
        if v[_STALLED]:
            gap = float(v[ss.STALL_GAP]) * 1e3
            return (RobotMode.STOPPED, f"command stream stalled: no target to play for {gap:.0f} ms "
                    f"(> {self.stall_periods} periods; the look-ahead is {self._stall_extra_s * 1e3:.0f} ms)",
                    ("stream_stalled",))
        return None  # an old state of a live child: late, not faulted

    def _needs_monitor(self) -> bool:
        return True

    def _send(self, q: npt.NDArray[np.float64]) -> None:
        try:
            self.driver.servo_j(q, self.period)
        except ConnectionLost as exc:
            self._latch_fault(RobotMode.DISCONNECTED, f"connection lost: {exc}", ("disconnected",))
            raise ConnectionLost(self._why, value=self._read(), reason=self._why) from exc

    def _hold(self) -> None:
        self.driver.hold()

    def _halt(self) -> None:
        self.driver.stop_j()  # never raises; the child brakes from its next window

    def _recover(self) -> None:
        try:
            self.driver.recover()
        except ConnectionLost as exc:
            raise ConnectionLost(f"recovery failed: {exc}", value=self._read(), reason=str(exc)) from exc

    def _close(self) -> None:
        self.driver.close()

    def _commanded(self) -> npt.NDArray[np.float64] | None:
        return self._read().q_cmd

    # ------------------------------------------------------------------ the interface
    def execute(self, trajectory: Trajectory, *, on_cycle: CycleCallback | None = None) -> ExecutionResult:
        """:meth:`Backend.execute <robointel.interface.backend.Backend.execute>`, then wait for the queue.

        The targets are streamed paced at the period and played ``lookahead_s`` later; this returns
        once the child has played the last one (or after the look-ahead plus
        :data:`SETTLE_TIMEOUT_S`). ``ExecutionResult.q`` holds the state read as each target was
        queued, so it lags the targets by the look-ahead.

        Raises:
            ControllerFault: as :meth:`Backend.execute <robointel.interface.backend.Backend.execute>`, or
                the child stopped while it played the queue (a divergence); ``.value`` = (state, result).
            ConnectionLost: as :meth:`Backend.execute <robointel.interface.backend.Backend.execute>`, or
                the child died while it played the queue; ``.value`` = (state, result).
        """
        res = super().execute(trajectory, on_cycle=on_cycle)
        deadline = time.monotonic() + self.lookahead_s + SETTLE_TIMEOUT_S
        while not self.driver.held() and time.monotonic() < deadline:
            with self._lock:
                fault = self._fault_of(self._read()) if self._mode is RobotMode.HOLDING else None
                if fault is not None:  # the child stopped while it played the queue
                    self._latch_fault(*fault)
                    cls = ConnectionLost if self._mode is RobotMode.DISCONNECTED else ControllerFault
                    raise cls(f"execution stopped: {self._why}", value=(self._read(), res), reason=self._why)
            time.sleep(self.period)
        return res

    @contextlib.contextmanager
    def low_latency(self, lookahead_s: float | None = None) -> Iterator[None]:
        """Stream the ``with`` block's targets with a force loop's look-ahead (default ``force_lookahead_s``).

        Raises:
            InvalidInput: ``lookahead_s`` outside [0, 1] s.
        """
        lookahead_s = self.force_lookahead_s if lookahead_s is None else lookahead_s
        check_lookahead(lookahead_s)
        with self._lookahead_section(lambda: self.driver, lookahead_s, self.lookahead_s):
            yield

    def idle(self, duration: float) -> RobotState:
        """Wait until the simulated time has run ``duration`` s further (the child holds the last target).

        Raises:
            InvalidInput: negative or non-finite duration. ConnectionLost: the child is gone.
        """
        if not (np.isfinite(duration) and duration >= 0):
            raise InvalidInput(f"duration must be a finite number of seconds >= 0, got {duration}", value=duration)
        end = self._read().t + duration
        while self._read().t < end - 1e-9:
            if not self.driver.alive():
                raise ConnectionLost("the simulation process ended", value=self._read(), reason="disconnected")
            time.sleep(min(self.period, max(0.0, end - self._read().t)))
        return self.state()

    def timing_stats(self) -> dict[str, Any]:
        """The streaming process's physics figures and window counters (:meth:`SimStreamProcess.timing_stats`)."""
        return self.driver.timing_stats()

