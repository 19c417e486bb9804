"""The ``sim`` backend: the MuJoCo workcell behind the robot interface.

Each streamed target is one controller period: the workcell's 1 kHz joint controller tracks the
straight line from the previous target to the new one (velocity feed-forward = the line's slope),
as a robot controller interpolates between Stream Motion targets. Time only advances while
targets arrive (or in :meth:`SimRobot.idle`); ``paced=True`` makes :meth:`execute` wait for wall
time between targets, ``paced=False`` runs as fast as it can. The paced simulation whose physics runs
in a process of its own, against wall time, is :class:`~robointel.interface.sim_stream.SimStreamRobot`
(``open_robot("sim", stream_process=True)``).
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robointel.errors import ControllerFault, InvalidInput, SafetyStop
from robointel.interface.backend import Backend, Recorder
from robointel.interface.state import RobotMode, RobotState
from robointel.sim.workcell import Workcell

BRAKE_S = 0.05
"""How long a stop holds the measured position to bring the simulated arm to rest, s."""


def substeps_of(period: float, control_dt: float) -> int:
    """The workcell's control periods per controller period.

    Raises:
        InvalidInput: ``period`` is not a positive multiple of ``control_dt``.
    """
    ratio = period / control_dt
    if not (period > 0 and abs(ratio - round(ratio)) < 1e-6 and round(ratio) >= 1):
        raise InvalidInput(f"period {period} s must be a multiple of the workcell's control period "
                           f"{control_dt} s", value=period)
    return int(round(ratio))


def step_window(wc: Workcell, prev: npt.NDArray[np.float64], q: npt.NDArray[np.float64], period: float,
                substeps: int) -> None:
    """One controller window: track the straight line from target ``prev`` to ``q`` (n,) rad.

    The velocity feed-forward is the line's slope, as a robot controller interpolates between Stream
    Motion targets; ``prev == q`` holds.

    Raises:
        SafetyStop: the simulation diverged (the workcell is back at rest where it last was).
    """
    slope = (q - prev) / period
    for i in range(1, substeps + 1):
        wc.track(prev + (q - prev) * (i / substeps), slope)


class SimRobot(Backend):
    """A :class:`~robointel.interface.protocol.RobotInterface` on a :class:`~robointel.sim.Workcell`.

    Args:
        workcell: the workcell (default: the LR Mate on its table with an F/T sensor).
        period: controller period, s (a multiple of the workcell's control period; default 8 ms).
        paced: execute in wall-clock time; False steps as fast as possible.
        stall_periods: stop when a stream gives no target for this many periods of wall time
            (None, the default for the unpaced simulation, disables it).
        recorder: optional recorder of states and commands.
        q0: (n,) start configuration, rad (default: the workcell's current one).

    Raises:
        InvalidInput: ``period`` is not a positive multiple of the workcell's control period.
    """

    def __init__(self, workcell: Workcell | None = None, *, period: float = 0.008, paced: bool = False,
                 stall_periods: int | None = None, recorder: Recorder | None = None,
                 q0: npt.ArrayLike | None = None) -> None:
        self.workcell = workcell if workcell is not None else Workcell()
        wc = self.workcell
        self.substeps = substeps_of(period, wc.control_dt)
        robot = wc.robot
        super().__init__(robot.joint_names, robot.lower, robot.upper, robot.velocity_limit, period, paced=paced,
                         stall_periods=stall_periods, recorder=recorder)
        if q0 is not None:
            wc.reset(q0)
        self._target = wc.hold_reference
        self._has_ft = getattr(wc, "_has_ft", False)

    @property
    def has_wrench(self) -> bool:
        """True when the workcell has its wrist F/T sensor."""
        return bool(self._has_ft)

    # ------------------------------------------------------------------ backend hooks
    def _send(self, q: npt.NDArray[np.float64]) -> None:
        try:
            step_window(self.workcell, self._target, q, self.period, self.substeps)
        except SafetyStop as exc:
            self._latch_fault(RobotMode.FAULTED, str(exc), ("sim_unstable",))
            raise ControllerFault(str(exc), value=self._read(), reason=str(exc)) from None
        self._target = q

    def _read(self) -> RobotState:
        wc = self.workcell
        wrench = wc.ft_reading() if self._has_ft else None
        return self._make_state(wc.time, wc.q, wc.qd, wrench, self._target.copy())

    def _hold(self) -> None:
        pass  # the workcell's controller holds the last reference whenever it is stepped

    def _halt(self) -> None:
        wc = self.workcell
        q = wc.q
        wc.track(q)
        wc.hold(BRAKE_S)
        self._target = q

    def _recover(self) -> None:
        self._target = self.workcell.hold_reference

    def _close(self) -> None:
        pass

    def _commanded(self) -> npt.NDArray[np.float64] | None:
        return self._target.copy()

    # ------------------------------------------------------------------ simulation only
    def idle(self, duration: float) -> RobotState:
        """Let simulated time run ``duration`` s holding the last target (no command is sent).

        Raises:
            InvalidInput: negative or non-finite duration.
        """
        if not (np.isfinite(duration) and duration >= 0):
            raise InvalidInput(f"duration must be a finite number of seconds >= 0, got {duration}", value=duration)
        with self._lock:
            if duration > 0:
                self.workcell.hold(duration)
            return self._read()
