"""The one robot interface every capability talks to (sim or a real FANUC controller)."""
from __future__ import annotations

from collections.abc import Callable
from types import TracebackType
from typing import Protocol, runtime_checkable

import numpy.typing as npt

from robointel.interface.state import RobotState
from robointel.trajectory import Trajectory

CycleCallback = Callable[[int, RobotState], None]
"""Called after every streamed target of :meth:`RobotInterface.execute` with (cycle index, state)."""


@runtime_checkable
class RobotInterface(Protocol):
    """A position-controlled robot streamed one joint target per controller period.

    Every command goes through the shared :class:`~robointel.interface.gate.SafetyGate` before it
    reaches the backend; a refused command raises :class:`~robointel.errors.UnsafeCommand` and the
    robot holds. A fault on the robot's side raises :class:`~robointel.errors.ControllerFault`
    (:class:`~robointel.errors.ConnectionLost` for a lost link) from the next call, with the last
    known state on ``.value``; nothing is retried into motion.
    """

    joint_names: list[str]

    @property
    def period(self) -> float:
        """The controller period, s (one :meth:`stream` target per period)."""
        ...

    def state(self) -> RobotState:
        """The latest state of the robot (never raises)."""
        ...

    def stream(self, q_target: npt.ArrayLike) -> RobotState:
        """Send one joint position target (n,) rad for the next controller period; return the state.

        Raises:
            UnsafeCommand: the target is outside the limits, not finite, or too far from the last one.
            ControllerFault: the robot is stopped or faulted (``.reason`` says why).
        """
        ...

    def execute(self, trajectory: Trajectory, *, on_cycle: CycleCallback | None = None) -> object:
        """Stream a whole trajectory at the controller period (resampled), then hold."""
        ...

    def hold(self) -> None:
        """Hold the last commanded position (ends a stream without a stall stop)."""
        ...

    def stop(self, reason: str) -> None:
        """Stop at once and refuse further targets until :meth:`recover`; ``reason`` goes into the state."""
        ...

    def recover(self) -> None:
        """Clear a stop or a controller fault whose cause is gone; the robot holds where it is."""
        ...

    def close(self) -> None:
        """Stop commanding and release the robot (idempotent)."""
        ...

    def __enter__(self) -> RobotInterface: ...

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None: ...
