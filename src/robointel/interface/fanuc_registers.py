"""Numeric registers of a FANUC controller over RMI (``FRC_WriteRegister`` / ``FRC_ReadRegister``)."""
from __future__ import annotations

from typing import Any

import numpy as np
from airo_fanuc.exceptions import RmiError, RmiSessionDown
from airo_fanuc.gripper import REG_CMD, REG_R3

from robointel.errors import ConnectionLost, ControllerFault, InvalidInput

GRIPPER_REGISTERS = tuple(range(REG_CMD, REG_R3 + 1))
"""The numeric registers the gripper dispatcher (GRIPDISP) reads and clears: R[1]-R[3]."""


class RegisterIO:
    """Register reads and writes of :class:`~robointel.interface.fanuc.FanucRobot` (its RMI session).

    Attributes:
        driver: the driver (or streaming process) whose ``rmi`` is the RMI session.
        policy: the driver policy (``enable_gripper``).
    """

    driver: Any
    policy: Any
    _closed: bool

    @property
    def gripper_registers(self) -> tuple[int, ...]:
        """Numeric registers the gripper dispatcher owns while the gripper is up (empty otherwise)."""
        return GRIPPER_REGISTERS if self.policy.enable_gripper else ()

    def write_register(self, number: int, value: float) -> None:
        """Write the numeric register R[number] over RMI (``FRC_WriteRegister``).

        An integral value is written as an integer register value, anything else as a real. A TP or
        background-logic program on the controller turns it into an output (e.g. ``DO[1]=(R[10]=1)``).

        Args:
            number: register number (>= 1; not one of :attr:`gripper_registers`).
            value: the value (finite).

        Raises:
            InvalidInput: bad number or value. ConnectionLost: the RMI session is down.
            ControllerFault: the controller refused the write.
        """
        n = _register_number(number, self.gripper_registers)
        v = float(value)
        if not np.isfinite(v):
            raise InvalidInput(f"register R[{n}] needs a finite value, got {value!r}", value=value)
        rmi = self._rmi()
        try:
            rmi.write_register(n, int(v) if v.is_integer() else v)
        except RmiSessionDown as exc:
            raise ConnectionLost(f"writing R[{n}]: the RMI session is down: {exc}", reason=str(exc)) from exc
        except RmiError as exc:
            raise ControllerFault(f"the controller refused writing R[{n}]: {exc}", value=v, reason=str(exc)) from exc

    def read_register(self, number: int) -> float:
        """Read the numeric register R[number] over RMI (``FRC_ReadRegister``).

        Raises:
            InvalidInput: bad number. ConnectionLost: the RMI session is down.
            ControllerFault: the controller refused the read.
        """
        n = _register_number(number, ())
        rmi = self._rmi()
        try:
            return float(rmi.read_register(n))
        except RmiSessionDown as exc:
            raise ConnectionLost(f"reading R[{n}]: the RMI session is down: {exc}", reason=str(exc)) from exc
        except RmiError as exc:
            raise ControllerFault(f"the controller refused reading R[{n}]: {exc}", reason=str(exc)) from exc

    def _rmi(self) -> Any:
        if self._closed or self.driver.rmi is None:
            raise ConnectionLost("the robot interface is closed (no RMI session)", reason="closed")
        return self.driver.rmi


def _register_number(number: int, reserved: tuple[int, ...]) -> int:
    """A numeric register number (>= 1, not reserved), or InvalidInput."""
    if isinstance(number, bool) or not isinstance(number, (int, np.integer)) or number < 1:
        raise InvalidInput(f"a numeric register number is an integer >= 1, got {number!r}", value=number)
    if int(number) in reserved:
        raise InvalidInput(f"R[{number}] belongs to the gripper dispatcher (R[{reserved[0]}]-R[{reserved[-1]}]) "
                           "while the gripper is up", value=number)
    return int(number)
