"""The move to a trajectory's start: a quintic point-to-point joint move within a fraction of the limits.

A taught or planned trajectory starts where it was taught, not where the arm stands. Before it
runs, the arm is brought to its first sample by the minimum-jerk quintic
``q(s) = q0 + (q1 - q0)(10 s^3 - 15 s^4 + 6 s^5)``, ``s = t / T``, whose peak speed is
``1.875 |q1 - q0| / T`` and peak acceleration ``5.7735 |q1 - q0| / T^2``; ``T`` is the shortest
duration that keeps every joint within ``fraction`` of its speed and acceleration limits.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput
from robointel.trajectory import Trajectory

PEAK_SPEED = 1.875
PEAK_ACCELERATION = 10.0 / np.sqrt(3.0)


def approach_trajectory(q_from: npt.ArrayLike, q_to: npt.ArrayLike, velocity_limit: npt.ArrayLike,
                        acceleration_limit: npt.ArrayLike, *, fraction: float = 0.2, period: float = 0.008,
                        joint_names: Sequence[str] = ()) -> Trajectory:
    """The quintic joint move from ``q_from`` to ``q_to`` at ``fraction`` of the limits, sampled at ``period``.

    Args:
        q_from: (n,) start, rad.
        q_to: (n,) goal, rad.
        velocity_limit: (n,) joint speed limits, rad/s.
        acceleration_limit: (n,) joint acceleration limits, rad/s^2.
        fraction: share of the limits the move may use, in (0, 1].
        period: sampling period of the returned knots, s.
        joint_names: n names (default ``joint_1``...).

    Returns:
        The :class:`~robointel.trajectory.Trajectory` (at least two knots; rest at both ends).

    Raises:
        InvalidInput: shapes differ, values are not finite, limits are not positive, or
            ``fraction`` / ``period`` out of range.
    """
    a, b = np.asarray(q_from, dtype=float).reshape(-1), np.asarray(q_to, dtype=float).reshape(-1)
    v = np.asarray(velocity_limit, dtype=float).reshape(-1)
    acc = np.asarray(acceleration_limit, dtype=float).reshape(-1)
    if not (a.shape == b.shape == v.shape == acc.shape):
        raise InvalidInput(f"q_from, q_to and the limits must have one value per joint, got {a.shape}, {b.shape}, "
                           f"{v.shape}, {acc.shape}", value=(q_from, q_to))
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b)) and np.all(v > 0) and np.all(acc > 0)):
        raise InvalidInput("joint positions must be finite and limits positive", value=(q_from, q_to))
    if not (0 < fraction <= 1 and 0 < period <= 1):
        raise InvalidInput(f"fraction must be in (0, 1] and period in (0, 1] s, got {fraction}, {period}",
                           value=(fraction, period))
    d = b - a
    T = float(np.max(np.maximum(PEAK_SPEED * np.abs(d) / (fraction * v),
                                 np.sqrt(PEAK_ACCELERATION * np.abs(d) / (fraction * acc)))))
    K = max(2, int(np.ceil(T / period)) + 1)
    T = (K - 1) * period
    t = np.arange(K, dtype=np.float64) * period
    s = t / T
    pos = 10 * s**3 - 15 * s**4 + 6 * s**5
    vel = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
    accel = (60 * s - 180 * s**2 + 120 * s**3) / T**2
    return Trajectory(t, a + pos[:, None] * d, vel[:, None] * d, accel[:, None] * d, list(joint_names))
