"""Compiled (numba) edge checks on batches: many points of a straight motion checked in one call.

The guarantee is that of :func:`~robointel.planning._edge_kernels.edge_valid`: a point with
clearance c proves every point within sphere-centre travel c - thresh + res / 2 of it to keep
clearance >= thresh - res / 2 (obstacles bound the travel of each sphere, self-collision pairs the
relative travel of their two links), so an accepted edge keeps thresh - res / 2 everywhere and
every point checked on it (its end included) keeps thresh; a refused edge has a point below thresh
(decisions are taken :data:`~robointel.planning._batch_kernels.TOL` = 1 nm below thresh, so a
start or goal exactly at thresh passes whatever the rounding; the guarantee is 1 nm lower).

The edge is checked in *rounds*. Each round places up to :data:`LANES` points on the stretches not
yet proven (the first round spreads them over the whole edge, its end among them), computes the
path-parameter radius each point proves in one batched call (:func:`batch_advance`: the sphere
kinematics and distances of all points as vectors, see :mod:`robointel.planning._batch_kernels`),
and keeps what the radii leave uncovered for the next round. A collision anywhere on the edge is met
in the first round or two (the points are spread), and a free edge is proven in a few batched
calls. ``BS`` is the batch state (:func:`batch_state`): the self-collision pair lists, the batch
scratch arrays and the per-edge rates.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from robointel.planning._batch_kernels import (
    TOL,
    _dist,
    batch_groups,
    box_gap,
    ensure_spheres,
    place_clusters,
)
from robointel.planning._batch_view import LANES, BatchScratch, batch_world
from robointel.planning._collision_kernels import CLOUD, ENV, FM, SELF, _aabb_dist, _cloud_min
from robointel.planning._edge_kernels import _rates, root_split

#: sphere-centre travel between the first round's points, m (at most :data:`LANES` of them): a batch costs
#: the same with any number of lanes up to LANES, and closer points each prove a shorter stretch, so fewer
#: obstacles and sphere pairs are within reach (0.05 against 0.2: the search 9 % and the shortcut 11 % faster
#: on the UR5, the same trajectories on 105 UR5 and 93 Fetch problems; 0.02 no faster)
FIRST_SPACING = 0.05
#: each point is asked to prove this much more than half the spacing (so rounding leaves no sliver)
NEED_SLACK = 1.0001


def batch_state(W: tuple) -> tuple:
    """The batch state of world ``W`` (and of every world with its joints, spheres and self pairs).

    (the :func:`~robointel.planning._batch_view.batch_world` view, the :class:`BatchScratch`
    arrays, rate (m, nj), irate (m,), adv (lanes,), f (lanes,), lo, hi (the stretch queue), pair
    levers (p,)).
    """
    P = batch_world(W)
    lanes = LANES
    S = BatchScratch(W, len(P[7])).arrays()
    m, nj = W[23].shape[0], W[23].shape[1]
    qcap = 4096
    return (P, S, np.empty((m, nj)), np.empty(m), np.empty(lanes), np.empty(lanes), np.empty(qcap), np.empty(qcap),
            np.empty(W[20].shape[0]))


@njit(cache=True, fastmath=FM)
def batch_advance(B, W, BS, thresh, res, cap, out):  # pragma: no cover - compiled
    """Path-parameter radius ``BS[4]`` (adv) proven around each lane of the batch ``BS[1][0]``; False on a collision.

    On entry adv[b] is the radius lane b needs (the caller's spacing of the lanes); on return the
    radius it proves, at most that: the pairs that cannot bring a lane below its need are not
    looked into. Lane b proves min(need, adv) with adv = min over spheres i of
    (min(d_i, cap) - thresh + res / 2) / rate_i (obstacles; ``BS[3]`` holds 1 / rate_i) and over
    self-collision sphere pairs of (d_ij - thresh + res / 2) / (relative rate ``rate[i, joint of j] +
    rate[j, joint of i]``, worked out only for the pairs looked into), where
    every d is >= thresh, at least
    res / 2 of travel at the largest rate; a lane with a distance below ``thresh`` ends the call
    (False, ``out`` = the pair: kind, sphere, obstacle or sphere, lane). Groups and group pairs whose
    bounding spheres cannot lower a lane's radius are not looked into.
    """
    P, S, rate, irate, adv = BS[0], BS[1], BS[2], BS[3], BS[4]
    thresh -= TOL  # a lane exactly at thresh passes, whatever the rounding (its radius TOL / rate larger)
    batch_groups(B, W, S)
    X, Y, Z, GX, GY, GZ, L, GB = S[2], S[3], S[4], S[5], S[6], S[7], S[8], S[9]
    D = L[2]
    sr, gr, gs, types, params, cd, gj = W[7], W[10], W[11], W[12], W[13], W[19], W[8]
    obox = P[3]
    half = 0.5 * res
    Lmax = 0.0
    for i in range(rate.shape[0]):
        Lmax = max(Lmax, rate[i, 0])
    if Lmax <= 0.0:
        Lmax = 1.0
    a0 = (cap - thresh + half) / Lmax  # clearances are capped at cap: no sphere limits below this
    amax = 0.0  # the largest lane radius: a pair that cannot lower it is skipped
    for b in range(B, LANES):  # the padded lanes repeat lane B - 1
        adv[b] = adv[B - 1]
    for b in range(LANES):
        adv[b] = min(adv[b], a0)
        amax = max(amax, adv[b])
    ng = gr.shape[0]
    for kk in range(ng):  # from the tool back: most colliding edges meet an obstacle at the end of the chain
        k = ng - 1 - kk
        if gj[k] == 0:
            continue
        Rg = 0.0
        for i in range(gs[k], gs[k + 1]):
            Rg = max(Rg, rate[i, 0])
        for o in range(types.shape[0]):
            bg = box_gap(GB, k, obox, o) - gr[k]
            if bg >= thresh and min(bg, cap) - thresh + half >= amax * Rg:
                continue
            _dist(types[o], params[o], GX, GY, GZ, k, B, D)
            need = False
            for b in range(LANES):
                db = D[b] - gr[k]
                need |= (db < thresh) | (min(db, cap) - thresh + half < adv[b] * Rg)
            if not need:
                continue
            ensure_spheres(k, B, W, S)
            for i in range(gs[k], gs[k + 1]):
                _dist(types[o], params[o], X, Y, Z, i, B, D)
                ri, ir = sr[i], irate[i]
                dmin = np.inf
                for b in range(LANES):
                    d = D[b] - ri
                    dmin = min(dmin, d)
                    adv[b] = min(adv[b], (min(d, cap) - thresh + half) * ir)
                if dmin < thresh:
                    for b in range(LANES):
                        if D[b] - ri < thresh:
                            out[0], out[1], out[2], out[3] = ENV, i, o, b
                            return False
            amax = 0.0
            for b in range(LANES):
                amax = max(amax, adv[b])
        if cd[0] > 0:
            for b in range(LANES):
                if _aabb_dist(GX[k, b], GY[k, b], GZ[k, b], W) - gr[k] >= max(thresh - half + adv[b] * Rg, thresh):
                    continue
                ensure_spheres(k, B, W, S)
                for i in range(gs[k], gs[k + 1]):
                    reach = min(cap, max(thresh - half + adv[b] * rate[i, 0], thresh))
                    d = _cloud_min(X[i, b], Y[i, b], Z[i, b], reach + sr[i], W) - sr[i]
                    if d < thresh:
                        out[0], out[1], out[2], out[3] = CLOUD, i, 0, b
                        return False
                    adv[b] = min(adv[b], (min(d, cap) - thresh + half) * irate[i])
            amax = 0.0
            for b in range(LANES):
                amax = max(amax, adv[b])
    gpairs, sgr, gL = W[14], W[22], BS[8]
    start, ca, cb, cr = P[0], P[4], P[5], S[14]
    CX, CY, CZ = S[11], S[12], S[13]
    clustered = False
    for p in range(gpairs.shape[0]):
        a, c = gpairs[p, 0], gpairs[p, 1]
        rr = sgr[a] + sgr[c]
        Lp = gL[p]
        base = rr + thresh + half  # centre distances below base + adv * Lp may limit a lane
        if box_gap(GB, a, GB, c) >= base + amax * Lp:
            continue
        ax, ay, az, cx, cy, cz = GX[a], GY[a], GZ[a], GX[c], GY[c], GZ[c]
        need = False
        for b in range(LANES):  # squared distances: no root unless a pair may matter
            dx, dy, dz = ax[b] - cx[b], ay[b] - cy[b], az[b] - cz[b]
            lim = base + adv[b] * Lp
            need |= dx * dx + dy * dy + dz * dz < lim * lim
        if not need:
            continue
        if not clustered:
            place_clusters(W, P, S)
            clustered = True
        ensure_spheres(a, B, W, S)
        ensure_spheres(c, B, W, S)
        for t in range(start[p], start[p + 1]):
            x, y = ca[t], cb[t]
            base = cr[x] + cr[y] + thresh + half
            need = False
            for b in range(LANES):
                dx, dy, dz = CX[x, b] - CX[y, b], CY[x, b] - CY[y, b], CZ[x, b] - CZ[y, b]
                lim = base + adv[b] * Lp
                need |= dx * dx + dy * dy + dz * dz < lim * lim
            if need:
                if not _sphere_pairs(t, P, S, W, BS, thresh, half, out):
                    return False
        amax = 0.0
        for b in range(LANES):
            amax = max(amax, adv[b])
    return True


@njit(cache=True, fastmath=FM, inline="always")
def _sphere_pairs(t, P, S, W, BS, thresh, half, out):  # pragma: no cover - compiled
    """The sphere pairs of cluster pair t in :func:`batch_advance`: lower each lane's radius; False on a collision."""
    pi, pj, sstart = P[1], P[2], P[6]
    X, Y, Z, D = S[2], S[3], S[4], S[8][2]
    ssr, sj, rate, adv = W[21], W[5], BS[2], BS[4]
    for s in range(sstart[t], sstart[t + 1]):
        i, j = pi[s], pj[s]
        xi, yi, zi, xj, yj, zj = X[i], Y[i], Z[i], X[j], Y[j], Z[j]
        rr = ssr[i] + ssr[j]
        Lij = rate[i, sj[j]] + rate[j, sj[i]]  # their relative travel on the edge
        iL = 1.0 / Lij if Lij > 0.0 else np.inf
        low = rr + thresh  # centre distances below low: a collision
        base = rr + thresh - half
        need = False
        for b in range(LANES):
            dx, dy, dz = xi[b] - xj[b], yi[b] - yj[b], zi[b] - zj[b]
            lim = max(base + adv[b] * Lij, low)
            D[b] = dx * dx + dy * dy + dz * dz
            need |= D[b] < lim * lim
        if not need:
            continue
        dmin = np.inf
        for b in range(LANES):
            d = math.sqrt(D[b]) - rr
            dmin = min(dmin, d)
            adv[b] = min(adv[b], (d - thresh + half) * iL)
        if dmin < thresh:
            for b in range(LANES):
                if math.sqrt(D[b]) - rr < thresh:
                    out[0], out[1], out[2], out[3] = SELF, i, j, b
                    return False
    return True


@njit(cache=True)
def edge_rates(q0, q1, W, BS):  # pragma: no cover - compiled
    """The per-edge rates of q0 -> q1 in ``BS``: sphere rates (m, nj), 1 / obstacle rate, group-pair levers.

    Returns the largest rate (0: nothing moves relative to anything).
    """
    n = q0.shape[0]
    dq = np.empty(n)
    for k in range(n):
        dq[k] = abs(q1[k] - q0[k])
    rate, irate, gL = BS[2], BS[3], BS[8]
    _rates(dq, W, rate)
    rm = 0.0
    for i in range(rate.shape[0]):
        irate[i] = 1.0 / rate[i, 0] if rate[i, 0] > 0.0 else np.inf
        for J in range(rate.shape[1]):
            rm = max(rm, rate[i, J])
    rel = W[20]
    for p in range(rel.shape[0]):
        v = 0.0
        for k in range(n):
            v += rel[p, k] * dq[k]
        gL[p] = v
    return rm


@njit(cache=True)
def _load(q0, q1, f, B, Qt):  # pragma: no cover - compiled
    """Lanes 0..B-1 of Qt (n, lanes) = q0 + f[b] (q1 - q0)."""
    for k in range(q0.shape[0]):
        a, d = q0[k], q1[k] - q0[k]
        row = Qt[k]
        for b in range(B):
            row[b] = a + f[b] * d


@njit(cache=True)
def _push(lo, hi, head, size, a, c):  # pragma: no cover - compiled
    """Append the stretch [a, c] to the circular queue (lo, hi); returns the new size (-1 when full)."""
    if size >= lo.shape[0]:
        return -1
    t = (head + size) % lo.shape[0]
    lo[t], hi[t] = a, c
    return size + 1


@njit(cache=True)
def edge_batch(q0, q1, W, BS, thresh, res, out):  # pragma: no cover - compiled
    """Check the straight motion q0 -> q1 (q1 included) in world ``W`` in batched rounds (module doc).

    True when every point keeps thresh - res / 2 (``res``: m of sphere-centre travel) and q1 and
    every other point checked keep ``thresh``; False at a point below ``thresh`` (``out`` names the
    pair and the batch lane) or, conservatively, when the stretch queue would overflow.
    """
    rm = edge_rates(q0, q1, W, BS)
    S, adv, F, lo, hi = BS[1], BS[4], BS[5], BS[6], BS[7]
    lanes = F.shape[0]
    Qt = S[0]
    cap = thresh + 0.25
    if rm <= 0.0:  # nothing moves relative to anything: q1 decides
        F[0], adv[0] = 1.0, 0.0
        _load(q0, q1, F, 1, Qt)
        return batch_advance(1, W, BS, thresh, res, cap, out)
    w = res / rm  # the path-parameter width one point proves at least (res / 2 of travel each side)
    sa = np.empty(lanes)  # the stretches of a round: ends and first lane
    sc = np.empty(lanes)
    sb = np.empty(lanes + 1, np.int64)
    # round 1: one stretch [0, 1], points spread over it, the end last
    B = min(lanes, int(math.ceil(rm / FIRST_SPACING)) + 1, int(math.ceil(1.0 / w)) + 1)
    for b in range(B - 1):
        F[b] = (b + 0.5) / (B - 1)
        adv[b] = NEED_SLACK * 0.5 / (B - 1)  # neighbours' proven stretches meet
    F[B - 1], adv[B - 1] = 1.0, 0.0
    sa[0], sc[0], sb[0], sb[1] = 0.0, 1.0, 0, B
    ns = 1
    head, size = 0, 0
    while True:
        _load(q0, q1, F, B, Qt)
        if not batch_advance(B, W, BS, thresh, res, cap, out):
            return False
        for t in range(ns):  # each stretch minus its lanes' proven intervals (lanes in increasing order)
            cur = sa[t]
            for b in range(sb[t], sb[t + 1]):
                left = F[b] - adv[b]
                if left > cur:
                    size = _push(lo, hi, head, size, cur, left)
                    if size < 0:
                        return False
                cur = max(cur, F[b] + adv[b])
            if cur < sc[t]:
                size = _push(lo, hi, head, size, cur, sc[t])
                if size < 0:
                    return False
        if size == 0:
            return True
        # the next round: one point per stretch when they fill the lanes (oldest first), else the spare lanes
        # shared in proportion to length (never more points than the stretch needs)
        ns = min(size, lanes)
        U = 0.0
        for t in range(ns):
            u = (head + t) % lo.shape[0]
            U += hi[u] - lo[u]
        spare = lanes - ns
        B = 0
        for t in range(ns):
            u = (head + t) % lo.shape[0]
            a, c = lo[u], hi[u]
            k = 1
            if spare > 0:
                k = 1 + min(int(spare * (c - a) / U), max(int(math.ceil((c - a) / w)) - 1, 0))
            sa[t], sc[t], sb[t] = a, c, B
            for j in range(k):
                F[B + j] = a + (j + 0.5) * (c - a) / k
                adv[B + j] = NEED_SLACK * 0.5 * (c - a) / k
            B += k
        sb[ns] = B
        head = (head + ns) % lo.shape[0]
        size -= ns


@njit(cache=True)
def root_edge_batch(q0, q1, Wr, W, root0, root1, rcap, BS, thresh, res, out):  # pragma: no cover - compiled
    """:func:`edge_batch` with the relaxed world ``Wr`` within ``rcap`` rad (max |dq|) of a root.

    A root is q0 when ``root0``, q1 when ``root1`` (a start or goal that may be valid only in
    ``Wr``); the split points and the rest of the edge are checked in ``W``, as
    :func:`~robointel.planning._shortcut_kernels.root_edge_fine` splits them.
    """
    if not root0 and not root1:
        return edge_batch(q0, q1, W, BS, thresh, res, out)
    L, a, b, qa, qb = root_split(q0, q1, root0, root1, rcap)
    if L <= 0.0:
        return True
    if a >= b:  # every point within rcap of a root
        return edge_batch(q0, q1, Wr, BS, thresh, res, out)
    if root0 and not edge_batch(q0, qa, Wr, BS, thresh, res, out):
        return False
    if not edge_batch(qa, qb, W, BS, thresh, res, out):  # qb included, in W
        return False
    return not root1 or edge_batch(qb, q1, Wr, BS, thresh, res, out)
