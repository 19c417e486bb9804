"""Figures against the human motion delayed by a known time.

The ideal delayed signal (no robot), the robot measured against the recorded motion shifted by
the known delay, and the torques that following a motion exactly would take.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline

from robointel.errors import InvalidInput
from robointel.robot import Robot
from robointel.teach.scara.angles import human_reference, recorded_angles
from robointel.teach.scara.simulation import ScaraResult
from robointel.teach.skeleton import Skeleton


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


def delay_aligned_rms(result: ScaraResult, skel: Skeleton, *, delay: float = 0.1, robot: Robot | None = None,
                      side: str | None = None, elbow: str = "flexion") -> np.ndarray:
    """RMS over time of q_robot(t) - q_human(t - delay), the tracking error with the known delay taken out.

    This is the dissertation's "if the delay is compensated in 0.1 second" figure.

    q_human are the angles from the recording itself (:func:`recorded_angles`: dropouts bridged,
    not smoothed), clipped to the robot's range and interpolated linearly between frames; the RMS
    runs over the control steps with t - delay inside the recording.

    Args:
        result: a SCARA run of ``simulate_scara`` on ``skel`` (normally live and uncompensated).
        skel: the raw skeleton the run imitated.
        delay: the known delay taken out [s] (>= 0).
        robot: whose joint range clips the angles (default ``Robot.load("scara2")``).
        side: the arm the run used (default: the more active one).
        elbow: the run's elbow angle, "flexion" or "planar".

    Returns:
        (2,) RMS [rad].

    Raises:
        InvalidInput: a negative delay, or a run shorter than the delay.
    """
    if delay < 0:
        raise InvalidInput(f"delay must be >= 0 s, got {delay}", value=delay)
    robot = robot or Robot.load("scara2")
    t_h, q_rec = recorded_angles(skel, side, elbow=elbow)
    q_rec = np.clip(q_rec, robot.lower, robot.upper)
    ts = result.t - delay
    ok = (ts >= t_h[0]) & (ts <= t_h[-1])
    if not ok.any():
        raise InvalidInput(f"the run ({result.t[-1]:.3g} s) is shorter than the delay {delay} s", value=delay)
    q_h = np.stack([np.interp(ts[ok], t_h, q_rec[:, j]) for j in range(q_rec.shape[1])], axis=1)
    return np.sqrt(np.mean((result.q[ok] - q_h) ** 2, axis=0))


def required_torques(t: npt.ArrayLike, q: npt.ArrayLike, robot: Robot, *,
                     dt: float = 0.001) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Torques and rates it takes to follow the cubic spline through (t, q) exactly (3.9).

    tau = M(q) qdd + C(q, qd) qd + G(q) + F_v qd on the 1/dt grid, qd and qdd the spline's
    derivatives (what a perfect follower of the motion would have to apply).

    Args:
        t: (N,) sample times [s], increasing.
        q: (N, n) joint angles [rad] (clipped to the robot's range).
        robot: the robot (dynamics, joint range).
        dt: grid period [s].

    Returns:
        grid times (M,) [s], torques (M, n) [N m], rates (M, n) [rad/s].

    Raises:
        InvalidInput: shapes that do not match the robot, or fewer than 2 samples.
    """
    t = np.asarray(t, float)
    q = np.asarray(q, float)
    if q.ndim != 2 or q.shape[1] != robot.nq or len(t) != len(q) or len(t) < 2:
        raise InvalidInput(f"required_torques: t (N,) and q (N, {robot.nq}) with N >= 2, got {t.shape} and "
                           f"{q.shape}", value=q.shape)
    spline = CubicSpline(t, np.clip(q, robot.lower, robot.upper), axis=0)
    tg = t[0] + np.arange(int(np.floor((t[-1] - t[0]) / dt)) + 1) * dt
    qg, qd, qdd = spline(tg), spline(tg, 1), spline(tg, 2)
    tau = np.array([robot.mass_matrix(a) @ c + robot.nonlinear_effects(a, b) + robot.viscous * b
                    for a, b, c in zip(qg, qd, qdd, strict=True)])
    return tg, tau, qd
