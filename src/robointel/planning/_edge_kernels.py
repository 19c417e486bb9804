"""Compiled (numba) edge checks of the motion planner: conservative advancement along a straight motion.

A checked point with clearance c proves every point within sphere-centre travel c - thresh + res / 2
of it >= thresh - res / 2; obstacles bound the travel of each sphere, self-collision pairs the
relative travel of their two links (``W[23]``, see :mod:`robointel.planning._collision_kernels`
for the packed world ``W``). :func:`edge_valid` walks from q0; :func:`edge_valid_bisect` checks
coarse to fine (the middle of every stretch not yet proven, breadth first).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from robointel.geometry._kernels import _one
from robointel.planning._collision_kernels import (
    CLOUD,
    ENV,
    FM,
    SELF,
    _aabb_dist,
    _cloud_min,
    config_valid,
    sphere_centres,
    travel,
)


@njit(cache=True, fastmath=FM)
def _self_advance(C, G, W, thresh, res, dq, out, best, rate, floor):  # pragma: no cover - compiled
    """Largest path-parameter advance allowed by the self-collision pairs, at most ``best``.

    Each sphere pair (i, j) limits it by its distance over its relative travel
    ``rate[i, joint of j] + rate[j, joint of i]`` (``rate`` (m, nj): ``W[23]`` times |dq|), never
    below ``floor`` of relative travel; -1 when a pair is below ``thresh``. A group pair whose
    bounding spheres alone allow an advance of ``best`` (the obstacles' limit) under its relative
    lever ``W[20]`` is not looked into.
    """
    sr, gr, gs, gpairs, smask, rel, gj = W[21], W[22], W[11], W[14], W[15], W[20], W[8]
    for p in range(gpairs.shape[0]):
        L = 0.0
        for k in range(dq.shape[0]):
            L += rel[p, k] * dq[k]
        a, b = gpairs[p, 0], gpairs[p, 1]
        dx, dy, dz = G[a, 0] - G[b, 0], G[a, 1] - G[b, 1], G[a, 2] - G[b, 2]
        db = math.sqrt(dx * dx + dy * dy + dz * dz) - gr[a] - gr[b]
        lim = thresh + 0.5 * res + best * L  # pair distances above this do not limit the advance
        if db >= lim:
            continue
        ja, jb = gj[a], gj[b]
        bx, by, bz, rb = G[b, 0], G[b, 1], G[b, 2], gr[b]
        Rb = 0.0  # the largest travel of b's spheres relative to a's joint
        for j in range(gs[b], gs[b + 1]):
            Rb = max(Rb, rate[j, ja])
        for i in range(gs[a], gs[a + 1]):
            # sphere i against b's bounding sphere (it holds each of b's spheres): a lower bound of its
            # pairs' distances, their relative travel at most rate[i, jb] + Rb
            xi, yi, zi = C[i, 0], C[i, 1], C[i, 2]
            dx, dy, dz = xi - bx, yi - by, zi - bz
            di = math.sqrt(dx * dx + dy * dy + dz * dz) - sr[i] - rb
            if di >= thresh and max(di - thresh + 0.5 * res, floor) >= best * (rate[i, jb] + Rb):
                continue
            for j in range(gs[b], gs[b + 1]):
                if smask[i, j] == 0:
                    continue
                dx, dy, dz = xi - C[j, 0], yi - C[j, 1], zi - C[j, 2]
                d = math.sqrt(dx * dx + dy * dy + dz * dz) - sr[i] - sr[j]
                if d < thresh:
                    out[0], out[1], out[2] = SELF, i, j
                    return -1.0
                Lij = rate[i, jb] + rate[j, ja]
                if Lij > 0.0:
                    best = min(best, max(d - thresh + 0.5 * res, floor) / Lij)
    return best


@njit(cache=True, fastmath=FM)
def _env_advance(C, G, W, thresh, res, rate, out, cap, floor):  # pragma: no cover - compiled
    """Largest path-parameter advance allowed by the obstacles; -1 when a sphere is below ``thresh``.

    Sphere i limits it by its clearance (capped at ``cap``) less ``thresh - res / 2``, never below
    ``floor``, over its travel ``rate[i, 0]`` (m per unit of the parameter); a group whose bounding
    sphere cannot limit it below the current best is not looked into. Spheres fixed to the base are
    not checked (as in :func:`full_clearance`).
    """
    sr, gr, gs, types, params, cd, gj = W[7], W[10], W[11], W[12], W[13], W[19], W[8]
    half = 0.5 * res
    Lmax = 0.0
    for i in range(rate.shape[0]):
        Lmax = max(Lmax, rate[i, 0])
    if Lmax <= 0.0:
        Lmax = 1.0
    best = (cap - thresh + half) / Lmax  # clearances are capped at cap: no sphere limits below this
    for k in range(gr.shape[0]):
        if gj[k] == 0:
            continue
        Rg = 0.0
        for i in range(gs[k], gs[k + 1]):
            Rg = max(Rg, rate[i, 0])
        gx, gy, gz = G[k, 0], G[k, 1], G[k, 2]
        for o in range(types.shape[0]):
            db = _one(types[o], params[o], gx, gy, gz)[0] - gr[k]
            if db >= thresh and min(db, cap) - thresh + half >= best * Rg:
                continue
            for i in range(gs[k], gs[k + 1]):
                d = _one(types[o], params[o], C[i, 0], C[i, 1], C[i, 2])[0] - sr[i]
                if d < thresh:
                    out[0], out[1], out[2] = ENV, i, o
                    return -1.0
                if rate[i, 0] > 0.0:
                    best = min(best, max(min(d, cap) - thresh + half, floor) / rate[i, 0])
        if cd[0] > 0 and _aabb_dist(gx, gy, gz, W) - gr[k] < max(thresh - half + best * Rg, thresh):
            for i in range(gs[k], gs[k + 1]):
                reach = min(cap, max(thresh - half + best * rate[i, 0], thresh))
                d = _cloud_min(C[i, 0], C[i, 1], C[i, 2], reach + sr[i], W) - sr[i]
                if d < thresh:
                    out[0], out[1], out[2] = CLOUD, i, 0
                    return -1.0
                if rate[i, 0] > 0.0:
                    best = min(best, max(min(d, cap) - thresh + half, floor) / rate[i, 0])
    return best


@njit(cache=True)
def _rates(dq, W, rate):  # pragma: no cover - compiled
    """rate[i, J] = sum_k W[23][i, J, k] dq_k: the relative speed bounds of the spheres on an edge."""
    slev = W[23]
    for i in range(slev.shape[0]):
        for J in range(slev.shape[1]):
            v = 0.0
            for k in range(dq.shape[0]):
                v += slev[i, J, k] * dq[k]
            rate[i, J] = v


@njit(cache=True)
def _cover(q0, q1, f, W, T, C, G, out, thresh, res, dq, rate, cap, q):  # pragma: no cover - compiled
    """Half-width (path parameter) of the stretch around q0 + f (q1 - q0) proven >= thresh - res / 2.

    The point's clearance less ``thresh - res / 2`` over the travel of each sphere (obstacles) and
    each self-collision sphere pair (relative travel), at least ``res / 2`` of travel; -1 when the
    point itself is below ``thresh``.
    """
    for k in range(q0.shape[0]):
        q[k] = q0[k] + f * (q1[k] - q0[k])
    sphere_centres(q, W, T, C, G)
    r = _env_advance(C, G, W, thresh, res, rate, out, cap, 0.5 * res)
    if r >= 0.0 and W[14].shape[0] > 0:
        r = _self_advance(C, G, W, thresh, res, dq, out, r, rate, 0.5 * res)
    return r


@njit(cache=True)
def edge_valid(q0, q1, W, T, C, G, out, thresh, lever, res):  # pragma: no cover - compiled
    """Check the straight joint-space motion q0 -> q1 (q1 excluded) by conservative advancement.

    From a point with clearance c, every point within sphere-centre travel c - thresh + res / 2 keeps
    clearance >= thresh - res / 2, so the next check is that far along (at least ``res`` of travel).
    Obstacles bound the travel of each sphere, self-collision pairs the relative travel of their
    two links.
    """
    n = q0.shape[0]
    dq = np.empty(n)
    for k in range(n):
        dq[k] = abs(q1[k] - q0[k])
    L = travel(q0, q1, lever)
    if L <= 0.0:
        return True
    q = np.empty(n)
    f = 0.0
    cap = thresh + 0.25
    gp = W[14]
    rate = np.empty((W[23].shape[0], W[23].shape[1]))
    _rates(dq, W, rate)
    while f < 1.0:
        for k in range(n):
            q[k] = q0[k] + f * (q1[k] - q0[k])
        sphere_centres(q, W, T, C, G)
        step = _env_advance(C, G, W, thresh, res, rate, out, cap, res)
        if step < 0.0:
            return False
        if gp.shape[0] > 0:
            step = _self_advance(C, G, W, thresh, res, dq, out, step, rate, res)
            if step < 0.0:
                return False
        f += step
    return True


@njit(cache=True)
def edge_valid_bisect(q0, q1, W, T, C, G, out, thresh, lever, res):  # pragma: no cover - compiled
    """:func:`edge_valid`'s verdict guarantee, the edge walked coarse to fine.

    A point with clearance c proves every point within sphere-centre travel c - thresh + res / 2
    of it >= thresh - res / 2 (obstacles bound the travel of each sphere, self-collision pairs the
    relative travel of their two links; at least res / 2 of travel). The edge is walked coarse to
    fine: q0, then the middle of every stretch not yet proven, breadth first, so a collision
    anywhere on the edge is met after a few checks; a free edge costs more checks than the walk
    of :func:`edge_valid`, and so does a collision near q0. q1 is the caller's to check (>= thresh, it
    proves res / 2 of travel around itself).
    """
    n = q0.shape[0]
    dq = np.empty(n)
    for k in range(n):
        dq[k] = abs(q1[k] - q0[k])
    if travel(q0, q1, lever) <= 0.0:
        return True
    q = np.empty(n)
    cap = thresh + 0.25
    rate = np.empty((W[23].shape[0], W[23].shape[1]))
    _rates(dq, W, rate)
    rm = 0.0
    for i in range(rate.shape[0]):
        for J in range(rate.shape[1]):
            rm = max(rm, rate[i, J])
    if rm <= 0.0:  # nothing moves relative to anything
        return True
    r = _cover(q0, q1, 0.0, W, T, C, G, out, thresh, res, dq, rate, cap, q)
    if r < 0.0:
        return False
    hi = 1.0 - 0.25 * res / rm  # q1 proves res / 2 of (relative) travel, <= 2 rm per unit
    if r >= hi:
        return True
    # every checked point lies outside the stretches proven before it (each >= res / (4 rm)): at
    # most 4 rm / res + 1 checks, and never more stretches pending than checks
    m = int(4.0 * rm / res) + 16
    glo = np.empty(m)
    ghi = np.empty(m)
    glo[0], ghi[0] = r, hi
    head, size = 0, 1
    while size > 0:
        a, b = glo[head], ghi[head]
        head = (head + 1) % m
        size -= 1
        f = 0.5 * (a + b)
        r = _cover(q0, q1, f, W, T, C, G, out, thresh, res, dq, rate, cap, q)
        if r < 0.0 or size + 2 > m:  # (a full queue cannot happen by the bound above; refuse if it did)
            return False
        if f - r > a:
            t = (head + size) % m
            glo[t], ghi[t] = a, f - r
            size += 1
        if f + r < b:
            t = (head + size) % m
            glo[t], ghi[t] = f + r, b
            size += 1
    return True


@njit(cache=True)
def edge_two_pass(q0, q1, W, T, C, G, out, thresh, lever, res, coarse):  # pragma: no cover - compiled
    """:func:`edge_valid` at ``res``, after a coarse-to-fine pass at ``coarse`` (> res) that rejects faster.

    The coarse pass returns False only at a configuration below ``thresh``, so it never rejects a
    valid edge; an edge is accepted only by the walk at ``res``. ``coarse <= res``: the walk alone.
    """
    if coarse > res and not edge_valid_bisect(q0, q1, W, T, C, G, out, thresh, lever, coarse):
        return False
    return edge_valid(q0, q1, W, T, C, G, out, thresh, lever, res)


@njit(cache=True)
def root_split(q0: np.ndarray, q1: np.ndarray, root0: bool, root1: bool,
               rcap: float) -> tuple[float, float, float, np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Where a root edge q0 -> q1 leaves the relaxed world: (L, a, b, qa, qb).

    L is the edge's max |dq|; [0, a] lies within ``rcap`` rad of q0 (a = 0 unless ``root0``),
    [b, 1] within ``rcap`` of q1 (b = 1 unless ``root1``); qa, qb are the points at a and b.
    a >= b: every point is within ``rcap`` of a root. Shared by :func:`root_edge` and the
    shortcut's ``root_edge_fine``.
    """
    n = q0.shape[0]
    L = 0.0
    for k in range(n):
        L = max(L, abs(q1[k] - q0[k]))
    f = rcap / L if L > 0.0 else np.inf
    a = min(f, 1.0) if root0 else 0.0  # [0, a] relaxed
    b = max(1.0 - f, 0.0) if root1 else 1.0  # [b, 1] relaxed
    qa = np.empty(n)
    qb = np.empty(n)
    for k in range(n):
        qa[k] = q0[k] + a * (q1[k] - q0[k])
        qb[k] = q0[k] + b * (q1[k] - q0[k])
    return L, a, b, qa, qb


@njit(cache=True)
def root_edge(q0, q1, Wr, W, root0, root1, rcap, T, C, G, out, thresh, lever, res, coarse):  # pragma: no cover
    """Check q0 -> q1 (q1 excluded, as :func:`edge_valid`) with the relaxed world ``Wr`` only near a root.

    A root (q0 when ``root0``, q1 when ``root1``: a start or goal that may be valid only in ``Wr``)
    relaxes the check for the first ``rcap`` rad (max |dq|) from it; the split point and the rest of
    the edge are checked in ``W`` (each stretch with :func:`edge_two_pass`, so the walk's guarantee
    holds per stretch: >= thresh - res / 2 in its world). An edge within ``rcap`` of a root at every
    point is checked in ``Wr`` alone; ``rcap`` = inf checks every root edge in ``Wr`` whole.
    """
    if not root0 and not root1:
        return edge_two_pass(q0, q1, W, T, C, G, out, thresh, lever, res, coarse)
    L, a, b, qa, qb = root_split(q0, q1, root0, root1, rcap)
    if L <= 0.0:
        return True
    if a >= b:  # every point within rcap of a root
        return edge_two_pass(q0, q1, Wr, T, C, G, out, thresh, lever, res, coarse)
    if root0 and not edge_two_pass(q0, qa, Wr, T, C, G, out, thresh, lever, res, coarse):
        return False
    # the middle in W: its walk checks qa first; qb (its excluded end) is checked on its own
    if not edge_two_pass(qa, qb, W, T, C, G, out, thresh, lever, res, coarse):
        return False
    if root1:
        if not config_valid(qb, W, T, C, G, out, thresh):
            return False
        return edge_two_pass(qb, q1, Wr, T, C, G, out, thresh, lever, res, coarse)
    return True
