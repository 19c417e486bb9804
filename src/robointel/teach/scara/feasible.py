"""Torque-feasible online reference (3.9).

Acceleration bounds from the effort limits and M(q), b(q, qd), and the jerk-limited follower of
:mod:`robointel.control` (ruckig) with those bounds, set every period, that keeps the reference within them.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robointel.control import JerkLimitedFollower
from robointel.errors import InvalidInput
from robointel.robot import Robot


def accel_limits(robot: Robot, q: npt.ArrayLike, qd: npt.ArrayLike, *, margin: float = 0.85, ratio: float = 2.0,
                 qdd: npt.ArrayLike | None = None, floor: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Joint acceleration bounds that the effort limits allow at (q, qd).

    With ``qdd`` None: the symmetric box |qdd_i| <= A_i such that every qdd in it satisfies
    |M(q) qdd + b(q, qd)|_i <= margin tau_max,i, b = C(q, qd) qd + G(q) + F_v qd (3.9): row i needs
    sum_j |M_ij| A_j <= margin tau_max,i - |b_i|; A_j proportional to (1, ratio, ...), the largest such box.

    With ``qdd`` (n,) (the accelerations the joints have now): joint i's own range with the other
    joints' accelerations held at ``qdd``: (+-margin tau_max,i - b_i - sum_{j != i} M_ij qdd_j) / M_ii
    (the coupling as it is, not its worst case; jerk-limited accelerations change little per period).
    Each range keeps 0 inside it, at least +-floor * margin tau_max,i / M_ii (with ``qdd``) or
    +-1e-3 (the box), so that the follower can always brake within a bounded time.

    Args:
        robot: the robot (M(q), b(q, qd), effort limits).
        q: (n,) joint angles [rad].
        qd: (n,) joint rates [rad/s].
        margin: share of the effort limits to use.
        ratio: A_{j+1} / A_j of the box.
        qdd: (n,) the joints' current accelerations [rad/s^2] (None: the box).
        floor: the least range kept, as a share of margin tau_max,i / M_ii.

    Returns:
        (lo (n,), hi (n,)) [rad/s^2].
    """
    M = robot.mass_matrix(q)
    qd = np.asarray(qd, float)
    b = robot.nonlinear_effects(q, qd) + robot.viscous * qd
    L = margin * np.asarray(robot.effort_limit, float)
    if qdd is None:
        shape = np.asarray(ratio, float) ** np.arange(len(b))
        room = np.maximum(L - np.abs(b), 0.0)
        A = np.maximum(np.min(room / (np.abs(M) @ shape)) * shape, 1e-3)
        return -A, A
    acc = np.asarray(qdd, float)
    d = np.diag(M)
    cross = M @ acc - d * acc + b
    lo, hi = (-L - cross) / d, (L - cross) / d
    return np.minimum(lo, -floor * L / d), np.maximum(hi, floor * L / d)


class FeasibleReference:
    """Torque-feasible online follower of a reference (:class:`~robointel.control.JerkLimitedFollower`).

    Each control period the state (q_s, qd_s, qdd_s) moves by one step of the time-optimal, jerk-limited
    trajectory to the target's current (q_r, qd_r), with acceleration bounds from the effort limits
    and the inertia at the follower's state (:func:`accel_limits`) and the robot's velocity limits.
    The LQ (3.7)-(3.9) then gets a reference it can follow, instead of saturating on jumps it cannot.
    ``mode="velocity"`` (default) aims ruckig's velocity interface at the target's rate plus a
    braking-curve feedback on the position error (gain ``gain`` near the target).

    Args:
        robot: the robot (M(q), b(q, qd), effort, velocity and position limits).
        dt: period [s].
        margin: share of the effort limits the reference may use (the rest is for the feedback).
        ratio: A2 / A1 of the acceleration box.
        jerk_time: time [s] to ramp the acceleration from 0 to its bound (jerk = A / jerk_time).
        coupling: "current" (the other joints' accelerations as they are) or "box" (worst case).
        mode: "velocity" or "position" ruckig interface.
        gain: position feedback gain [1/s] of the velocity mode.

    Raises:
        InvalidInput: a parameter out of range.
    """

    def __init__(self, robot: Robot, dt: float = 0.001, *, margin: float = 0.9, ratio: float = 2.0,
                 jerk_time: float = 0.004, coupling: str = "current", mode: str = "velocity",
                 gain: float = 20.0) -> None:

        if not (0.0 < margin <= 1.0) or ratio <= 0 or jerk_time <= 0:
            raise InvalidInput(f"FeasibleReference: margin in (0, 1], ratio > 0 and jerk_time > 0 "
                               f"(got {margin}, {ratio}, {jerk_time})")
        if coupling not in ("box", "current"):
            raise InvalidInput(f"FeasibleReference: coupling must be 'box' or 'current', got {coupling!r}")
        self.robot, self.dt, self.margin, self.ratio, self.jerk_time = robot, dt, margin, ratio, jerk_time
        if mode not in ("position", "velocity"):
            raise InvalidInput(f"FeasibleReference: mode must be 'position' or 'velocity', got {mode!r}")
        self.coupling, self.mode, self.gain = coupling, mode, float(gain)
        n = robot.nq
        # the acceleration and jerk bounds are set every period from the effort limits (set_limits)
        self.follower = JerkLimitedFollower(np.asarray(robot.velocity_limit, float), np.ones(n), np.ones(n), dt=dt,
                                            gain=gain, brake_share=1.0, velocity_share=0.99, synchronize=False)
        self.q = self.qd = self.qdd = np.zeros(n)
        self.scaled = 0

    def reset(self, q: npt.ArrayLike, qd: npt.ArrayLike | None = None) -> None:
        """Start at rest (or at velocity ``qd`` (n,) [rad/s]) at ``q`` (n,) [rad]."""
        n = self.robot.nq
        self.q = np.array(q, float)
        self.qd = np.zeros(n) if qd is None else np.array(qd, float)
        self.qdd = np.zeros(n)
        self.scaled = 0  # steps whose acceleration had to be scaled down (coupling)
        self.follower.reset(self.q, self.qd)

    def step(self, q_r: npt.ArrayLike, qd_r: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One period toward the target.

        Args:
            q_r: (n,) target angles [rad].
            qd_r: (n,) target rates [rad/s].

        Returns:
            The new state (q_s, qd_s, qdd_s), (n,) each [rad, rad/s, rad/s^2].

        Raises:
            SolverFailure: ruckig rejected the step.
        """
        rb, fol = self.robot, self.follower
        lo, hi = accel_limits(rb, self.q, self.qd, margin=self.margin, ratio=self.ratio,
                              qdd=self.qdd if self.coupling == "current" else None)
        fol.set_limits(min_acceleration=lo, max_acceleration=hi, max_jerk=np.maximum(-lo, hi) / self.jerk_time)
        # the bounds change with q: a state beyond the new ones is brought back by ruckig itself
        target = np.clip(q_r, rb.lower, rb.upper)
        q, qd, a = fol.step(target, qd_r) if self.mode == "velocity" else fol.step_position(target, qd_r)
        # the per-joint bounds hold the other joints' accelerations at their last values; when the joints
        # change together the coupling can still ask for more: scale the step's acceleration as a whole
        # (largest alpha in [0, 1] with |M alpha a + b| <= margin tau_max) and integrate it here instead
        M = rb.mass_matrix(self.q)
        bias = rb.nonlinear_effects(self.q, self.qd) + rb.viscous * self.qd
        L, Ma = self.margin * np.asarray(rb.effort_limit, float), M @ a
        alpha = 1.0
        for i in range(len(a)):
            if abs(Ma[i] + bias[i]) > L[i] and abs(Ma[i]) > 1e-12:
                alpha = min(alpha, max(L[i] - np.sign(Ma[i]) * bias[i], 0.0) / abs(Ma[i]))
        if alpha < 1.0:
            a = alpha * a
            self.q = self.q + self.dt * self.qd + 0.5 * self.dt ** 2 * a
            self.qd = self.qd + self.dt * a
            fol.reset(self.q, self.qd, a)
        else:
            self.q, self.qd = q, qd
        self.qdd = a
        self.scaled += alpha < 1.0
        return self.q, self.qd, self.qdd
