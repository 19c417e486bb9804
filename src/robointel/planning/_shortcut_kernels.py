"""Compiled (numba) path shortcutting of the motion planner, every edge checked coarse to fine in one pass.

A candidate edge is checked by :func:`~robointel.planning._edge_kernels.edge_valid_bisect` at the
fine resolution itself: the middle of every stretch not yet proven first, so a collision anywhere on
the edge is met after a few checks (as a rejecting pass at a coarser resolution would), while an
edge that passes is proven once (no second walk). The guarantee is that of
:func:`~robointel.planning._edge_kernels.edge_valid`: an accepted edge keeps clearance >= thresh -
res / 2 everywhere (its end is checked >= thresh too), a rejected one has a point below thresh.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from robointel.planning._collision_kernels import config_valid
from robointel.planning._edge_kernels import edge_valid_bisect, root_split


@njit(cache=True)
def _length(P: np.ndarray, npts: int, L: np.ndarray) -> None:  # pragma: no cover - compiled
    """Cumulative Euclidean length L[:npts] of the path P[:npts], rad."""
    L[0] = 0.0
    for i in range(1, npts):
        s = 0.0
        for k in range(P.shape[1]):
            e = P[i, k] - P[i - 1, k]
            s += e * e
        L[i] = L[i - 1] + math.sqrt(s)


@njit(cache=True)
def edge_fine(q0: np.ndarray, q1: np.ndarray, W: tuple, T: np.ndarray, C: np.ndarray, G: np.ndarray, out: np.ndarray,
              thresh: float, lever: np.ndarray, res: float) -> bool:  # pragma: no cover - compiled
    """The straight motion q0 -> q1 in world ``W``, q1 included, checked coarse to fine at ``res``.

    True when q1 keeps ``thresh`` and every point of the edge keeps thresh - res / 2 (a point
    with clearance c proves sphere travel c - thresh + res / 2 around itself).
    """
    if not config_valid(q1, W, T, C, G, out, thresh):
        return False
    return edge_valid_bisect(q0, q1, W, T, C, G, out, thresh, lever, res)


@njit(cache=True)
def root_edge_fine(q0: np.ndarray, q1: np.ndarray, Wr: tuple, W: tuple, root0: bool, root1: bool, rcap: float,
                   T: np.ndarray, C: np.ndarray, G: np.ndarray, out: np.ndarray, thresh: float, lever: np.ndarray,
                   res: float) -> bool:  # pragma: no cover - compiled
    """:func:`~robointel.planning._edge_kernels.root_edge` with every stretch checked by :func:`edge_fine`.

    Within ``rcap`` rad (max |dq|) of a root (q0 when ``root0``, q1 when ``root1``) the edge is
    checked in the relaxed world ``Wr``, the rest (and the split points) in ``W``.
    """
    if not root0 and not root1:
        return edge_fine(q0, q1, W, T, C, G, out, thresh, lever, res)
    L, a, b, qa, qb = root_split(q0, q1, root0, root1, rcap)
    if L <= 0.0:
        return True
    if a >= b:  # every point within rcap of a root
        return edge_fine(q0, q1, Wr, T, C, G, out, thresh, lever, res)
    if root0 and not edge_fine(q0, qa, Wr, T, C, G, out, thresh, lever, res):
        return False
    if not edge_fine(qa, qb, W, T, C, G, out, thresh, lever, res):  # qb included, in W
        return False
    return not root1 or edge_fine(qb, q1, Wr, T, C, G, out, thresh, lever, res)


#: how far :func:`tighten` tries to move a vertex toward its neighbours' midpoint, largest first
PULL_FRACTIONS = (1.0, 0.5, 0.25, 0.125)


@njit(cache=True)
def tighten(P: np.ndarray, npts: int, W: tuple, Wr: tuple, rcap: float, T: np.ndarray, C: np.ndarray, G: np.ndarray,
            out: np.ndarray, thresh: float, lever: np.ndarray, res: float) -> int:  # pragma: no cover - compiled
    """One pass over the inner vertices of P[:npts], each moved toward the midpoint of its neighbours.

    Vertex i goes to P[i] + f (m - P[i]), m = (P[i-1] + P[i+1]) / 2, for the largest f of
    :data:`PULL_FRACTIONS` whose two new edges pass the check of the shortcut (:func:`root_edge_fine`
    from the first / to the last vertex, else :func:`edge_fine`); else it stays. The path length
    a -> q -> b is convex in q and smallest at m, so no move lengthens the path (in any norm: the
    motion time, ~ the max-joint length, falls with it). Returns the number of vertices moved.
    """
    n = P.shape[1]
    q = np.empty(n)
    moved = 0
    for i in range(1, npts - 1):
        for f in PULL_FRACTIONS:
            for k in range(n):
                q[k] = P[i, k] + f * (0.5 * (P[i - 1, k] + P[i + 1, k]) - P[i, k])
            if (root_edge_fine(P[i - 1], q, Wr, W, i == 1, False, rcap, T, C, G, out, thresh, lever, res)
                    and root_edge_fine(q, P[i + 1], Wr, W, False, i + 1 == npts - 1, rcap, T, C, G, out, thresh,
                                       lever, res)):
                for k in range(n):
                    P[i, k] = q[k]
                moved += 1
                break
    return moved


@njit(cache=True)
def shortcut(P: np.ndarray, npts: int, iters: int, W: tuple, Wr: tuple, rcap: float, T: np.ndarray, C: np.ndarray,
             G: np.ndarray, out: np.ndarray, thresh: float, lever: np.ndarray,
             res: float) -> int:  # pragma: no cover - compiled
    """Shorten the path P[:npts] in place; returns the new vertex count.

    A greedy pass (each vertex joined to the farthest one it sees), then ``iters`` random
    shortcuts between points anywhere on the path (numba's random stream), then one
    :func:`tighten` pass (corners cut toward the neighbours' midpoint). Edges from the first or
    to the last vertex are checked in world ``Wr`` within ``rcap`` rad of that vertex and in ``W``
    beyond (:func:`root_edge_fine`), all others in ``W`` (:func:`edge_fine`), at resolution ``res``.
    """
    n = P.shape[1]
    cap = P.shape[0]
    Q = np.empty_like(P)
    # greedy pass
    Q[0] = P[0]
    m = 1
    i = 0
    while i < npts - 1:
        j = npts - 1
        while j > i + 1 and not root_edge_fine(P[i], P[j], Wr, W, i == 0, j == npts - 1, rcap, T, C, G, out, thresh,
                                               lever, res):
            j -= 1
        Q[m] = P[j]
        m += 1
        i = j
    for r in range(m):
        P[r] = Q[r]
    npts = m
    L = np.empty(cap)
    qa = np.empty(n)
    qb = np.empty(n)
    for _ in range(iters):
        if npts < 3:
            break
        _length(P, npts, L)
        u1 = np.random.uniform(0.0, L[npts - 1])
        u2 = np.random.uniform(0.0, L[npts - 1])
        if u1 > u2:
            u1, u2 = u2, u1
        s1 = np.searchsorted(L[:npts], u1, side="right") - 1
        s2 = np.searchsorted(L[:npts], u2, side="right") - 1
        s1 = min(max(s1, 0), npts - 2)
        s2 = min(max(s2, 0), npts - 2)
        if s1 == s2 or npts + 1 > cap:
            continue
        f1 = (u1 - L[s1]) / max(L[s1 + 1] - L[s1], 1e-12)
        f2 = (u2 - L[s2]) / max(L[s2 + 1] - L[s2], 1e-12)
        for k in range(n):
            qa[k] = P[s1, k] + f1 * (P[s1 + 1, k] - P[s1, k])
            qb[k] = P[s2, k] + f2 * (P[s2 + 1, k] - P[s2, k])
        if not edge_fine(qa, qb, W, T, C, G, out, thresh, lever, res):
            continue
        m = 0
        for r in range(s1 + 1):
            Q[m] = P[r]
            m += 1
        Q[m] = qa
        Q[m + 1] = qb
        m += 2
        for r in range(s2 + 1, npts):
            Q[m] = P[r]
            m += 1
        for r in range(m):
            P[r] = Q[r]
        npts = m
    if npts >= 3:
        tighten(P, npts, W, Wr, rcap, T, C, G, out, thresh, lever, res)
    # drop vertices that are (almost) duplicates of their predecessor
    m = 1
    for r in range(1, npts):
        s = 0.0
        for k in range(n):
            e = P[r, k] - P[m - 1, k]
            s += e * e
        if s > 1e-16 or r == npts - 1:
            P[m] = P[r]
            m += 1
    return m
