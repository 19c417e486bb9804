"""Key-point path reproduction (Ch. 3.3, Figs. 3.11-3.12).

A path guided by hand is noisy and slow; the robot reproduces it from a few key points instead:

1. :func:`extract_keypoints` picks the start, the end, dwell points (the operator paused) and
   direction changes (corners of a Ramer-Douglas-Peucker simplification of the path).
2. :func:`blended_trajectory` joins the key points with straight line segments at constant speed
   and rounds each corner with a cubic (parabolic-velocity) or quintic (continuous-acceleration)
   blend; it starts and ends at rest.
3. :func:`joint_velocity_reference` turns the Cartesian trajectory into a joint velocity reference
   by resolved-rate control with position feedback, dq = J^# (V_d + K e).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation, Slerp

from robointel._validate import as_array
from robointel.control.admittance import damped_pinv
from robointel.errors import InvalidInput
from robointel.trajectory import Trajectory

if TYPE_CHECKING:  # pragma: no cover
    from robointel.robot import Robot

__all__ = ["BlendedTrajectory", "Reproduction", "blended_trajectory", "extract_keypoints",
           "joint_velocity_reference", "orientation_reference", "plot_reproduction", "rdp_indices",
           "reproduce_path"]


def rdp_indices(points: np.ndarray, tolerance: float) -> np.ndarray:
    """Indices kept by the Ramer-Douglas-Peucker simplification of a polyline (N, d) within ``tolerance`` (same units).

    Always keeps the first and last point. Iterative, no recursion.
    """
    P = np.asarray(points, float)
    n = len(P)
    if n <= 2:
        return np.arange(n)
    keep = np.zeros(n, bool)
    keep[[0, n - 1]] = True
    stack = [(0, n - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        seg = P[b] - P[a]
        L = np.linalg.norm(seg)
        rel = P[a + 1:b] - P[a]
        if L < 1e-12:
            d = np.linalg.norm(rel, axis=1)
        else:
            u = seg / L
            d = np.linalg.norm(rel - np.outer(rel @ u, u), axis=1)
        k = int(np.argmax(d))
        if d[k] > tolerance:
            m = a + 1 + k
            keep[m] = True
            stack += [(a, m), (m, b)]
    return np.flatnonzero(keep)


def extract_keypoints(t: ArrayLike, positions: ArrayLike, *, tolerance: float = 0.01, dwell_speed: float = 0.01,
                      dwell_time: float = 0.3, min_separation: float = 0.005) -> np.ndarray:
    """Key points of a guided path: start, end, dwells and direction changes.

    Args:
        t: (N,) increasing times, s.
        positions: (N, 3) tool positions, m.
        tolerance: RDP tolerance, m (how far the reproduced path may stray from the guided one).
        dwell_speed: speeds below this (m/s) count as standing still.
        dwell_time: standing still at least this long (s) makes a key point.
        min_separation: key points closer than this (m) are merged (the first is kept).

    Returns:
        Sorted indices into ``t`` of the key points (first and last included).
    """
    t = as_array(t, "t", (None,))
    P = as_array(positions, "positions", (len(t), 3))
    if len(t) < 2:
        raise InvalidInput("a path needs at least 2 samples", value=len(t))
    if np.any(np.diff(t) <= 0):
        raise InvalidInput("t must be strictly increasing")
    idx = set(rdp_indices(P, tolerance).tolist())
    speed = np.linalg.norm(np.gradient(P, t, axis=0), axis=1)
    still = speed < dwell_speed
    # runs of standing still: take the middle of each long enough run
    edges = np.flatnonzero(np.diff(np.r_[0, still.astype(int), 0]))
    for s, e in zip(edges[::2], edges[1::2]):
        if t[e - 1] - t[s] >= dwell_time:
            idx.add((s + e - 1) // 2)
    order = sorted(idx)
    out = [order[0]]
    for i in order[1:]:
        if np.linalg.norm(P[i] - P[out[-1]]) >= min_separation:
            out.append(i)
    if out[-1] != len(t) - 1:
        if np.linalg.norm(P[-1] - P[out[-1]]) < min_separation and len(out) > 1:
            out[-1] = len(t) - 1
        else:
            out.append(len(t) - 1)
    return np.array(out, dtype=int)


@dataclass
class BlendedTrajectory:
    """Straight segments between key points with polynomial corner blends.

    Attributes:
        points: (K, 3) key points, m.
        times: (K,) time at which the path passes the corner of each key point, s.
        blend: (K,) blend durations, s.
        velocities: (K+1, 3) segment velocities (first and last are zero: at rest), m/s.
        kind: "cubic" or "quintic".
    """

    points: np.ndarray
    times: np.ndarray
    blend: np.ndarray
    velocities: np.ndarray
    kind: str

    @property
    def duration(self) -> float:
        """Total time from rest to rest, s."""
        return float(self.times[-1] + self.blend[-1] / 2)

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration of the blended trajectory.

        Position (M, 3), velocity (M, 3) and acceleration (M, 3) at times t (M,) (clipped to [0, duration]).
        """
        t = np.clip(np.atleast_1d(np.asarray(t, float)), 0.0, self.duration)
        K = len(self.points)
        # which segment (line after key point k) or blend k each t falls in
        k = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, K - 1)
        # nearest key point: blend if within its half-width
        kn = np.clip(np.searchsorted(self.times, t), 0, K - 1)
        kp = np.clip(kn - 1, 0, K - 1)
        near = np.where(np.abs(t - self.times[kp]) <= np.abs(t - self.times[kn]), kp, kn)
        in_blend = np.abs(t - self.times[near]) <= self.blend[near] / 2
        v_line = self.velocities[k + 1]
        p = self.points[k] + v_line * (t - self.times[k])[:, None]
        v = v_line.copy()
        a = np.zeros_like(p)
        if np.any(in_blend):
            j = near[in_blend]
            tau = self.blend[j]
            s = (t[in_blend] - self.times[j] + tau / 2) / tau  # 0..1
            vi, vo = self.velocities[j], self.velocities[j + 1]
            dv = vo - vi
            if self.kind == "cubic":  # velocity linear in s: constant acceleration
                g, dg, ig = s, np.ones_like(s), s ** 2 / 2
            else:  # quintic: velocity smoothstep, acceleration zero at both ends
                g = 3 * s ** 2 - 2 * s ** 3
                dg = 6 * s - 6 * s ** 2
                ig = s ** 3 - s ** 4 / 2
            start = self.points[j] - vi * (tau / 2)[:, None]
            p[in_blend] = start + (vi * s[:, None] + dv * ig[:, None]) * tau[:, None]
            v[in_blend] = vi + dv * g[:, None]
            a[in_blend] = dv * (dg / tau)[:, None]
        return p, v, a


def blended_trajectory(points: ArrayLike, *, speed: float = 0.1, blend_time: float = 0.4,
                       kind: str = "quintic") -> BlendedTrajectory:
    """Line segments through key points at ``speed`` with corner blends, from rest to rest.

    Each corner blend lasts ``blend_time`` (shortened on short segments so blends never
    overlap); the path passes within ``|v_out - v_in| blend_time / 8`` of an interior key point
    and exactly through the first and last ones.

    Args:
        points: (K, 3) key points, m (K >= 2).
        speed: cruise speed along segments, m/s.
        blend_time: corner blend duration, s.
        kind: "cubic" (constant acceleration in the blend) or "quintic" (smooth acceleration).
    """
    P = as_array(points, "points", (None, 3))
    if len(P) < 2:
        raise InvalidInput("need at least 2 key points", value=len(P))
    if kind not in ("cubic", "quintic"):
        raise InvalidInput(f"kind must be 'cubic' or 'quintic', got {kind!r}", value=kind)
    if not (speed > 0 and blend_time > 0):
        raise InvalidInput("speed and blend_time must be positive")
    L = np.linalg.norm(np.diff(P, axis=0), axis=1)
    if np.any(L < 1e-9):
        raise InvalidInput("consecutive key points coincide; remove duplicates first")
    K = len(P)
    tau = np.full(K, float(blend_time))
    T = np.maximum(L / speed, 1e-3)
    # blends must fit: tau_k/2 + tau_{k+1}/2 <= T_k, shrink blends on short segments
    for k in range(K - 1):
        if tau[k] / 2 + tau[k + 1] / 2 > T[k]:
            tau[k] = min(tau[k], T[k])
            tau[k + 1] = min(tau[k + 1], T[k])
    V = np.zeros((K + 1, 3))
    V[1:K] = np.diff(P, axis=0) / T[:, None]
    times = tau[0] / 2 + np.r_[0.0, np.cumsum(T)]
    return BlendedTrajectory(points=P.copy(), times=times, blend=tau, velocities=V, kind=kind)


def orientation_reference(trajectory: BlendedTrajectory, rotations: ArrayLike, t: ArrayLike) -> np.ndarray:
    """Tool orientation reference (M, 3, 3) at times t (M,).

    Slerp between the key points' orientations ``rotations`` (K, 3, 3), eased (smoothstep) so it rests at each key
    point.
    """
    R = as_array(rotations, "rotations", (len(trajectory.points), 3, 3))
    knots = trajectory.times.copy()
    knots[0], knots[-1] = 0.0, trajectory.duration
    t = np.clip(np.asarray(t, float), 0.0, trajectory.duration)
    k = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(knots) - 2)
    s = (t - knots[k]) / (knots[k + 1] - knots[k])
    tau = knots[k] + (knots[k + 1] - knots[k]) * (3 * s ** 2 - 2 * s ** 3)
    return Slerp(knots, Rotation.from_matrix(R))(tau).as_matrix()


def joint_velocity_reference(robot: Robot, q0: ArrayLike, trajectory: BlendedTrajectory, *,
                             rotations: ArrayLike | None = None, dt: float = 0.001,
                             gain: float = 20.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint velocity reference that makes the TCP follow ``trajectory`` (Fig. 3.12).

    Resolved-rate control with feedback, dq = J^#(q) [v_d + K (p_d - p); w_d + K log(R_d R^T)],
    integrated with step ``dt``. The orientation R_d is the start orientation, or with
    ``rotations`` (K, 3, 3) the key points' orientations interpolated by
    :func:`orientation_reference`.

    Args:
        robot: :class:`robointel.robot.Robot`.
        q0: (n,) start configuration; its TCP should be at the trajectory's first point.
        trajectory: from :func:`blended_trajectory`.
        rotations: optional key-point tool orientations.
        dt: sample time, s.
        gain: position/orientation feedback gain K, 1/s.

    Returns:
        t (M,), q (M, n), dq (M, n).
    """
    q = robot.check_q(q0).copy()
    t = np.arange(0.0, trajectory.duration + dt / 2, dt)
    pd, vd, _ = trajectory(t)
    if rotations is None:
        Rd = np.repeat(robot.fk(q)[:3, :3][None], len(t), 0)
        wd = np.zeros((len(t), 3))
    else:
        Rd = orientation_reference(trajectory, rotations, t)
        wd = np.zeros((len(t), 3))
        wd[:-1] = np.array([pin.log3(b @ a.T) for a, b in zip(Rd[:-1], Rd[1:])]) / dt
    Q = np.empty((len(t), robot.nq))
    dQ = np.empty_like(Q)
    for i in range(len(t)):
        T = robot.fk(q)
        e_p = pd[i] - T[:3, 3]
        e_r = pin.log3(Rd[i] @ T[:3, :3].T)
        V = np.r_[vd[i] + gain * e_p, wd[i] + gain * e_r]
        dq = damped_pinv(robot.jacobian(q)) @ V
        dq = np.clip(dq, -robot.velocity_limit, robot.velocity_limit)
        Q[i], dQ[i] = q, dq
        q = q + dq * dt
    return t, Q, dQ


@dataclass
class Reproduction:
    """A guided path reproduced from its key points (Figs. 3.11-3.12).

    Attributes:
        keypoints: indices into the guided path.
        cartesian: the blended Cartesian TCP trajectory through the key points.
        trajectory: the joint reference (M samples at the reference's step), s, rad, rad/s and
            rad/s^2 (accelerations by finite differences of the velocity reference).
        path_error: largest distance (m) from the reproduced TCP path to the guided polyline.
    """

    keypoints: np.ndarray
    cartesian: BlendedTrajectory
    trajectory: Trajectory
    path_error: float


def _polyline_distance(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of each point (M, 3) to a polyline (N, 3)."""
    a, b = poly[:-1], poly[1:]
    ab = b - a
    L2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18)
    best = np.full(len(points), np.inf)
    for s in range(0, len(points), 256):
        p = points[s:s + 256, None, :]
        u = np.clip(np.einsum("mij,ij->mi", p - a[None], ab) / L2, 0.0, 1.0)
        d = np.linalg.norm(p - (a[None] + u[..., None] * ab[None]), axis=2)
        best[s:s + 256] = d.min(1)
    return best


def reproduce_path(robot: Robot, t: ArrayLike, positions: ArrayLike, q0: ArrayLike, *,
                   rotations: ArrayLike | None = None, tolerance: float = 0.01, speed: float = 0.1,
                   blend_time: float = 0.4, kind: str = "quintic", dt: float = 0.001,
                   **keypoint_args: Any) -> Reproduction:
    """Key points of a guided TCP path -> blended trajectory -> joint velocity reference.

    Args:
        robot: :class:`robointel.robot.Robot`.
        t: (N,) times of the guided path, s.
        positions: (N, 3) TCP positions, m.
        q0: (n,) configuration at the path's start (its TCP at positions[0]).
        rotations: optional (N, 3, 3) tool orientations along the guided path; the reproduction
            then passes the key points with their orientations (else it holds the start one).
        tolerance: path tolerance of :func:`extract_keypoints`, m.
        speed: TCP speed of :func:`blended_trajectory`, m/s.
        blend_time: corner blend duration, s.
        kind: ``"cubic"`` or ``"quintic"`` corner blends.
        dt: sample time of the joint reference, s.
        **keypoint_args: further arguments of :func:`extract_keypoints`.

    Returns:
        The key points, the Cartesian trajectory, the joint reference (a :class:`Trajectory`) and
        the largest distance to the guided path.
    """
    P = as_array(positions, "positions", (None, 3))
    k = extract_keypoints(t, P, tolerance=tolerance, **keypoint_args)
    tr = blended_trajectory(P[k], speed=speed, blend_time=blend_time, kind=kind)
    Rk = None if rotations is None else as_array(rotations, "rotations", (len(P), 3, 3))[k]
    tt, Q, dQ = joint_velocity_reference(robot, q0, tr, rotations=Rk, dt=dt)
    tcp = np.array([robot.fk(q)[:3, 3] for q in Q[::10]])
    err = float(_polyline_distance(tcp, P[np.r_[0:len(P):5, len(P) - 1]]).max())
    joints = Trajectory(tt, Q, dQ, np.gradient(dQ, tt, axis=0), list(getattr(robot, "joint_names", [])))
    return Reproduction(k, tr, joints, err)


def plot_reproduction(guided: np.ndarray, rep: Reproduction, path: str | Path, *,
                      executed: np.ndarray | None = None) -> Path:
    """Guided path, key points and reproduced path (Fig.

    3.11) beside the joint velocity reference (Fig. 3.12). ``guided`` (N, 3) and ``executed`` (M, 3) are TCP
    positions, m. Returns the PNG path.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    guided = np.asarray(guided, float)
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    # the plane of largest spread of the guided path
    ax0, ax1 = np.argsort(np.ptp(guided, axis=0))[::-1][:2]
    names = "xyz"
    ax[0].plot(guided[:, ax0], guided[:, ax1], c="0.6", lw=3, label="guided")
    p, _, _ = rep.cartesian(rep.trajectory.t)
    ax[0].plot(p[:, ax0], p[:, ax1], c="C0", label="reproduced (reference)")
    if executed is not None:
        ax[0].plot(executed[:, ax0], executed[:, ax1], "--", c="C1", label="executed (MuJoCo)")
    kp = guided[rep.keypoints]
    ax[0].plot(kp[:, ax0], kp[:, ax1], "o", c="C3", label="key points")
    ax[0].set_xlabel(f"{names[ax0]} [m]")
    ax[0].set_ylabel(f"{names[ax1]} [m]")
    ax[0].axis("equal")
    ax[0].legend(fontsize=7)
    ax[0].set_title(f"{len(rep.keypoints)} key points, path error {rep.path_error * 1e3:.1f} mm", fontsize=9)
    ax[1].plot(rep.trajectory.t, rep.trajectory.qd)
    ax[1].set_xlabel("time [s]")
    ax[1].set_ylabel("joint velocity reference [rad/s]")
    ax[1].legend([f"J{i + 1}" for i in range(rep.trajectory.n_joints)], fontsize=7, ncol=2)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
