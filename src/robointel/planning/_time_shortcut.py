"""Compiled (numba) shortcuts in the motion's own metric: time length and corners.

Under time-optimal timing with velocity limits ``vmax`` and acceleration limits ``amax`` a joint-space
polyline takes about its *time length* (sum over its segments of max_k |dq_k| / vmax_k; weights
``w = 1 / vmax``) plus a cost per corner. :func:`shortcut_time` shortens a path in that estimate
(:func:`chain_time`):

- points are drawn uniformly on the time length (where the motion's time is), anywhere on segments;
- a *full* shortcut joins the two points straight;
- a *partial* shortcut (Geraerts & Overmars 2007) moves one joint only onto the straight line
  between them (linear in the time-length parameter), the other joints keeping their motion: the
  joint that saves the most time length;
- a candidate is checked only when it lowers the estimate; the corners left are then cut toward
  their neighbours' midpoint (where the estimate says that saves time).

Every new edge is checked in batches of points (>= thresh - res / 2 on the edge, its end >= thresh;
:func:`~robointel.planning._batch_edges.edge_batch`), edges from the first or to the last vertex by
:func:`~robointel.planning._batch_edges.root_edge_batch` (relaxed world within ``rcap`` of that
vertex), so every edge of the result keeps that guarantee. ``BS`` is the environment's batch state
(:func:`~robointel.planning._batch_edges.batch_state`).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from robointel.planning._batch_edges import edge_batch, root_edge_batch
from robointel.planning._batch_kernels import LANES, batch_free
from robointel.planning._shortcut_kernels import PULL_FRACTIONS

#: share of the random tries that are partial (one-joint) shortcuts
PARTIAL_SHARE = 0.5
#: corner cost in :func:`chain_time`: this x the largest velocity change / acceleration limit, s
CORNER_WEIGHT = 0.5
#: a corner is cut only when the estimate says it saves at least this, s
TIGHTEN_GATE_S = 0.01


@njit(cache=True)
def seg_time(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> float:  # pragma: no cover - compiled
    """Time length max_k w_k |b_k - a_k| of the straight motion a -> b, s."""
    t = 0.0
    for k in range(a.shape[0]):
        t = max(t, w[k] * abs(b[k] - a[k]))
    return t


@njit(cache=True)
def time_length(P: np.ndarray, npts: int, w: np.ndarray, L: np.ndarray) -> float:  # pragma: no cover - compiled
    """Cumulative time length L[:npts] of the polyline P[:npts] (L[0] = 0); returns the total, s."""
    L[0] = 0.0
    for i in range(1, npts):
        L[i] = L[i - 1] + seg_time(P[i - 1], P[i], w)
    return L[npts - 1]


@njit(cache=True)
def _locate(P: np.ndarray, L: np.ndarray, npts: int, u: float, q: np.ndarray) -> int:  # pragma: no cover
    """Segment s (0 <= s <= npts - 2) holding time-length parameter ``u``; q = the point there."""
    s = int(np.searchsorted(L[:npts], u, side="right")) - 1
    s = min(max(s, 0), npts - 2)
    f = (u - L[s]) / max(L[s + 1] - L[s], 1e-12)
    f = min(max(f, 0.0), 1.0)
    for k in range(P.shape[1]):
        q[k] = P[s, k] + f * (P[s + 1, k] - P[s, k])
    return s


@njit(cache=True)
def _partial(P: np.ndarray, L: np.ndarray, s1: int, s2: int, u1: float, u2: float, qa: np.ndarray,
             qb: np.ndarray, w: np.ndarray, V: np.ndarray) -> float:  # pragma: no cover - compiled
    """Best one-joint partial shortcut between qa (u1, on segment s1) and qb (u2, on segment s2 > s1).

    Fills V[0] = qa, V[1:s2 - s1 + 1] = the vertices P[s1 + 1 .. s2] with the best joint moved onto
    the line qa_k -> qb_k (linear in the time-length parameter), V[s2 - s1 + 1] = qb. Returns the
    time length saved (<= 0: no joint saves any).
    """
    n = P.shape[1]
    c = s2 - s1  # inner vertices
    old = seg_time(qa, P[s1 + 1], w) + seg_time(P[s2], qb, w)
    for i in range(s1 + 1, s2):
        old += seg_time(P[i], P[i + 1], w)
    span = max(u2 - u1, 1e-12)
    best, bk = 0.0, -1
    for j in range(n):
        new = 0.0
        prev_j = qa[j]
        for r in range(c + 1):  # segment r: (qa | P[s1 + r]) -> (P[s1 + 1 + r] | qb), joint j replaced
            a = qa if r == 0 else P[s1 + r]
            b = qb if r == c else P[s1 + 1 + r]
            bj = qb[j] if r == c else qa[j] + (L[s1 + 1 + r] - u1) / span * (qb[j] - qa[j])
            t = w[j] * abs(bj - prev_j)
            for k in range(n):
                if k != j:
                    t = max(t, w[k] * abs(b[k] - a[k]))
            new += t
            prev_j = bj
        if old - new > best:
            best, bk = old - new, j
    if bk < 0:
        return 0.0
    for k in range(n):
        V[0, k] = qa[k]
        V[c + 1, k] = qb[k]
    for r in range(1, c + 1):
        for k in range(n):
            V[r, k] = P[s1 + r, k]
        V[r, bk] = qa[bk] + (L[s1 + r] - u1) / span * (qb[bk] - qa[bk])
    return best


@njit(cache=True)
def chain_time(A: np.ndarray, na: int, w: np.ndarray, ia: np.ndarray, corner: float) -> float:  # pragma: no cover
    """Estimated motion time of the chain A[:na], s.

    Its time length plus, at each inner point, ``corner`` x max_k |v_out,k - v_in,k| / amax_k, where
    a segment's velocity is its dq over its time length (the limiting joint at its limit) and
    ``ia`` = 1 / amax: the velocity change a corner forces, over the acceleration that makes it.
    """
    n = A.shape[1]
    tot = 0.0
    tp = 0.0
    for i in range(1, na):
        t = seg_time(A[i - 1], A[i], w)
        tot += t
        if i >= 2 and corner > 0.0 and t > 1e-12 and tp > 1e-12:
            c = 0.0
            for k in range(n):
                dv = (A[i, k] - A[i - 1, k]) / t - (A[i - 1, k] - A[i - 2, k]) / tp
                c = max(c, abs(dv) * ia[k])
            tot += corner * c
        if t > 1e-12:
            tp = t
    return tot


@njit(cache=True)
def _splice(P: np.ndarray, npts: int, Q: np.ndarray, s1: int, s2: int, V: np.ndarray,
            nv: int) -> int:  # pragma: no cover - compiled
    """P[:s1 + 1], V[:nv], P[s2 + 1:npts] into P (through Q); returns the new vertex count."""
    m = 0
    for r in range(s1 + 1):
        Q[m] = P[r]
        m += 1
    for r in range(nv):
        Q[m] = V[r]
        m += 1
    for r in range(s2 + 1, npts):
        Q[m] = P[r]
        m += 1
    for r in range(m):
        P[r] = Q[r]
    return m


@njit(cache=True)
def _faster(P: np.ndarray, npts: int, s1: int, s2: int, qa: np.ndarray, qb: np.ndarray, V: np.ndarray, nv: int,
            A: np.ndarray, w: np.ndarray, ia: np.ndarray) -> bool:  # pragma: no cover - compiled
    """Whether the replacement V[:nv] of the stretch qa -> qb lowers :func:`chain_time`.

    Compares P[s1], V[:nv], P[s2 + 1] with P[s1], qa, P[s1 + 1 .. s2], qb, P[s2 + 1] (qa on segment
    s1, qb on segment s2), one more vertex each side for the corners there.
    """
    lo = max(s1 - 1, 0)
    hi = min(s2 + 2, npts - 1)
    m = 0
    for r in range(lo, s1 + 1):
        A[m] = P[r]
        m += 1
    A[m] = qa
    m += 1
    for r in range(s1 + 1, s2 + 1):
        A[m] = P[r]
        m += 1
    A[m] = qb
    m += 1
    for r in range(s2 + 1, hi + 1):
        A[m] = P[r]
        m += 1
    old = chain_time(A, m, w, ia, CORNER_WEIGHT)
    m = 0
    for r in range(lo, s1 + 1):
        A[m] = P[r]
        m += 1
    for r in range(nv):
        A[m] = V[r]
        m += 1
    for r in range(s2 + 1, hi + 1):
        A[m] = P[r]
        m += 1
    return chain_time(A, m, w, ia, CORNER_WEIGHT) < old - 1e-9


@njit(cache=True)
def greedy(P: np.ndarray, npts: int, Q: np.ndarray, W: tuple, Wr: tuple, rcap: float, BS: tuple, out: np.ndarray,
           thresh: float, lever: np.ndarray,
           res: float) -> int:  # pragma: no cover - compiled
    """Each vertex joined to the farthest later vertex it sees (root edges as ``root_edge_batch``)."""
    Q[0] = P[0]
    m = 1
    i = 0
    while i < npts - 1:
        j = npts - 1
        while j > i + 1 and not root_edge_batch(P[i], P[j], Wr, W, i == 0, j == npts - 1, rcap, BS, thresh,
                                               res, out):
            j -= 1
        Q[m] = P[j]
        m += 1
        i = j
    for r in range(m):
        P[r] = Q[r]
    return m


@njit(cache=True)
def tighten_time(P: np.ndarray, npts: int, W: tuple, Wr: tuple, rcap: float, BS: tuple, out: np.ndarray,
                 thresh: float, lever: np.ndarray, res: float, w: np.ndarray,
                 ia: np.ndarray) -> int:  # pragma: no cover - compiled
    """One pass over the inner vertices of P[:npts], each corner cut toward its neighbours' midpoint.

    Each vertex moves the largest fraction of
    :data:`~robointel.planning._shortcut_kernels.PULL_FRACTIONS` of the way to m = (P[i-1] + P[i+1]) / 2
    whose two new edges pass the check, but it is tried only when moving it to m lowers the
    :func:`chain_time` of the five points around it by >= :data:`TIGHTEN_GATE_S`. No move lengthens
    the path in any norm. Returns the number of vertices moved.
    """
    n = P.shape[1]
    q = np.empty(n)
    A = np.empty((5, n))
    moved = 0
    for i in range(1, npts - 1):
        lo, hi = max(i - 2, 0), min(i + 2, npts - 1)
        for r in range(lo, hi + 1):
            A[r - lo] = P[r]
        before = chain_time(A, hi - lo + 1, w, ia, CORNER_WEIGHT)
        for k in range(n):
            A[i - lo, k] = 0.5 * (P[i - 1, k] + P[i + 1, k])
        if before - chain_time(A, hi - lo + 1, w, ia, CORNER_WEIGHT) < TIGHTEN_GATE_S:
            continue
        for f in PULL_FRACTIONS:
            for k in range(n):
                q[k] = P[i, k] + f * (0.5 * (P[i - 1, k] + P[i + 1, k]) - P[i, k])
            if (root_edge_batch(P[i - 1], q, Wr, W, i == 1, False, rcap, BS, thresh, res, out)
                    and root_edge_batch(q, P[i + 1], Wr, W, False, i + 1 == npts - 1, rcap, BS, thresh,
                                       res, out)):
                for k in range(n):
                    P[i, k] = q[k]
                moved += 1
                break
    return moved


@njit(cache=True)
def _checked(V: np.ndarray, nv: int, W: tuple, BS: tuple, out: np.ndarray, thresh: float, lever: np.ndarray,
             res: float) -> bool:  # pragma: no cover - compiled
    """Whether the chain V[:nv] passes: V[1:nv] >= thresh (cheap, first, in batches), then every edge in batches."""
    Qt = BS[1][0]
    for r0 in range(1, nv, LANES):
        B = min(LANES, nv - r0)
        for b in range(B):
            for k in range(V.shape[1]):
                Qt[k, b] = V[r0 + b, k]
        if batch_free(B, W, BS[0], BS[1], thresh, out) >= 0:
            return False
    for r in range(nv - 1):
        if not edge_batch(V[r], V[r + 1], W, BS, thresh, res, out):
            return False
    return True


@njit(cache=True)
def shortcut_time(P: np.ndarray, npts: int, iters: int, W: tuple, Wr: tuple, rcap: float, BS: tuple,
                  out: np.ndarray, thresh: float, lever: np.ndarray, res: float,
                  w: np.ndarray, ia: np.ndarray) -> int:  # pragma: no cover - compiled
    """Shorten P[:npts] in place in estimated motion time; returns the new vertex count.

    The greedy pass (:func:`greedy`), then ``iters`` random tries between two points drawn
    uniformly on the time length (numba's random stream; a share :data:`PARTIAL_SHARE` partial, the
    rest full), each checked only when it lowers :func:`chain_time`, then one
    :func:`tighten_time` pass. ``w`` (n,) = 1 / vmax, s/rad; ``ia`` (n,) = 1 / amax, s^2/rad. Edges
    from the first or to the last vertex are checked in world ``Wr`` within ``rcap`` rad of that vertex
    and in ``W`` beyond, all others in ``W``, at resolution ``res`` (m of sphere travel) against
    clearance ``thresh`` (m). P's rows are its capacity: a try that would not fit is skipped.
    """
    n = P.shape[1]
    cap = P.shape[0]
    Q = np.empty_like(P)
    V = np.empty_like(P)
    A = np.empty((cap + 4, n))
    npts = greedy(P, npts, Q, W, Wr, rcap, BS, out, thresh, lever, res)
    L = np.empty(cap)
    qa = np.empty(n)
    qb = np.empty(n)
    for _ in range(iters):
        if npts < 3:
            break
        tot = time_length(P, npts, w, L)
        u1 = np.random.uniform(0.0, tot)
        u2 = np.random.uniform(0.0, tot)
        partial = np.random.uniform(0.0, 1.0) < PARTIAL_SHARE
        if u1 > u2:
            u1, u2 = u2, u1
        s1 = _locate(P, L, npts, u1, qa)
        s2 = _locate(P, L, npts, u2, qb)
        if s1 == s2 or npts + 2 > cap:
            continue
        if partial:
            if _partial(P, L, s1, s2, u1, u2, qa, qb, w, V) <= 1e-9:
                continue
            nv = s2 - s1 + 2
        else:
            V[0] = qa
            V[1] = qb
            nv = 2
        if _faster(P, npts, s1, s2, qa, qb, V, nv, A, w, ia) and _checked(V, nv, W, BS, out, thresh, lever, res):
            npts = _splice(P, npts, Q, s1, s2, V, nv)
    if npts >= 3:
        tighten_time(P, npts, W, Wr, rcap, BS, out, thresh, lever, res, w, ia)
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
