"""Computed torque (3.9) around discrete LQ tracking (3.2)-(3.8).

Computed torque

    tau = M(q) u + C(q, qd) qd + G(q) + F_v qd

turns the robot into decoupled double integrators qdd = u. Sampled at T these are
x_{k+1} = A x_k + B u_k with x = [q; qd] (3.2)-(3.5). The discrete LQ tracking law minimises
sum (x_k - r_k)' Q (x_k - r_k) + u_k' R u_k (3.6); its gain comes from the discrete algebraic
Riccati equation (3.7)-(3.8) (``scipy.linalg.solve_discrete_are``):

    P = A'PA - A'PB (R + B'PB)^-1 B'PA + Q,     K = (R + B'PB)^-1 B'PA,
    u_k = qdd_r,k - K (x_k - r_k).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy.linalg import solve_discrete_are

from robointel.errors import InvalidInput
from robointel.robot import Robot


def double_integrator(n: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation of n double integrators (3.2)-(3.5).

    Args:
        n: number of joints.
        dt: sampling period [s].

    Returns:
        A (2n, 2n), B (2n, n) with x = [q; qd], u = qdd.
    """
    eye = np.eye(n)
    A = np.block([[eye, dt * eye], [np.zeros((n, n)), eye]])
    B = np.vstack([0.5 * dt * dt * eye, dt * eye])
    return A, B


def lq_gain(A: npt.ArrayLike, B: npt.ArrayLike, Q: npt.ArrayLike,
            R: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Solve the DARE (3.7) and return the LQ gain (3.8).

    Args:
        A: (m, m) state matrix.
        B: (m, n) input matrix.
        Q: (m, m) state weight.
        R: (n, n) input weight (or a scalar for n = 1).

    Returns:
        K (n, m) = (R + B'PB)^-1 B'PA and P (m, m), the Riccati solution.
    """
    A, B = np.asarray(A, float), np.asarray(B, float)
    Qm, Rm = np.atleast_2d(Q).astype(float), np.atleast_2d(R).astype(float)
    P = solve_discrete_are(A, B, Qm, Rm)
    K = np.linalg.solve(Rm + B.T @ P @ B, B.T @ P @ A)
    return K, P


@dataclass
class ComputedTorqueLQ:
    """Computed torque (3.9) around discrete LQ tracking (3.7)-(3.8) for any robot.

    Args:
        robot: the robot (dynamics from Pinocchio).
        dt: control period [s].
        q_weight: LQ weight on the position error [1/rad^2] (scalar or one per joint).
        qd_weight: weight on the velocity error [s^2/rad^2].
        r_weight: weight on the commanded acceleration [s^4/rad^2]; 1e-6 gives a position gain
            of about 1000 s^-2.

    Raises:
        InvalidInput: a weight is not positive.
    """

    robot: Robot
    dt: float = 0.001
    q_weight: float = 1.0
    qd_weight: float = 1e-3
    r_weight: float = 1e-6
    K: np.ndarray = field(init=False)
    P: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        n = self.robot.nq
        A, B = double_integrator(n, self.dt)
        w = [np.broadcast_to(np.asarray(x, float), (n,)) for x in (self.q_weight, self.qd_weight, self.r_weight)]
        if any(np.any(x <= 0) for x in w):
            raise InvalidInput("LQ weights must be positive")
        self.K, self.P = lq_gain(A, B, np.diag(np.concatenate(w[:2])), np.diag(w[2]))

    def torque(self, q: npt.ArrayLike, qd: npt.ArrayLike, q_r: npt.ArrayLike, qd_r: npt.ArrayLike,
               qdd_r: npt.ArrayLike) -> np.ndarray:
        """Joint torques within the effort limits (3.9).

        When M(q) u + b (b = C qd + G + F_v qd) would exceed a limit, the commanded acceleration u
        is scaled down as a whole (largest alpha in [0, 1] with |M alpha u + b| <= limit): the
        joints stay decoupled and the robot accelerates in the commanded direction.

        Args:
            q: (n,) joint angles [rad].
            qd: (n,) joint rates [rad/s].
            q_r: (n,) reference angles [rad].
            qd_r: (n,) reference rates [rad/s].
            qdd_r: (n,) reference accelerations [rad/s^2].

        Returns:
            (n,) torques [N m].
        """
        q, qd = np.asarray(q, float), np.asarray(qd, float)
        u = np.asarray(qdd_r, float) - self.K @ (np.concatenate([q, qd]) - np.concatenate([q_r, qd_r]))
        rb = self.robot
        b = rb.nonlinear_effects(q, qd) + rb.viscous * qd
        a = rb.mass_matrix(q) @ u
        lim = rb.effort_limit
        alpha = 1.0
        for i in range(len(a)):
            if abs(a[i] + b[i]) > lim[i] and abs(a[i]) > 1e-12:
                room = lim[i] - np.sign(a[i]) * b[i]  # torque left for acceleration in a[i]'s direction
                alpha = min(alpha, max(room, 0.0) / abs(a[i]))
        return np.clip(alpha * a + b, -lim, lim)
