"""Insertion policies that are not learned: the baselines the learned skill is measured against."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt


@dataclass(frozen=True)
class ConstantPush:
    """The compliant controller without a skill: a constant axial speed, the equilibrium left where it is.

    Attributes:
        speed: Axial speed of the force-limited damper (m/s).
    """

    speed: float = 0.008

    def __call__(self, wrench: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Tool twist [0, 0, speed, 0, 0] whatever the wrench (6,)."""
        return np.array([0.0, 0.0, self.speed, 0.0, 0.0])


@dataclass(frozen=True)
class HandTunedAdmittance:
    """A hand-tuned linear admittance: the corrective twist is proportional to the felt wrench.

    With the torque about the compliance centre tau_c = tau - c z x f (the sensor's torque moved ``centre``
    metres down the tool axis), all in the tool frame::

        twist = [k_f fx, k_f fy, speed * clip(1 - |fz| / f_slow, 0, 1), k_t tau_c,x, k_t tau_c,y]

    the equilibrium yields to lateral forces and turns with the torque about the centre (the rotation that
    relieves it), and the push slows as the axial force grows.

    Attributes:
        k_force: Lateral admittance (m/s per N).
        k_torque: Rotational admittance (rad/s per N m) about the compliance centre.
        speed: Free axial speed (m/s).
        f_slow: Axial force (N) at which the push stops.
        centre: Distance (m) from the F/T sensor to the compliance centre along the tool axis.
    """

    k_force: float = 1e-3
    k_torque: float = 0.1
    speed: float = 0.008
    f_slow: float = 10.0
    centre: float = 0.0

    def __call__(self, wrench: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Tool twist (5,) [m/s, rad/s] for the felt wrench (6,) [N, N m] in the tool frame."""
        w = np.asarray(wrench, float)
        slow = float(np.clip(1.0 - abs(w[2]) / self.f_slow, 0.0, 1.0))
        tx, ty = w[3] + self.centre * w[1], w[4] - self.centre * w[0]
        return np.array([self.k_force * w[0], self.k_force * w[1], self.speed * slow,
                         self.k_torque * tx, self.k_torque * ty])
