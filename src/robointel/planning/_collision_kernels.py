"""Compiled (numba) collision kernels of the motion planner.

Chain kinematics, sphere clearance against primitives, a gridded point cloud and the robot
itself, and checks of sample sequences (the edge checks are in ``_edge_kernels``).

The world is one tuple ``W`` of arrays built by :class:`robointel.planning.environment.Environment`:

====  ==========  ====================================================================================
idx   name        content
====  ==========  ====================================================================================
0     parent      (nj,) parent joint of each joint (joint 0 is the fixed base)
1     place       (nj, 4, 4) joint placement in its parent joint frame
2     axis        (nj, 3) unit joint axis in its own frame
3     kind        (nj,) 0 revolute, 1 prismatic (unused for joint 0)
4     qidx        (nj,) configuration index of each joint (-1 for joint 0)
5     sj          (m,) joint each sphere moves with (spheres sorted by group)
6     sp          (m, 3) sphere centre in its joint frame, m
7     sr          (m,) sphere radius, m
8     gj          (g,) joint of each group (a rigid set of spheres)
9     gc          (g, 3) bounding-sphere centre of each group in its joint frame
10    gr          (g,) bounding-sphere radius
11    gs          (g + 1,) first sphere of each group (spheres gs[k]:gs[k+1])
12    types       (k,) primitive codes (robointel.geometry._kernels)
13    params      (k, NPARAM) primitive parameters
14    gpairs      (p, 2) group pairs that hold at least one self-collision sphere pair
15    smask       (m, m) uint8, 1 where a sphere pair is checked for self-collision
16    cpts        (N, 3) cloud points sorted by grid cell
17    cstart      (cells + 1,) first point of each cell
18    cgrid       (7,) origin xyz, cell size, point radius, and (unused) padding
19    cdims       (3,) cells per axis (0 0 0: no cloud)
20    rel         (p, n) relative lever of each group pair: m of relative travel per rad of joint k
21    ssr         (m,) sphere radii used for self-collision (7 and 10 are used against obstacles)
22    sgr         (g,) group bounding radii for self-collision
23    slev        (m, nj, n) speed bound of sphere i relative to joint J's body per rad/s of joint k
====  ==========  ====================================================================================
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from robointel.geometry._kernels import _one

ENV, SELF, CLOUD = 0, 1, 2
#: fast-math flags that keep inf/NaN semantics (the kernels compare against +-inf)
FM = {"nsz", "arcp", "contract", "reassoc"}


@njit(cache=True, fastmath=FM)
def chain_fk(q, W, T):  # pragma: no cover - compiled
    """Joint placements T (nj, 4, 4) in the world at configuration q (T[0] is left as given)."""
    parent, place, axis, kind, qidx = W[0], W[1], W[2], W[3], W[4]
    for j in range(1, parent.shape[0]):
        P = T[parent[j]]
        M = place[j]
        x = q[qidx[j]]
        ax, ay, az = axis[j, 0], axis[j, 1], axis[j, 2]
        rev = kind[j] == 0
        s, c1 = math.sin(x), 1.0 - math.cos(x)
        R00 = 1.0 - c1 * (ay * ay + az * az)
        R11 = 1.0 - c1 * (ax * ax + az * az)
        R22 = 1.0 - c1 * (ax * ax + ay * ay)
        R01, R10 = -s * az + c1 * ax * ay, s * az + c1 * ax * ay
        R02, R20 = s * ay + c1 * ax * az, -s * ay + c1 * ax * az
        R12, R21 = -s * ax + c1 * ay * az, s * ax + c1 * ay * az
        for r in range(3):
            p0, p1, p2 = P[r, 0], P[r, 1], P[r, 2]
            a0 = p0 * M[0, 0] + p1 * M[1, 0] + p2 * M[2, 0]
            a1 = p0 * M[0, 1] + p1 * M[1, 1] + p2 * M[2, 1]
            a2 = p0 * M[0, 2] + p1 * M[1, 2] + p2 * M[2, 2]
            a3 = p0 * M[0, 3] + p1 * M[1, 3] + p2 * M[2, 3] + P[r, 3]
            if rev:
                T[j, r, 0] = a0 * R00 + a1 * R10 + a2 * R20
                T[j, r, 1] = a0 * R01 + a1 * R11 + a2 * R21
                T[j, r, 2] = a0 * R02 + a1 * R12 + a2 * R22
                T[j, r, 3] = a3
            else:
                T[j, r, 0], T[j, r, 1], T[j, r, 2] = a0, a1, a2
                T[j, r, 3] = a3 + x * (a0 * ax + a1 * ay + a2 * az)
        T[j, 3, 0], T[j, 3, 1], T[j, 3, 2], T[j, 3, 3] = 0.0, 0.0, 0.0, 1.0


@njit(cache=True, fastmath=FM, inline="always")
def place_spheres(lo, hi, W, T, C):  # pragma: no cover - compiled
    """Sphere centres C[lo:hi] (m, 3) at the joint placements T."""
    sj, sp = W[5], W[6]
    for i in range(lo, hi):
        j = sj[i]
        x, y, z = sp[i, 0], sp[i, 1], sp[i, 2]
        for r in range(3):
            C[i, r] = T[j, r, 0] * x + T[j, r, 1] * y + T[j, r, 2] * z + T[j, r, 3]


@njit(cache=True, fastmath=FM, inline="always")
def group_centres(W, T, G):  # pragma: no cover - compiled
    """Group bounding-sphere centres G (g, 3) at the joint placements T."""
    gj, gc = W[8], W[9]
    for k in range(gj.shape[0]):
        j = gj[k]
        x, y, z = gc[k, 0], gc[k, 1], gc[k, 2]
        for r in range(3):
            G[k, r] = T[j, r, 0] * x + T[j, r, 1] * y + T[j, r, 2] * z + T[j, r, 3]


@njit(cache=True, fastmath=FM)
def sphere_centres(q, W, T, C, G):  # pragma: no cover - compiled
    """Fill T (joint placements), C (m, 3) sphere centres and G (g, 3) group centres at q."""
    chain_fk(q, W, T)
    place_spheres(0, W[5].shape[0], W, T, C)
    group_centres(W, T, G)


@njit(cache=True, fastmath=FM)
def _cloud_min(x, y, z, reach, W):  # pragma: no cover - compiled
    """Distance from (x, y, z) to the nearest cloud point within ``reach``.

    The point radius is subtracted; the result is, or ``reach`` when none is that close.
    """
    cpts, cstart, cg, cd = W[16], W[17], W[18], W[19]
    h, pr = cg[3], cg[4]
    rr = reach + pr
    lo0 = max(0, int(math.floor((x - rr - cg[0]) / h)))
    lo1 = max(0, int(math.floor((y - rr - cg[1]) / h)))
    lo2 = max(0, int(math.floor((z - rr - cg[2]) / h)))
    hi0 = min(cd[0] - 1, int(math.floor((x + rr - cg[0]) / h)))
    hi1 = min(cd[1] - 1, int(math.floor((y + rr - cg[1]) / h)))
    hi2 = min(cd[2] - 1, int(math.floor((z + rr - cg[2]) / h)))
    best2 = rr * rr
    for a in range(lo0, hi0 + 1):
        for b in range(lo1, hi1 + 1):
            base = (a * cd[1] + b) * cd[2]
            for c in range(lo2, hi2 + 1):
                cell = base + c
                for p in range(cstart[cell], cstart[cell + 1]):
                    dx, dy, dz = cpts[p, 0] - x, cpts[p, 1] - y, cpts[p, 2] - z
                    d2 = dx * dx + dy * dy + dz * dz
                    if d2 < best2:
                        best2 = d2
    return math.sqrt(best2) - pr


@njit(cache=True)
def _aabb_dist(x, y, z, W):  # pragma: no cover - compiled
    cg, cd = W[18], W[19]
    h = cg[3]
    d2 = 0.0
    for r in range(3):
        v = x if r == 0 else (y if r == 1 else z)
        lo = cg[r]
        hi = cg[r] + h * cd[r]
        e = lo - v if v < lo else (v - hi if v > hi else 0.0)
        d2 += e * e
    return math.sqrt(d2) - cg[4]


@njit(cache=True)
def clearance(C, G, W, cap, stop, out):  # pragma: no cover - compiled
    """:func:`full_clearance` over obstacles and self-collision pairs."""
    return full_clearance(C, G, W, cap, stop, out, np.bool_(True))  # typed bool: one compiled signature


@njit(cache=True)
def env_clearance(C, G, W, cap, stop, out):  # pragma: no cover - compiled
    """:func:`full_clearance` over obstacles only."""
    return full_clearance(C, G, W, cap, stop, out, np.bool_(False))


@njit(cache=True, fastmath=FM)
def full_clearance(C, G, W, cap, stop, out, with_self):  # pragma: no cover - compiled
    """Smallest signed distance, capped at ``cap``.

    Over the moving spheres vs primitives and cloud (spheres fixed to the base are not checked
    against the environment: the table or floor the
    robot stands on touches them in every configuration) and, ``with_self``, the self-collision
    sphere pairs; returns as soon as it is below ``stop``.

    out (4,) int64 receives (kind ENV/SELF/CLOUD or -1, sphere, obstacle or other sphere, 0).
    """
    sr, gr, gs, types, params = W[7], W[10], W[11], W[12], W[13]
    gpairs, smask, cd = W[14], W[15], W[19]
    best = cap
    out[0] = -1
    ng = gr.shape[0]
    gj = W[8]
    for k in range(ng):
        if gj[k] == 0:  # spheres fixed to the base: the mounting never changes along a motion
            continue
        gx, gy, gz, R = G[k, 0], G[k, 1], G[k, 2], gr[k]
        for o in range(types.shape[0]):
            db = _one(types[o], params[o], gx, gy, gz)[0] - R
            if db >= best:
                continue
            for i in range(gs[k], gs[k + 1]):
                d = _one(types[o], params[o], C[i, 0], C[i, 1], C[i, 2])[0] - sr[i]
                if d < best:
                    best = d
                    out[0], out[1], out[2] = ENV, i, o
                    if best < stop:
                        return best
        if cd[0] > 0 and _aabb_dist(gx, gy, gz, W) - R < best:
            for i in range(gs[k], gs[k + 1]):
                reach = best + sr[i]
                d = _cloud_min(C[i, 0], C[i, 1], C[i, 2], reach, W) - sr[i]
                if d < best:
                    best = d
                    out[0], out[1], out[2] = CLOUD, i, 0
                    if best < stop:
                        return best
    if not with_self:
        return best
    sr, gr = W[21], W[22]  # self-collision radii
    for p in range(gpairs.shape[0]):
        a, b = gpairs[p, 0], gpairs[p, 1]
        dx, dy, dz = G[a, 0] - G[b, 0], G[a, 1] - G[b, 1], G[a, 2] - G[b, 2]
        if math.sqrt(dx * dx + dy * dy + dz * dz) - gr[a] - gr[b] >= best:
            continue
        bx, by, bz, rb = G[b, 0], G[b, 1], G[b, 2], gr[b]
        for i in range(gs[a], gs[a + 1]):
            xi, yi, zi = C[i, 0], C[i, 1], C[i, 2]
            dx, dy, dz = xi - bx, yi - by, zi - bz  # b's bounding sphere holds each of its spheres
            if math.sqrt(dx * dx + dy * dy + dz * dz) - sr[i] - rb >= best:
                continue
            for j in range(gs[b], gs[b + 1]):
                if smask[i, j] == 0:
                    continue
                dx, dy, dz = xi - C[j, 0], yi - C[j, 1], zi - C[j, 2]
                d = math.sqrt(dx * dx + dy * dy + dz * dz) - sr[i] - sr[j]
                if d < best:
                    best = d
                    out[0], out[1], out[2] = SELF, i, j
                    if best < stop:
                        return best
    return best


class Scratch:
    """Work arrays of one world (placements, centres), allocated once."""

    def __init__(self, W: tuple) -> None:
        nj, m, g = W[0].shape[0], W[5].shape[0], W[8].shape[0]
        self.T = np.zeros((nj, 4, 4))
        self.T[0] = np.eye(4)
        self.C = np.empty((m, 3))
        self.G = np.empty((g, 3))
        self.out = np.zeros(4, np.int64)


@njit(cache=True)
def config_valid(q, W, T, C, G, out, thresh):  # pragma: no cover - compiled
    """True when every checked distance at q is >= thresh."""
    sphere_centres(q, W, T, C, G)
    return clearance(C, G, W, thresh, thresh, out) >= thresh


@njit(cache=True)
def config_clearance(q, W, T, C, G, out, cap):  # pragma: no cover - compiled
    """Smallest distance at q (capped at ``cap``), with its pair in ``out``."""
    sphere_centres(q, W, T, C, G)
    return clearance(C, G, W, cap, -np.inf, out)


@njit(cache=True)
def travel(q0, q1, lever):  # pragma: no cover - compiled
    """Upper bound of the distance any sphere centre moves on the straight motion q0 -> q1, m."""
    s = 0.0
    for k in range(q0.shape[0]):
        s += lever[k] * abs(q1[k] - q0[k])
    return s


@njit(cache=True)
def samples_clearance(Q, W, T, C, G, out, lever, floor, cap):  # pragma: no cover - compiled
    """Smallest clearance over the configurations Q (K, n), a sequence of nearby samples.

    Also returns the index of the worst evaluated sample.

    A sample whose clearance bound (clearance of the last evaluated sample minus the travel since)
    stays >= min(best so far, ``floor``) is skipped: it can lower neither a minimum below ``floor``
    nor the result below ``floor``, so the result is exact whenever it is below ``floor``.
    """
    best = cap
    worst = -1
    k = 0
    K = Q.shape[0]
    while k < K:
        sphere_centres(Q[k], W, T, C, G)
        c = clearance(C, G, W, cap, -np.inf, out)
        if c < best:
            best, worst = c, k
        j = k + 1
        tau = min(best, floor)
        moved = 0.0
        while j < K:
            moved += travel(Q[j - 1], Q[j], lever)
            if c - moved < tau:
                break
            j += 1
        k = j
    return best, worst


@njit(cache=True)
def samples_env_below(Q, W, T, C, G, out, lever, thresh):  # pragma: no cover - compiled
    """Mask (K,) of the nearby samples Q (K, n) whose obstacle clearance may be below ``thresh``.

    A sample is cleared (False) when its own obstacle clearance is >= ``thresh`` or when the
    clearance of the last evaluated sample minus the sphere travel since stays >= ``thresh``; only
    the others (True) need a finer check. Self-collision is not looked at.
    """
    K = Q.shape[0]
    mask = np.zeros(K, np.bool_)
    cap = thresh + 0.25
    k = 0
    while k < K:
        sphere_centres(Q[k], W, T, C, G)
        c = env_clearance(C, G, W, cap, -np.inf, out)
        j = k + 1
        if c < thresh:
            mask[k] = True
        else:
            moved = 0.0
            while j < K:
                moved += travel(Q[j - 1], Q[j], lever)
                if c - moved < thresh:
                    break
                j += 1
        k = j
    return mask


@njit(cache=True)
def cloud_bounds(P):  # pragma: no cover - compiled
    """Lower and upper corners (3,), (3,) of the points P (N, 3), N >= 1."""
    lo = P[0].copy()
    hi = P[0].copy()
    for i in range(1, P.shape[0]):
        for r in range(3):
            v = P[i, r]
            if v < lo[r]:
                lo[r] = v
            elif v > hi[r]:
                hi[r] = v
    return lo, hi


@njit(cache=True)
def bin_points(P, lo, h, dims, out, cstart):  # pragma: no cover - compiled
    """Counting sort of the points P (N, 3) into grid cells.

    Fills ``out`` (N, 3), the points sorted by cell, and ``cstart`` (cells + 1,), the first point
    of each cell.
    """
    N = P.shape[0]
    key = np.empty(N, np.int64)
    cstart[:] = 0
    for i in range(N):
        a = min(int((P[i, 0] - lo[0]) / h), dims[0] - 1)
        b = min(int((P[i, 1] - lo[1]) / h), dims[1] - 1)
        c = min(int((P[i, 2] - lo[2]) / h), dims[2] - 1)
        k = (a * dims[1] + b) * dims[2] + c
        key[i] = k
        cstart[k + 1] += 1
    for k in range(1, cstart.shape[0]):
        cstart[k] += cstart[k - 1]
    fill = cstart[:-1].copy()
    for i in range(N):
        k = key[i]
        j = fill[k]
        out[j, 0], out[j, 1], out[j, 2] = P[i, 0], P[i, 1], P[i, 2]
        fill[k] = j + 1
