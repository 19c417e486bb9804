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

import numpy as np

from robointel._validate import as_array
from robointel.errors import InvalidInput
from robointel.programming.compliance import damped_pinv

__all__ = ["BlendedTrajectory", "blended_trajectory", "extract_keypoints", "joint_velocity_reference",
           "rdp_indices"]


def rdp_indices(points: np.ndarray, tolerance: float) -> np.ndarray:
    """Indices kept by the Ramer-Douglas-Peucker simplification of a polyline (N, d) within
    ``tolerance`` (same units); always keeps the first and last point. Iterative, no recursion."""
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


def extract_keypoints(t, positions, *, tolerance: float = 0.01, dwell_speed: float = 0.01,
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

    def __call__(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position (M, 3), velocity (M, 3) and acceleration (M, 3) at times t (M,) (clipped to
        [0, duration])."""
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


def blended_trajectory(points, *, speed: float = 0.1, blend_time: float = 0.4,
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


def joint_velocity_reference(robot, q0, trajectory: BlendedTrajectory, *, dt: float = 0.001,
                             gain: float = 20.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint velocity reference that makes the TCP follow ``trajectory`` (Fig. 3.12).

    Resolved-rate control with position feedback, holding the start orientation:
    dq = J^#(q) [v_d + K (p_d - p); K log(R_0 R^T)], integrated with step ``dt``.

    Args:
        robot: :class:`robointel.robot.Robot`.
        q0: (n,) start configuration; its TCP should be at the trajectory's first point.
        trajectory: from :func:`blended_trajectory`.
        dt: sample time, s.
        gain: position/orientation feedback gain K, 1/s.

    Returns:
        t (M,), q (M, n), dq (M, n).
    """
    import pinocchio as pin

    q = robot.check_q(q0).copy()
    t = np.arange(0.0, trajectory.duration + dt / 2, dt)
    pd, vd, _ = trajectory(t)
    R0 = robot.fk(q)[:3, :3]
    Q = np.empty((len(t), robot.nq))
    dQ = np.empty_like(Q)
    for i in range(len(t)):
        T = robot.fk(q)
        e_p = pd[i] - T[:3, 3]
        e_r = pin.log3(R0 @ T[:3, :3].T)
        V = np.r_[vd[i] + gain * e_p, gain * e_r]
        dq = damped_pinv(robot.jacobian(q)) @ V
        dq = np.clip(dq, -robot.velocity_limit, robot.velocity_limit)
        Q[i], dQ[i] = q, dq
        q = q + dq * dt
    return t, Q, dQ
