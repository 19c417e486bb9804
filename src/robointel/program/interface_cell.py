"""A program cell on the robot interface: the program's motions streamed to ``sim`` or a FANUC controller.

Every ``move`` and ``path`` trajectory the pre-run check planned goes to
:meth:`robointel.interface.backend.Backend.execute` (resampled at the controller period, checked by the
interface's safety gate before the first target goes out). ``wait`` holds; ``set_io`` outputs are kept
on the cell. Steps that need the simulated cell's gripper, objects, F/T lead-through or skill stations
(``grasp``, ``place``, ``guide``, ``insert``, ``grind``) are refused before anything moves
(:func:`interface_refusal`).
"""

from __future__ import annotations

import time

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput, SafetyStop
from robointel.interface.backend import Backend
from robointel.outcome import Failure, TrialOutcome
from robointel.program.format import Program
from robointel.trajectory import Trajectory

#: the step kinds a program runs on a robot interface
INTERFACE_KINDS = ("move", "path", "wait", "set_io")


def interface_refusal(program: Program, start: int = 0) -> None:
    """Refuse a program with steps a robot interface cannot run (nothing has moved yet).

    Args:
        program: The program.
        start: First step to run.

    Raises:
        InvalidInput: Names the first such step.
    """
    for i, s in enumerate(program.steps[start:], start):
        if s.kind not in INTERFACE_KINDS:
            raise InvalidInput(f"step {i} ({s.name!r}, {s.kind}): runs only on the simulated cell (--robot sim); on a "
                               f"robot interface a program runs {', '.join(INTERFACE_KINDS)}", value=s.kind)


class InterfaceCell:
    """The :class:`robointel.program.Cell` of a robot interface.

    Args:
        arm: The open robot interface (``open_robot("sim" | "fanuc://HOST")``).
    """

    def __init__(self, arm: Backend) -> None:
        self.arm = arm
        self.io: dict[str, float] = {}
        self.stopped: str | None = None

    @property
    def q(self) -> npt.NDArray[np.float64]:
        """(n,) measured joint configuration, rad."""
        return np.asarray(self.arm.state().q, float).copy()

    def execute(self, trajectory: Trajectory) -> tuple[TrialOutcome, npt.NDArray[np.float64]]:
        """Stream ``trajectory`` to the robot; a gate refusal or a controller fault fails the step (robot stopped).

        Returns:
            The outcome (FAULT with the interface's reason on a stop) and the measured joints (K, n).
        """
        try:
            res = self.arm.execute(trajectory)
        except SafetyStop as exc:
            self.stopped = str(exc)
            return TrialOutcome(False, Failure.FAULT, f"the robot interface stopped: {exc}"), np.zeros((0, self.arm.n))
        figures = {"tracking_rms_rad": res.tracking_rms_rad, "missed_cycles": float(res.missed_cycles),
                   "cycles": float(len(res.t))}
        return TrialOutcome(True, figures=figures), res.q

    def hold(self, seconds: float) -> None:
        """Hold the last target for ``seconds`` (simulated time on an unpaced ``sim``, wall time otherwise)."""
        self.arm.hold()
        if seconds <= 0:
            return
        idle = getattr(self.arm, "idle", None)
        if idle is not None and not self.arm.paced:
            idle(seconds)
        else:
            time.sleep(seconds)

    def stop(self, reason: str) -> None:
        """Stop the robot (the interface refuses targets until it is recovered)."""
        self.stopped = reason
        self.arm.stop(reason)

    def set_io(self, name: str, value: float) -> None:
        """Keep an output value (digital outputs are not wired to the controller by this cell)."""
        self.io[name] = float(value)
