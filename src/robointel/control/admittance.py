"""Cartesian admittance on a position-controlled arm (3.10)-(3.13): wrench -> twist -> joint position.

The measured (compensated) wrench F_E at the tool becomes a tool twist by a damping law

    V_r = C F_E,   C = diag(K_d I_3, K_r I_3)                       (3.10)-(3.11)

(forces inside a deadband give zero), the twist a joint velocity by a singularity-robust
pseudo-inverse of the tool Jacobian, dq_r = J^#(q) V_r (3.12)-(3.13), and the joint velocity the
next joint *position* command q_{k+1} = q_k + dq_r dt, scaled down to the joint speed limits and
clipped to the position limits: what an industrial controller streamed at its period accepts.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel._validate import as_array
from robointel.errors import InvalidInput

Vector = npt.NDArray[np.float64]


@dataclass(frozen=True)
class AdmittanceGains:
    """Damping gains of (3.11) and the deadbands.

    Attributes:
        translational: K_d, m/(N s): tool speed per newton (dissertation: 0.07).
        rotational: K_r, rad/(N m s): tool angular speed per newton metre.
        force_deadband: forces below this norm (N) are ignored.
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
                raise InvalidInput(f"AdmittanceGains.{name} must be finite and >= 0, got {v!r}", value=v)

    @property
    def matrix(self) -> Vector:
        """C = diag(K_d I_3, K_r I_3), (6, 6) (3.11)."""
        return np.diag([self.translational] * 3 + [self.rotational] * 3)


def shift_wrench(wrench: npt.ArrayLike, r: npt.ArrayLike) -> Vector:
    """Move a wrench [f; tau] (6,) to a point displaced by ``r`` (3,) m (same axes): tau' = tau - r x f."""
    w = as_array(wrench, "wrench", (6,)).copy()
    w[3:] -= np.cross(as_array(r, "r", (3,)), w[:3])
    return w


def wrench_to_world(wrench_sensor: npt.ArrayLike, R_world_sensor: npt.ArrayLike) -> Vector:
    """Rotate a wrench [f; tau] (6,) from sensor axes to world axes; R (3, 3) is world <- sensor."""
    w = as_array(wrench_sensor, "wrench_sensor", (6,))
    R = as_array(R_world_sensor, "R_world_sensor", (3, 3))
    return np.concatenate([R @ w[:3], R @ w[3:]])


def _deadband(v: Vector, band: float) -> Vector:
    n = float(np.linalg.norm(v))
    return np.zeros_like(v) if n <= band or n == 0.0 else v * ((n - band) / n)


def admittance_twist(wrench_world: npt.ArrayLike, gains: AdmittanceGains = AdmittanceGains()) -> Vector:
    """Tool twist V_r = C F_E (3.10)-(3.11).

    Args:
        wrench_world: (6,) [f (N); tau (N m)], world axes, torque about the tool point.
        gains: damping gains and deadbands.

    Returns:
        (6,) [v (m/s); w (rad/s)].
    """
    w = as_array(wrench_world, "wrench_world", (6,))
    return np.concatenate([gains.translational * _deadband(w[:3], gains.force_deadband),
                           gains.rotational * _deadband(w[3:], gains.torque_deadband)])


def damped_pinv(J: npt.ArrayLike, *, epsilon: float = 0.04, max_damping: float = 0.04) -> Vector:
    """Singularity-robust pseudo-inverse J^# = J^T (J J^T + lambda^2 I)^-1 (used in (3.12)).

    lambda^2 = max_damping^2 (1 - (sigma_min / epsilon)^2) inside the singular region
    sigma_min < epsilon, else 0 (Maciejewski-Klein / Chiaverini).

    Args:
        J: (m, n) Jacobian.
        epsilon: size of the singular region (units of the singular values).
        max_damping: lambda at the singularity.

    Returns:
        (n, m) matrix.
    """
    J = as_array(J, "J", (None, None))
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    smin = s[-1] if s.size else 0.0
    lam2 = max_damping ** 2 * (1.0 - (smin / epsilon) ** 2) if smin < epsilon else 0.0
    inv = s / (s ** 2 + lam2) if lam2 > 0 else np.where(s > 1e-12, 1.0 / np.where(s > 1e-12, s, 1.0), 0.0)
    return np.asarray((Vt.T * inv) @ U.T)


def admittance_velocity(robot: Any, q: npt.ArrayLike, wrench_world: npt.ArrayLike,
                        gains: AdmittanceGains = AdmittanceGains(), *, epsilon: float = 0.04,
                        max_damping: float = 0.04) -> Vector:
    """Joint velocity reference dq_r = J^#(q) C F_E (3.12)-(3.13) for a wrench at the robot's TCP (unscaled).

    Args:
        robot: a :class:`robointel.robot.Robot` (its TCP is the handle point).
        q: (n,) joint angles, rad.
        wrench_world: (6,) [f; tau] in world axes about the TCP, N and N m.
        gains: the damping gains C of (3.11).
        epsilon: singular-value threshold of the damped pseudo-inverse J^#.
        max_damping: largest damping of the pseudo-inverse near a singularity.

    Returns:
        (n,) joint velocities, rad/s (not scaled to the speed limits: see :class:`AdmittanceController`).

    Raises:
        ShapeError, NotFinite, LimitViolation: bad ``q`` or wrench.
    """
    q = robot.check_q(q)
    V = admittance_twist(wrench_world, gains)
    return np.asarray(damped_pinv(robot.jacobian(q), epsilon=epsilon, max_damping=max_damping) @ V)


class AdmittanceController:
    """Wrench at the TCP -> next joint position command, one controller period per call.

    Args:
        robot: a :class:`robointel.robot.Robot` (Jacobian at its TCP, limits).
        period: controller period, s.
        gains: :class:`AdmittanceGains`.
        epsilon: of :func:`damped_pinv`.
        max_damping: of :func:`damped_pinv`.

    Raises:
        InvalidInput: non-positive period.
    """

    def __init__(self, robot: Any, period: float, gains: AdmittanceGains = AdmittanceGains(), *,
                 epsilon: float = 0.04, max_damping: float = 0.04) -> None:
        if not (np.isfinite(period) and period > 0):
            raise InvalidInput(f"period must be > 0 s, got {period}", value=period)
        self.robot, self.period, self.gains = robot, float(period), gains
        self.epsilon, self.max_damping = epsilon, max_damping

    def velocity(self, q: npt.ArrayLike, wrench_world: npt.ArrayLike) -> Vector:
        """Joint velocity dq_r = J^#(q) C F_E (3.12)-(3.13), (n,) rad/s, scaled into the speed limits."""
        qd = admittance_velocity(self.robot, q, wrench_world, self.gains, epsilon=self.epsilon,
                                 max_damping=self.max_damping)
        ratio = float(np.max(np.abs(qd) / self.robot.velocity_limit))
        return np.asarray(qd / ratio if ratio > 1.0 else qd)

    def step(self, q_cmd: npt.ArrayLike, wrench_world: npt.ArrayLike) -> Vector:
        """The next joint position command q_cmd + dq_r dt, clipped to the limits, (n,) rad.

        Args:
            q_cmd: (n,) current joint position command, rad.
            wrench_world: (6,) compensated wrench at the TCP, world axes, N and N m.
        """
        q = self.robot.check_q(q_cmd)
        return np.asarray(np.clip(q + self.period * self.velocity(q, wrench_world), self.robot.lower,
                                  self.robot.upper))
