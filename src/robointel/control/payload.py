"""F/T payload compensation (3.14)-(3.15), (3.20): remove a tool's weight and the sensor's biases.

A payload of mass m with its centre of mass at r (sensor frame) puts f_P = m R^T g and
tau_P = r x f_P on the sensor (R = world <- sensor); the biases f_B, tau_B add to every reading.
The external wrench is the reading minus both.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput

GRAVITY = np.array([0.0, 0.0, -9.81])
"""World gravity, m/s^2."""


@dataclass(frozen=True)
class PayloadCompensation:
    """A payload and sensor biases to remove from F/T readings.

    Attributes:
        mass: payload mass, kg (>= 0).
        com: (3,) payload centre of mass in the sensor frame, m.
        force_bias: (3,) sensor force bias, N.
        torque_bias: (3,) sensor torque bias, N m.
        gravity: (3,) world gravity, m/s^2.
    """

    mass: float
    com: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    force_bias: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    torque_bias: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    gravity: npt.NDArray[np.float64] = field(default_factory=lambda: GRAVITY.copy())

    def __post_init__(self) -> None:
        if not (np.isfinite(self.mass) and self.mass >= 0):
            raise InvalidInput(f"payload mass must be finite and >= 0 kg, got {self.mass}", value=self.mass)
        for name in ("com", "force_bias", "torque_bias", "gravity"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise InvalidInput(f"{name} must be 3 finite numbers, got {v}", value=v)
            object.__setattr__(self, name, v)

    def payload_wrench(self, R_world_sensor: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """The wrench payload and biases put on the sensor, (3.14)-(3.15).

        Args:
            R_world_sensor: (3, 3) or (N, 3, 3) sensor orientation(s), world <- sensor.

        Returns:
            (6,) or (N, 6) [f (N); tau (N m)] in the sensor frame.
        """
        R = np.asarray(R_world_sensor, dtype=float)
        g_s = np.einsum("...ji,j->...i", R, self.gravity) * self.mass
        return np.concatenate([g_s + self.force_bias, np.cross(self.com, g_s) + self.torque_bias], -1)

    def compensate(self, wrench: npt.ArrayLike, R_world_sensor: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """The external wrench (3.20): reading minus payload weight and biases, sensor frame.

        Args:
            wrench: (6,) or (N, 6) raw reading(s) [f (N); tau (N m)].
            R_world_sensor: (3, 3) or (N, 3, 3) matching orientation(s).

        Returns:
            Same shape as ``wrench``.

        Raises:
            InvalidInput: shapes do not match or values are not finite.
        """
        w = np.asarray(wrench, dtype=float)
        R = np.asarray(R_world_sensor, dtype=float)
        if w.shape[-1:] != (6,) or R.shape[-2:] != (3, 3) or w.shape[:-1] != R.shape[:-2]:
            raise InvalidInput(f"wrench (..., 6) and R (..., 3, 3) must match, got {w.shape} and {R.shape}",
                               value=w)
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(R))):
            raise InvalidInput("wrench and orientation must be finite", value=w)
        return w - self.payload_wrench(R)
