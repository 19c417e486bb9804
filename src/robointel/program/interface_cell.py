"""A program cell on the robot interface: the program's motions streamed to ``sim`` or a FANUC controller.

Every ``move`` and ``path`` trajectory the pre-run check planned goes to
:meth:`robointel.interface.backend.Backend.execute` (resampled at the controller period, checked by the
interface's safety gate before the first target goes out). ``wait`` holds. ``set_io`` on a FANUC
controller writes numeric registers ``R[n]`` over RMI (``FRC_WriteRegister``): airo-fanuc's RMI client
has no digital-output command and its Stream Motion packets keep the I/O block empty, so an output named
otherwise (``DO[n]``, ``gripper``) is refused before anything moves (:func:`output_refusal`); on ``sim``
the outputs are kept on the cell. Steps that need the simulated cell's gripper, objects, F/T
lead-through or skill stations (``grasp``, ``place``, ``guide``, ``insert``, ``grind``) are refused
before anything moves (:func:`interface_refusal`).
"""

from __future__ import annotations

import re
import time

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput, SafetyStop
from robointel.interface.backend import Backend
from robointel.outcome import Failure, TrialOutcome
from robointel.program.check import ProgramRejected
from robointel.program.format import Program
from robointel.trajectory import Trajectory

#: the step kinds a program runs on a robot interface
INTERFACE_KINDS = ("move", "path", "wait", "set_io")
#: a FANUC numeric register as a ``set_io`` output name
REGISTER = re.compile(r"R\[(\d+)\]")
#: a motion ends in position (FANUC's FINE termination) when every joint is this close to its goal, rad
IN_POSITION_RAD = 0.005
#: the longest a motion waits for the arm to come into position before the next step checks it, s
SETTLE_TIMEOUT_S = 2.0


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


def register_of(name: str) -> int | None:
    """The register number of an output named ``R[n]``, else None."""
    m = REGISTER.fullmatch(name.strip())
    return int(m.group(1)) if m else None


def output_refusal(program: Program, arm: Backend, start: int = 0) -> None:
    """Refuse ``set_io`` outputs the robot interface cannot write (nothing has moved yet).

    A backend with numeric registers (``write_register``: the FANUC backend) writes outputs named
    ``R[n]`` (n >= 1, not a register of its gripper dispatcher); other backends (``sim``) keep any output.

    Args:
        program: The program.
        arm: The open robot interface.
        start: First step to run.

    Raises:
        ProgramRejected: Names the step and the output (``.value``: step index, name, output).
    """
    if not callable(getattr(arm, "write_register", None)):
        return
    reserved: tuple[int, ...] = tuple(getattr(arm, "gripper_registers", ()))
    for i, s in enumerate(program.steps[start:], start):
        if s.kind != "set_io":
            continue
        for name in s.args["outputs"]:
            n = register_of(name)
            where = {"step": i, "name": s.name, "output": name}
            if n is None:
                raise ProgramRejected(
                    f"step {i} ({s.name!r}, set_io): output {name!r}: on a FANUC controller set_io writes numeric "
                    "registers R[n] over RMI; digital outputs cannot be written (airo-fanuc's RMI client has no "
                    "digital-output command and its Stream Motion packets keep the I/O block empty): write a "
                    "register and drive the output from it on the controller (background logic DO[n]=(R[m]=1))",
                    value=where)
            if n < 1:
                raise ProgramRejected(f"step {i} ({s.name!r}, set_io): output {name!r}: register numbers start at 1",
                                      value=where)
            if n in reserved:
                raise ProgramRejected(f"step {i} ({s.name!r}, set_io): output {name!r}: R[{reserved[0]}]-"
                                      f"R[{reserved[-1]}] belong to the gripper dispatcher while the gripper is up",
                                      value=where)


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
                   "cycles": float(len(res.t)), "settle_s": self._settle(trajectory.q[-1])}
        return TrialOutcome(True, figures=figures), res.q

    def _settle(self, goal: npt.NDArray[np.float64]) -> float:
        """Hold until every joint is within ``IN_POSITION_RAD`` of ``goal`` or ``SETTLE_TIMEOUT_S`` passed.

        A position-controlled arm lags its commands (the FANUC servo's first-order lag is ~0.125 s), so a
        motion's last target is reached some time after it was sent; the next step starts from where the
        arm is (its start check is the runner's). Returns the time waited, s (simulated time on an unpaced
        ``sim``).
        """
        dt, t0, waited = float(self.arm.period), time.perf_counter(), 0.0
        idle = getattr(self.arm, "idle", None) if not self.arm.paced else None
        while float(np.max(np.abs(self.q - goal))) > IN_POSITION_RAD and waited < SETTLE_TIMEOUT_S:
            if idle is not None:
                idle(dt)
                waited += dt
            else:
                time.sleep(dt)
                waited = time.perf_counter() - t0
        return waited

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

    def refuse(self, program: Program, start: int = 0) -> None:
        """The interface's part of the pre-run check: step kinds and outputs.

        See :func:`interface_refusal` and :func:`output_refusal`.

        Raises:
            InvalidInput: A step the interface cannot run. ProgramRejected: An output it cannot write.
        """
        interface_refusal(program, start)
        output_refusal(program, self.arm, start)

    def set_io(self, name: str, value: float) -> None:
        """Set an output: a numeric register ``R[n]`` on a controller with registers, else kept on the cell.

        Raises:
            InvalidInput: An output the controller cannot write (refused by :meth:`refuse` before the run).
            ControllerFault: The controller refused the write (ConnectionLost: its RMI session is down).
        """
        write = getattr(self.arm, "write_register", None)
        if callable(write):
            n = register_of(name)
            if n is None:
                raise InvalidInput(f"output {name!r}: a FANUC controller's set_io outputs are registers R[n]",
                                   value=name)
            write(n, float(value))
        self.io[name] = float(value)
