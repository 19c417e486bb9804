"""Signal-only figures of a recording against its own delayed copy (no robot)."""
from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from robointel.programming.scara.angles import human_reference
from robointel.programming.skeleton import Skeleton
from robointel.robot import Robot


def delayed_copy_rms(skel: Skeleton, *, latency: float = 0.1, robot: Robot | None = None, dt: float = 0.001,
                     elbow: str = "flexion") -> np.ndarray:
    """RMS of q_human(t - latency) - q_human(t) on the 1/dt grid.

    A perfect, noise-free copy of the true human motion delayed by the latency: what an ideal
    uncompensated system with no frame age and no sensor noise would reach (a live system without
    prediction does worse).

    Args:
        skel: raw skeleton.
        latency: the delay [s].
        robot: whose joint range clips the angles (default ``Robot.load("scara2")``).
        dt: grid period [s].
        elbow: "flexion" or "planar".

    Returns:
        (2,) RMS [rad].
    """
    robot = robot or Robot.load("scara2")
    t_h, q_true, _ = human_reference(skel, elbow=elbow)
    spline = CubicSpline(t_h, np.clip(q_true, robot.lower, robot.upper), axis=0)
    t = np.arange(int(np.floor(t_h[-1] / dt)) + 1) * dt
    return np.sqrt(np.mean((spline(np.maximum(t - latency, t_h[0])) - spline(t)) ** 2, axis=0))
