"""Compliance control for lead-through teaching (Ch. 3.3, eqs. (3.10)-(3.13)).

The operator pushes a handle mounted on the F/T sensor; the measured (compensated) wrench F_E is
turned into a Cartesian velocity command of the tool by a damping law (3.10)-(3.11)

    V_r = C F_E,   C = diag(K_d I_3, K_r I_3)

(the dissertation's K_d = 0.07 m/(N s) for translation; K_r is its rotational counterpart), and
into a joint velocity reference by the inverse of the tool Jacobian (3.12)-(3.13)

    dq_r = J^+(q) V_r,

with a singularity-robust (damped) pseudo-inverse so that the command stays bounded near
singular configurations.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from robointel._validate import as_array
from robointel.errors import InvalidInput

if TYPE_CHECKING:  # pragma: no cover
    from robointel.robot import Robot

__all__ = ["ComplianceGains", "compliance_twist", "compliance_velocity", "damped_pinv", "shift_wrench",
           "wrench_to_world"]


@dataclass(frozen=True)
class ComplianceGains:
    """Damping gains of the compliance law (3.11).

    Attributes:
        translational: K_d, m/(N s): tool speed per newton (dissertation: 0.07).
        rotational: K_r, rad/(N m s): tool angular speed per newton metre.
        force_deadband: forces below this norm (N) are ignored (sensor noise, hand tremor).
        torque_deadband: torques below this norm (N m) are ignored.
    """

    translational: float = 0.07
    rotational: float = 0.5
    force_deadband: float = 1.0
    torque_deadband: float = 0.1

    def __post_init__(self) -> None:
        for name in ("translational", "rotational", "force_deadband", "torque_deadband"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise InvalidInput(f"ComplianceGains.{name} must be finite and >= 0, got {v!r}", value=v)

    @property
    def matrix(self) -> np.ndarray:
        """C = diag(K_d I_3, K_r I_3), 6x6 (3.11)."""
        return np.diag([self.translational] * 3 + [self.rotational] * 3)


def shift_wrench(wrench: ArrayLike, r: ArrayLike) -> np.ndarray:
    """Move a wrench [f.

    Tau] (6,) to a point displaced by ``r`` (3,) metres from its reference point (same axes): tau' = tau - r x f.
    """
    w = as_array(wrench, "wrench", (6,))
    r = as_array(r, "r", (3,))
    out = w.copy()
    out[3:] -= np.cross(r, w[:3])
    return out


def wrench_to_world(wrench_sensor: ArrayLike, R_world_sensor: ArrayLike) -> np.ndarray:
    """Rotate a wrench [f; tau] (6,) from sensor axes to world axes with R (3x3) = world<-sensor."""
    w = as_array(wrench_sensor, "wrench_sensor", (6,))
    R = as_array(R_world_sensor, "R_world_sensor", (3, 3))
    return np.concatenate([R @ w[:3], R @ w[3:]])


def _deadband(v: np.ndarray, band: float) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if n <= band or n == 0.0:
        return np.zeros_like(v)
    return v * ((n - band) / n)  # continuous: shrink by the band


def compliance_twist(wrench_world: ArrayLike, gains: ComplianceGains = ComplianceGains()) -> np.ndarray:
    """Tool twist V_r = C F_E (3.10)-(3.11) from a wrench in world axes at the tool point.

    Args:
        wrench_world: [f (N); tau (N m)], (6,), world axes, torque about the tool point.
        gains: the damping gains; forces/torques inside the deadbands give zero.

    Returns:
        V_r = [v (m/s); w (rad/s)], (6,).
    """
    w = as_array(wrench_world, "wrench_world", (6,))
    f = _deadband(w[:3], gains.force_deadband)
    t = _deadband(w[3:], gains.torque_deadband)
    return np.concatenate([gains.translational * f, gains.rotational * t])


def damped_pinv(J: ArrayLike, *, epsilon: float = 0.04, max_damping: float = 0.04) -> np.ndarray:
    """Singularity-robust pseudo-inverse J^# = J^T (J J^T + lambda^2 I)^-1 (used in (3.12)).

    The damping grows only near a singularity (Maciejewski-Klein / Chiaverini): with sigma_min the
    smallest singular value, lambda^2 = max_damping^2 (1 - (sigma_min/epsilon)^2) when
    sigma_min < epsilon, else 0. Then ||J^# V|| <= ||V|| / (2 lambda) stays bounded.

    Args:
        J: (m, n) Jacobian.
        epsilon: size of the singular region (same units as the singular values).
        max_damping: lambda at the singularity.

    Returns:
        (n, m) matrix.
    """
    J = as_array(J, "J", (None, None))
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    smin = s[-1] if s.size else 0.0
    lam2 = max_damping ** 2 * (1.0 - (smin / epsilon) ** 2) if smin < epsilon else 0.0
    inv = s / (s ** 2 + lam2) if lam2 > 0 else np.where(s > 1e-12, 1.0 / np.where(s > 1e-12, s, 1.0), 0.0)
    return (Vt.T * inv) @ U.T


def compliance_velocity(robot: Robot, q: ArrayLike, wrench_world: ArrayLike, gains: ComplianceGains = ComplianceGains(),
                        *, epsilon: float = 0.04, max_damping: float = 0.04) -> np.ndarray:
    """Joint velocity reference dq_r = J^#(q) C F_E (3.12)-(3.13) for a wrench at the robot's TCP.

    Args:
        robot: a :class:`robointel.robot.Robot` (its TCP is the handle point).
        q: (n,) joint angles, rad.
        wrench_world: (6,) [f; tau] in world axes about the TCP, N and N m.
        gains: the compliance gains C of (3.12).
        epsilon: singular-value threshold of the damped pseudo-inverse J^#.
        max_damping: largest damping of the pseudo-inverse near a singularity.

    Returns:
        (n,) joint velocities, rad/s.
    """
    q = robot.check_q(q)
    V = compliance_twist(wrench_world, gains)
    return damped_pinv(robot.jacobian(q), epsilon=epsilon, max_damping=max_damping) @ V
