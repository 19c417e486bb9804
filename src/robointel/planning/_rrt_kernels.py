"""Compiled (numba) RRT-Connect on the sphere collision kernels (the shortcut: ``_shortcut_kernels``).

Trees live in caller-owned arrays so that the search runs in chunks of iterations between which
the caller watches the clock: ``X`` (2, n, cap), the nodes joint by joint (the nearest-neighbour
scan reads them so, one joint of many nodes at a time, which the compiler vectorizes), ``parent``
(2, cap) and ``count`` (2,). Tree 0 grows from the start, tree 1 from every goal of the goal set
(each a root with parent -1). ``dom`` (2, cap) holds each node's dynamic domain (Yershova et al.,
ICRA 2005): inf until an extension from the node fails, then the radius asked for; a node is
extended only toward samples within its domain, so the samples that would fail next to an obstacle
that stopped a node before cost a nearest-neighbour scan, not a collision check.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from robointel.planning._batch_edges import root_edge_batch
from robointel.planning._node_check import config_free


@njit(cache=True)
def seed(s):  # pragma: no cover - compiled
    """Seed numba's random stream (used by the sampler and the shortcutter)."""
    np.random.seed(s)


@njit(cache=True, inline="always")
def _nearest(nodes, cnt, q):  # pragma: no cover - compiled
    best, bi = np.inf, 0
    n = q.shape[0]
    for i in range(cnt):
        d = 0.0
        for k in range(n):  # partial distances: a node stops counting once it cannot be the nearest
            e = nodes[i, k] - q[k]
            d += e * e
            if d >= best:
                break
        if d < best:
            best, bi = d, i
    return bi, math.sqrt(best)


#: lanes of the nearest-neighbour scan's running minima (a whole vector register of float64 twice over)
LANES = 16


@njit(cache=True, inline="always")
def _first_min(buf, cnt):  # pragma: no cover - compiled
    """(index, value) of the first smallest of ``buf[:cnt]``.

    The minimum is taken over :data:`LANES` running minima, a loop without a branch the compiler
    vectorizes, then the first entry equal to it is looked up (a scalar loop with a running index,
    its branch in each step, cost 1.2 ns per node).
    """
    m = np.full(LANES, np.inf)
    nb = cnt // LANES
    for b in range(nb):
        for lane in range(LANES):
            v = buf[LANES * b + lane]
            m[lane] = v if v < m[lane] else m[lane]
    best = np.inf
    for lane in range(LANES):
        best = m[lane] if m[lane] < best else best
    for i in range(LANES * nb, cnt):
        best = buf[i] if buf[i] < best else best
    for i in range(cnt):
        if buf[i] == best:
            return i, best
    return 0, best


@njit(cache=True, inline="always")
def _nearest_soa(X, cnt, q, buf):  # pragma: no cover - compiled
    """The nearest of the ``cnt`` nodes stored joint by joint, ``X`` (n, cap), to q: (index, distance).

    The squared distances are summed into ``buf`` (cap,) four joints per pass (each pass a loop
    over the nodes that the compiler vectorizes; the passes over ``buf``, not the arithmetic, bound
    the scan), then the first smallest is taken (:func:`_first_min`). The sum's order differs from
    :func:`_nearest`'s, so the distance may differ from it in the last bits.
    """
    n = X.shape[0]
    k = 0
    while k + 4 <= n:
        x0, x1, x2, x3 = X[k], X[k + 1], X[k + 2], X[k + 3]
        q0, q1, q2, q3 = q[k], q[k + 1], q[k + 2], q[k + 3]
        if k == 0:
            for i in range(cnt):
                e0, e1, e2, e3 = x0[i] - q0, x1[i] - q1, x2[i] - q2, x3[i] - q3
                buf[i] = (e0 * e0 + e1 * e1) + (e2 * e2 + e3 * e3)
        else:
            for i in range(cnt):
                e0, e1, e2, e3 = x0[i] - q0, x1[i] - q1, x2[i] - q2, x3[i] - q3
                buf[i] += (e0 * e0 + e1 * e1) + (e2 * e2 + e3 * e3)
        k += 4
    if k == 0:
        for i in range(cnt):
            buf[i] = 0.0
    while k < n:
        xk, qk = X[k], q[k]
        for i in range(cnt):
            e = xk[i] - qk
            buf[i] += e * e
        k += 1
    bi, best = _first_min(buf, cnt)
    return bi, math.sqrt(best)


#: a tree's range adapts over windows of this many extension attempts
WINDOW = 16
#: the smallest adapted range, rad (1/8 -> 1/2 and windows 32 -> 16 halved the cage's search)
MIN_RANGE = 0.5


@njit(cache=True, inline="always")
def _adapt(rng, win, t, ok):  # pragma: no cover - compiled
    """Count one extension attempt of tree t; at the end of a window adapt the tree's range.

    Below 1/8 of the window's attempts added a node: the range halves (not below ``MIN_RANGE``);
    above 1/2: it doubles (not above ``rng[2]``, the range asked for).
    """
    win[t, 0] += 1
    if ok:
        win[t, 1] += 1
    if win[t, 0] >= WINDOW:
        if 8 * win[t, 1] < win[t, 0]:
            rng[t] = max(MIN_RANGE, 0.5 * rng[t])
        elif 2 * win[t, 1] > win[t, 0]:
            rng[t] = min(rng[2], 2.0 * rng[t])
        win[t, 0] = 0
        win[t, 1] = 0


@njit(cache=True, inline="always")
def _steer(a, b, dist, rng, out):  # pragma: no cover - compiled
    f = 1.0 if dist <= rng else rng / dist
    for k in range(a.shape[0]):
        out[k] = a[k] + f * (b[k] - a[k])
    return f >= 1.0


@njit(cache=True)
def rrt_connect(X, parent, count, lower, upper, iters, rng, win, W, Wr, nroot, rcap, T, C, G, out, thresh,
                lever, res, link, BS, dom, rdom):  # pragma: no cover - compiled
    """Run up to ``iters`` RRT-Connect iterations.

    Returns 1 when the trees met (``link`` = (tree-0 node,
    tree-1 node)), 0 when not yet, -1 when a tree is full. Nodes are checked in world ``W``; edges
    leaving one of the ``nroot[t]`` roots of tree t are checked in world ``Wr`` (the roots may be
    valid only there) for their first ``rcap`` rad (max |dq|) and in ``W`` beyond
    (:func:`~robointel.planning._batch_edges.root_edge_batch`, ``BS`` the batch state), all other
    edges in ``W``. A sample farther from its nearest node than the node's domain ``dom`` is passed
    over (the iteration counts); a node whose extension fails gets the domain ``rdom`` (rad; inf:
    none), a node added the domain inf (module doc).

    ``X`` (2, n, cap): the nodes of each tree joint by joint, node i of tree t ``X[t, :, i]``
    (the caller writes the roots, the kernel every node it adds); ``parent`` (2, cap) int64.

    ``rng`` (3,): the current range (rad, joint-space norm) of tree 0 and tree 1 and the range asked
    for (their upper bound), ``win`` (2, 2) int64: each tree's attempts and successes in the current
    window; both caller-owned, so the ranges carry over between chunks (start with ``rng`` all equal
    and ``win`` zero). A tree whose extensions mostly fail (a goal deep in a narrow pocket) steps
    shorter (:func:`_adapt`); its greedy connect steps by its own range. The smaller tree is extended
    (ties: tree 0), so the search does not depend on how it is cut into chunks of ``iters``.
    Samples are checked with :func:`~robointel.planning._node_check.config_free`.
    """
    n = lower.shape[0]
    cap = X.shape[2]
    qr = np.empty(n)
    qn = np.empty(n)
    qa = np.empty(n)  # the node extended from (a contiguous copy for the edge check)
    buf = np.empty(cap)
    obox = BS[0][3]  # the obstacles' boxes (the node check's first test)
    for _ in range(iters):
        # balanced: the smaller tree grows (a goal tree stuck in a pocket gets the attempts, which
        # fail cheaply at the sample's node check)
        a = 0 if count[0] <= count[1] else 1
        b = 1 - a
        if count[a] >= cap or count[b] >= cap:
            return -1
        for k in range(n):
            qr[k] = np.random.uniform(lower[k], upper[k])
        i, d = _nearest_soa(X[a], count[a], qr, buf)
        if d > dom[a, i]:  # outside the node's dynamic domain
            continue
        for k in range(n):
            qa[k] = X[a, k, i]
        _steer(qa, qr, d, rng[a], qn)
        ok = config_free(qn, W, T, C, G, out, thresh, obox) and root_edge_batch(
            qa, qn, Wr, W, i < nroot[a], np.bool_(False), rcap, BS, thresh, res, out)
        _adapt(rng, win, a, ok)
        if not ok:
            dom[a, i] = min(dom[a, i], rdom)
            continue
        ia = count[a]
        X[a, :, ia] = qn
        parent[a, ia] = i
        dom[a, ia] = np.inf
        count[a] += 1
        # connect tree b greedily toward the new node
        j, d = _nearest_soa(X[b], count[b], qn, buf)
        for k in range(n):
            qa[k] = X[b, k, j]
        while True:
            if count[b] >= cap:
                return -1
            reached = _steer(qa, qn, d, rng[b], qr)
            if not reached and not config_free(qr, W, T, C, G, out, thresh, obox):
                break
            if not root_edge_batch(qa, qr, Wr, W, j < nroot[b], np.bool_(False), rcap, BS, thresh, res, out):
                break
            if reached:
                if a == 0:
                    link[0], link[1] = ia, j
                else:
                    link[0], link[1] = j, ia
                return 1
            jb = count[b]
            X[b, :, jb] = qr
            parent[b, jb] = j
            dom[b, jb] = np.inf
            count[b] += 1
            j = jb
            d = 0.0
            for k in range(n):
                qa[k] = qr[k]
                e = qn[k] - qr[k]
                d += e * e
            d = math.sqrt(d)
    return 0


@njit(cache=True)
def revalidate(X, parent, count, nroot, W, Wr, rcap, T, C, G, out, thresh, res, BS, dom):  # pragma: no cover - compiled
    """Keep of each tree the nodes still free, reached by edges still valid, in world ``W``: nodes dropped.

    Node i of tree t is kept when its parent is kept, it passes the node check (``thresh``) and the
    edge from its parent passes the edge check (``res``; leaving a root: ``Wr`` for its first ``rcap``
    rad) as in :func:`rrt_connect`; the rest of its subtree goes with a dropped node. The roots are
    kept (the caller checked them). The trees are compacted in place (a node's parent comes before
    it, so the order of the kept nodes and their parents hold), their domains ``dom`` with them;
    ``count`` is updated.
    """
    n = X.shape[1]
    obox = BS[0][3]
    dropped = 0
    new = np.empty(X.shape[2], np.int64)
    qa = np.empty(n)
    qn = np.empty(n)
    for t in range(2):
        m = nroot[t]
        for i in range(m):
            new[i] = i
        for i in range(nroot[t], count[t]):
            new[i] = -1
            p = new[parent[t, i]]
            if p < 0:
                dropped += 1
                continue
            for k in range(n):
                qn[k] = X[t, k, i]
                qa[k] = X[t, k, p]
            if not (config_free(qn, W, T, C, G, out, thresh, obox) and root_edge_batch(
                    qa, qn, Wr, W, p < nroot[t], np.bool_(False), rcap, BS, thresh, res, out)):
                dropped += 1
                continue
            X[t, :, m] = qn
            parent[t, m] = p
            dom[t, m] = dom[t, i]
            new[i] = m
            m += 1
        for i in range(m, count[t]):
            parent[t, i] = -1
        count[t] = m
    return dropped
