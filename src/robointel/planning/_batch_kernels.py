"""Compiled (numba) collision checks of many configurations at once, in structure-of-arrays form.

A batch holds up to :data:`LANES` configurations, one per *lane*. Every quantity of the check is an
array over the lanes: the joint placements ``TB`` (nj, 12, lanes) (the 3x4 top of each 4x4, row
by row), the sphere centres ``X``, ``Y``, ``Z`` (m, lanes) and the group centres ``GX``, ``GY``,
``GZ`` (g, lanes). Each step of the check (a joint's placement, a sphere's centre, a sphere's
distance to one obstacle) is one loop over the lanes with no branch inside, which the compiler
turns into vector instructions; the decisions (is a group near an obstacle in any lane, is any
lane below the threshold) are taken once per loop, for the whole batch.

The packed world ``W`` is the planner's (see :mod:`robointel.planning._collision_kernels`), for any
number of joints (revolute or prismatic) and any number of spheres per link; ``P`` is its
self-collision sphere pairs as flat lists (:func:`pair_lists`). The checks and their verdicts are
those of the scalar kernels:

- :func:`batch_free`: is every checked distance >= ``thresh`` in every lane (``config_valid``'s
  verdict per lane), with an early exit for the batch at the first lane found below it;
- :func:`batch_clearance`: each lane's smallest distance over obstacles and self-collision pairs,
  capped (``config_clearance``'s value per lane).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from robointel.geometry._kernels import CAPSULE, CYLINDER, SPHERE
from robointel.planning._collision_kernels import FM, _aabb_dist, _cloud_min

#: configurations per batch (the scratch arrays' width)
LANES = 32


class BatchScratch:
    """Work arrays of batched checks in one world (placements, centres, lane values), allocated once."""

    def __init__(self, W: tuple, lanes: int = LANES) -> None:
        nj, m, g, n = W[0].shape[0], W[5].shape[0], W[8].shape[0], int(W[20].shape[1])
        self.lanes = lanes
        self.Q = np.zeros((max(n, 1), lanes))
        self.TB = np.zeros((nj, 12, lanes))
        self.TB[0, 0], self.TB[0, 5], self.TB[0, 10] = 1.0, 1.0, 1.0  # joint 0: the fixed base
        self.X, self.Y, self.Z = np.empty((m, lanes)), np.empty((m, lanes)), np.empty((m, lanes))
        self.GX, self.GY, self.GZ = np.empty((g, lanes)), np.empty((g, lanes)), np.empty((g, lanes))
        self.L = np.empty((4, lanes))  # lane work rows: sin, 1 - cos, distances, best

    def arrays(self) -> tuple:
        """The tuple the kernels take: (Q, TB, X, Y, Z, GX, GY, GZ, L)."""
        return (self.Q, self.TB, self.X, self.Y, self.Z, self.GX, self.GY, self.GZ, self.L)


def pair_lists(W: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The self-collision sphere pairs of ``W`` as flat lists: (start (p + 1,), i (s,), j (s,)).

    Group pair ``k`` (``W[14][k]``) holds the sphere pairs ``i[start[k]:start[k+1]]``,
    ``j[start[k]:start[k+1]]`` (those with ``W[15][i, j] == 1``).
    """
    gpairs, smask, gs = W[14], W[15], W[11]
    start = [0]
    pi: list[int] = []
    pj: list[int] = []
    for a, b in gpairs:
        for i in range(gs[a], gs[a + 1]):
            for j in range(gs[b], gs[b + 1]):
                if smask[i, j]:
                    pi.append(i)
                    pj.append(j)
        start.append(len(pi))
    return np.array(start, np.int64), np.array(pi, np.int64), np.array(pj, np.int64)


@njit(cache=True, fastmath=FM)
def batch_fk(B, W, S):  # pragma: no cover - compiled
    """Joint placements ``S[1]`` (nj, 12, lanes) of the configurations ``S[0]`` (n, lanes), lanes 0..B-1."""
    parent, place, axis, kind, qidx = W[0], W[1], W[2], W[3], W[4]
    Qt, TB, L = S[0], S[1], S[8]
    sn, c1 = L[0], L[1]
    for j in range(1, parent.shape[0]):
        P = TB[parent[j]]
        T = TB[j]
        M = place[j]
        qr = Qt[qidx[j]]
        ax, ay, az = axis[j, 0], axis[j, 1], axis[j, 2]
        m00, m01, m02, m03 = M[0, 0], M[0, 1], M[0, 2], M[0, 3]
        m10, m11, m12, m13 = M[1, 0], M[1, 1], M[1, 2], M[1, 3]
        m20, m21, m22, m23 = M[2, 0], M[2, 1], M[2, 2], M[2, 3]
        if kind[j] == 0:
            for b in range(B):
                x = qr[b]
                sn[b] = math.sin(x)
                c1[b] = 1.0 - math.cos(x)
            for r in range(3):
                P0, P1, P2, P3 = P[4 * r], P[4 * r + 1], P[4 * r + 2], P[4 * r + 3]
                T0, T1, T2, T3 = T[4 * r], T[4 * r + 1], T[4 * r + 2], T[4 * r + 3]
                for b in range(B):
                    p0, p1, p2 = P0[b], P1[b], P2[b]
                    a0 = p0 * m00 + p1 * m10 + p2 * m20
                    a1 = p0 * m01 + p1 * m11 + p2 * m21
                    a2 = p0 * m02 + p1 * m12 + p2 * m22
                    s, c = sn[b], c1[b]
                    R00 = 1.0 - c * (ay * ay + az * az)
                    R11 = 1.0 - c * (ax * ax + az * az)
                    R22 = 1.0 - c * (ax * ax + ay * ay)
                    R01, R10 = -s * az + c * ax * ay, s * az + c * ax * ay
                    R02, R20 = s * ay + c * ax * az, -s * ay + c * ax * az
                    R12, R21 = -s * ax + c * ay * az, s * ax + c * ay * az
                    T0[b] = a0 * R00 + a1 * R10 + a2 * R20
                    T1[b] = a0 * R01 + a1 * R11 + a2 * R21
                    T2[b] = a0 * R02 + a1 * R12 + a2 * R22
                    T3[b] = p0 * m03 + p1 * m13 + p2 * m23 + P3[b]
        else:
            for r in range(3):
                P0, P1, P2, P3 = P[4 * r], P[4 * r + 1], P[4 * r + 2], P[4 * r + 3]
                T0, T1, T2, T3 = T[4 * r], T[4 * r + 1], T[4 * r + 2], T[4 * r + 3]
                for b in range(B):
                    p0, p1, p2 = P0[b], P1[b], P2[b]
                    a0 = p0 * m00 + p1 * m10 + p2 * m20
                    a1 = p0 * m01 + p1 * m11 + p2 * m21
                    a2 = p0 * m02 + p1 * m12 + p2 * m22
                    T0[b], T1[b], T2[b] = a0, a1, a2
                    T3[b] = p0 * m03 + p1 * m13 + p2 * m23 + P3[b] + qr[b] * (a0 * ax + a1 * ay + a2 * az)


@njit(cache=True, fastmath=FM, inline="always")
def _place(TB, j, px, py, pz, X, Y, Z, row, B):  # pragma: no cover - compiled
    """X/Y/Z[row, :B] = the point (px, py, pz) of joint j's frame in the world, per lane."""
    T = TB[j]
    xr, yr, zr = X[row], Y[row], Z[row]
    for b in range(B):
        xr[b] = T[0, b] * px + T[1, b] * py + T[2, b] * pz + T[3, b]
        yr[b] = T[4, b] * px + T[5, b] * py + T[6, b] * pz + T[7, b]
        zr[b] = T[8, b] * px + T[9, b] * py + T[10, b] * pz + T[11, b]


@njit(cache=True, fastmath=FM)
def batch_centres(B, W, S):  # pragma: no cover - compiled
    """Sphere centres ``S[2:5]`` (m, lanes) and group centres ``S[5:8]`` (g, lanes) of lanes 0..B-1."""
    batch_fk(B, W, S)
    sj, sp, gj, gc = W[5], W[6], W[8], W[9]
    TB, X, Y, Z, GX, GY, GZ = S[1], S[2], S[3], S[4], S[5], S[6], S[7]
    for i in range(sj.shape[0]):
        _place(TB, sj[i], sp[i, 0], sp[i, 1], sp[i, 2], X, Y, Z, i, B)
    for k in range(gj.shape[0]):
        _place(TB, gj[k], gc[k, 0], gc[k, 1], gc[k, 2], GX, GY, GZ, k, B)


@njit(cache=True, fastmath=FM, inline="always")
def _dist(t, p, X, Y, Z, row, B, D):  # pragma: no cover - compiled
    """D[:B] = signed distance of the points (X, Y, Z)[row, :B] to primitive (t, p), branch-free per lane.

    The values of :func:`robointel.geometry._kernels._one` (its first output).
    """
    xr, yr, zr = X[row], Y[row], Z[row]
    if t == SPHERE:
        cx, cy, cz, r = p[0], p[1], p[2], p[3]
        for b in range(B):
            vx, vy, vz = xr[b] - cx, yr[b] - cy, zr[b] - cz
            D[b] = math.sqrt(vx * vx + vy * vy + vz * vz) - r
    elif t == CAPSULE:
        ox, oy, oz, ux, uy, uz, L, r = p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7]
        for b in range(B):
            vx, vy, vz = xr[b] - ox, yr[b] - oy, zr[b] - oz
            s = min(max(vx * ux + vy * uy + vz * uz, 0.0), L)
            wx, wy, wz = vx - s * ux, vy - s * uy, vz - s * uz
            D[b] = math.sqrt(wx * wx + wy * wy + wz * wz) - r
    elif t == CYLINDER:
        ox, oy, oz, ux, uy, uz, h, r = p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7]
        for b in range(B):
            vx, vy, vz = xr[b] - ox, yr[b] - oy, zr[b] - oz
            a = vx * ux + vy * uy + vz * uz
            wx, wy, wz = vx - a * ux, vy - a * uy, vz - a * uz
            dx = abs(a) - h
            dr = math.sqrt(wx * wx + wy * wy + wz * wz) - r
            ex, er = max(dx, 0.0), max(dr, 0.0)
            D[b] = math.sqrt(ex * ex + er * er) + min(max(dx, dr), 0.0)
    else:  # BOX
        cx, cy, cz, h0, h1, h2 = p[0], p[1], p[2], p[3], p[4], p[5]
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = p[6], p[7], p[8], p[9], p[10], p[11], p[12], p[13], p[14]
        for b in range(B):
            vx, vy, vz = xr[b] - cx, yr[b] - cy, zr[b] - cz
            q0 = abs(r00 * vx + r10 * vy + r20 * vz) - h0
            q1 = abs(r01 * vx + r11 * vy + r21 * vz) - h1
            q2 = abs(r02 * vx + r12 * vy + r22 * vz) - h2
            e0, e1, e2 = max(q0, 0.0), max(q1, 0.0), max(q2, 0.0)
            D[b] = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2) + min(max(q0, max(q1, q2)), 0.0)


@njit(cache=True, fastmath=FM, inline="always")
def _lane_min(D, B):  # pragma: no cover - compiled
    m = np.inf
    for b in range(B):
        m = min(m, D[b])
    return m


@njit(cache=True, fastmath=FM, inline="always")
def _first_below(D, B, v):  # pragma: no cover - compiled
    for b in range(B):
        if D[b] < v:
            return b
    return -1


@njit(cache=True, fastmath=FM)
def batch_free(B, W, P, S, thresh, out):  # pragma: no cover - compiled
    """A lane (0..B-1) of the batch ``S[0]`` with a checked distance below ``thresh``, or -1 when none.

    The verdict per lane is ``config_valid``'s. The groups are looked at from the tool back (as
    :func:`~robointel.planning._node_check.config_free`), a group against an obstacle only when its
    bounding sphere is below ``thresh`` in some lane, and the check stops at the first pair found
    below ``thresh`` in any lane; ``out`` receives that pair (kind, sphere, obstacle or sphere).
    """
    batch_centres(B, W, S)
    X, Y, Z, GX, GY, GZ, L = S[2], S[3], S[4], S[5], S[6], S[7], S[8]
    D = L[2]
    gj, sr, gr, gs, types, params, cd = W[8], W[7], W[10], W[11], W[12], W[13], W[19]
    ng = gj.shape[0]
    out[0] = -1
    for kk in range(ng):
        k = ng - 1 - kk
        if gj[k] == 0:
            continue
        for o in range(types.shape[0]):
            _dist(types[o], params[o], GX, GY, GZ, k, B, D)
            if _lane_min(D, B) - gr[k] >= thresh:
                continue
            for i in range(gs[k], gs[k + 1]):
                _dist(types[o], params[o], X, Y, Z, i, B, D)
                if _lane_min(D, B) - sr[i] < thresh:
                    out[0], out[1], out[2] = 0, i, o
                    return _first_below(D, B, thresh + sr[i])
        if cd[0] > 0:
            for b in range(B):
                if _aabb_dist(GX[k, b], GY[k, b], GZ[k, b], W) - gr[k] >= thresh:
                    continue
                for i in range(gs[k], gs[k + 1]):
                    if _cloud_min(X[i, b], Y[i, b], Z[i, b], thresh + sr[i], W) - sr[i] < thresh:
                        out[0], out[1], out[2] = 2, i, 0
                        return b
    gpairs, ssr, sgr = W[14], W[21], W[22]
    start, pi, pj = P
    for p in range(gpairs.shape[0]):
        a, c = gpairs[p, 0], gpairs[p, 1]
        ax, ay, az, cx, cy, cz = GX[a], GY[a], GZ[a], GX[c], GY[c], GZ[c]
        lim = max(thresh + sgr[a] + sgr[c], 0.0)
        for b in range(B):
            dx, dy, dz = ax[b] - cx[b], ay[b] - cy[b], az[b] - cz[b]
            D[b] = dx * dx + dy * dy + dz * dz
        if _lane_min(D, B) >= lim * lim:
            continue
        for s in range(start[p], start[p + 1]):
            i, j = pi[s], pj[s]
            xi, yi, zi, xj, yj, zj = X[i], Y[i], Z[i], X[j], Y[j], Z[j]
            lim = thresh + ssr[i] + ssr[j]
            if lim <= 0.0:  # a distance is never negative
                continue
            for b in range(B):
                dx, dy, dz = xi[b] - xj[b], yi[b] - yj[b], zi[b] - zj[b]
                D[b] = dx * dx + dy * dy + dz * dz
            if _lane_min(D, B) < lim * lim:
                out[0], out[1], out[2] = 1, i, j
                return _first_below(D, B, lim * lim)
    return -1


@njit(cache=True, fastmath=FM)
def batch_clearance(B, W, P, S, cap, best):  # pragma: no cover - compiled
    """Each lane's smallest distance over obstacles and self-collision pairs, capped at ``cap``: ``best[:B]``.

    The value per lane is ``config_clearance``'s (spheres fixed to the base are not checked
    against the obstacles). A group is looked into for an obstacle (a group pair for self-collision)
    only when its bounding sphere is closer than some lane's current best.
    """
    batch_centres(B, W, S)
    X, Y, Z, GX, GY, GZ, L = S[2], S[3], S[4], S[5], S[6], S[7], S[8]
    D, E = L[2], L[3]
    gj, sr, gr, gs, types, params, cd = W[8], W[7], W[10], W[11], W[12], W[13], W[19]
    for b in range(B):
        best[b] = cap
    for k in range(gj.shape[0]):
        if gj[k] == 0:
            continue
        for o in range(types.shape[0]):
            _dist(types[o], params[o], GX, GY, GZ, k, B, D)
            need = False
            for b in range(B):
                need |= D[b] - gr[k] < best[b]
            if not need:
                continue
            for i in range(gs[k], gs[k + 1]):
                _dist(types[o], params[o], X, Y, Z, i, B, D)
                ri = sr[i]
                for b in range(B):
                    best[b] = min(best[b], D[b] - ri)
        if cd[0] > 0:
            for b in range(B):
                if _aabb_dist(GX[k, b], GY[k, b], GZ[k, b], W) - gr[k] >= best[b]:
                    continue
                for i in range(gs[k], gs[k + 1]):
                    d = _cloud_min(X[i, b], Y[i, b], Z[i, b], best[b] + sr[i], W) - sr[i]
                    best[b] = min(best[b], d)
    gpairs, ssr, sgr = W[14], W[21], W[22]
    start, pi, pj = P
    for p in range(gpairs.shape[0]):
        a, c = gpairs[p, 0], gpairs[p, 1]
        ax, ay, az, cx, cy, cz = GX[a], GY[a], GZ[a], GX[c], GY[c], GZ[c]
        rr = sgr[a] + sgr[c]
        need = False
        for b in range(B):
            dx, dy, dz = ax[b] - cx[b], ay[b] - cy[b], az[b] - cz[b]
            need |= math.sqrt(dx * dx + dy * dy + dz * dz) - rr < best[b]
        if not need:
            continue
        for s in range(start[p], start[p + 1]):
            i, j = pi[s], pj[s]
            xi, yi, zi, xj, yj, zj = X[i], Y[i], Z[i], X[j], Y[j], Z[j]
            rr = ssr[i] + ssr[j]
            for b in range(B):
                dx, dy, dz = xi[b] - xj[b], yi[b] - yj[b], zi[b] - zj[b]
                best[b] = min(best[b], math.sqrt(dx * dx + dy * dy + dz * dz) - rr)
    for b in range(B):
        E[b] = best[b]
