"""Compiled kernels of the dense check: limits and joint travel in one pass, clearance with a two-sided skip.

The clearance of a run of samples skips samples by a two-sided travel bound, the obstacles and
every self-collision group pair bounded apart.

Between two samples a and m, with V_k the total variation of joint k between them, the sphere
centres move at most ``lever . V`` (:attr:`Environment.lever`), so the obstacle clearance falls at
most by that; the distance of a self-collision group pair p at most by ``rel_p . V`` (``W[20]``: the
levers of the joints that move one of its two groups but not the other). So a sample m has
clearance

    c_m >= B_a(m) = min(e_a - lever . V(a, m), min_p (s_pa - rel_p . V(a, m)))

with e_a the obstacle clearance of an evaluated sample a and s_pa its pair distances, and likewise
from an evaluated sample on its other side. Every sample these bounds leave above the threshold
is skipped; the others are evaluated (bisecting the unresolved stretch). The pairs matter: on the
MotionBenchMaker UR5 the self-collision pairs are the closest in ~70 % of the samples, and most of
them are moved by the wrist alone.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from robointel.planning import _collision_kernels as K

#: margin on the travel bound's comparisons, m (floating-point rounding of the summed travel)
TRAVEL_EPS = 1e-12


@njit(cache=True)
def limits_travel(Q: np.ndarray, QD: np.ndarray, QDD: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                  vmax: np.ndarray, amax: np.ndarray,
                  V: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """The limits of every sample and the joints' total variation, in one pass.

    Returns (first sample index out of [lower, upper] or -1 (1e-9 rad tolerance), rv, ra): rv, ra
    (n,) per joint max |qd| / vmax and max |qdd| / amax (NaN propagates, as in ``np.max``). Fills
    ``V`` (K, n): V[0] = 0, V[k, j] = V[k-1, j] + |Q[k, j] - Q[k-1, j]| (non-decreasing).
    """
    Kn, n = Q.shape
    first = -1
    mv = np.zeros(n)
    ma = np.zeros(n)
    for k in range(Kn):
        for j in range(n):
            x = Q[k, j]
            if first < 0 and (x < lower[j] - 1e-9 or x > upper[j] + 1e-9):
                first = k
            v = abs(QD[k, j])
            a = abs(QDD[k, j])
            if v > mv[j] or v != v:
                mv[j] = v
            if a > ma[j] or a != a:
                ma[j] = a
            V[k, j] = V[k - 1, j] + abs(x - Q[k - 1, j]) if k > 0 else 0.0
    # max_k |x_k| / lim == max_k (|x_k| / lim): division by a positive number is monotone
    return first, mv / vmax, ma / amax


@njit(cache=True)
def variation(Q: np.ndarray, V: np.ndarray) -> None:  # pragma: no cover - compiled
    """Fill ``V`` (K, n) with the joints' total variation from Q[0], as :func:`limits_travel` does."""
    for j in range(Q.shape[1]):
        V[0, j] = 0.0
    for k in range(1, Q.shape[0]):
        for j in range(Q.shape[1]):
            V[k, j] = V[k - 1, j] + abs(Q[k, j] - Q[k - 1, j])


@njit(cache=True, fastmath=K.FM)
def _evaluate(q: np.ndarray, W: tuple, T: np.ndarray, C: np.ndarray, G: np.ndarray, out: np.ndarray, cap: float,
              sp: np.ndarray) -> tuple[float, float]:  # pragma: no cover - compiled
    """(obstacle clearance e, clearance) at q, both capped at ``cap``; ``sp`` (P,) the pairs' distance bounds.

    ``sp[p]`` is a lower bound of group pair p's distance: the distance itself where it is below
    e, else a value >= e.

    The clearance is :func:`~robointel.planning._collision_kernels.clearance`'s (obstacles and
    self-collision pairs). A pair at or above e never tightens the bound of :func:`_bound` (its
    relative levers are at most the environment's), so its bounding-sphere distance stands in.
    """
    K.sphere_centres(q, W, T, C, G)
    e = K.env_clearance(C, G, W, cap, -np.inf, out)
    sr, gr, gs, gpairs, smask = W[21], W[22], W[11], W[14], W[15]
    best = e
    for p in range(gpairs.shape[0]):
        a, b = gpairs[p, 0], gpairs[p, 1]
        dx, dy, dz = G[a, 0] - G[b, 0], G[a, 1] - G[b, 1], G[a, 2] - G[b, 2]
        db = math.sqrt(dx * dx + dy * dy + dz * dz) - gr[a] - gr[b]
        if db >= e:  # a lower bound at or above the obstacle clearance: the pair never binds (rel_p <= lever)
            sp[p] = db
            continue
        d_p = e
        bx, by, bz, rb = G[b, 0], G[b, 1], G[b, 2], gr[b]
        for i in range(gs[a], gs[a + 1]):
            xi, yi, zi = C[i, 0], C[i, 1], C[i, 2]
            dx, dy, dz = xi - bx, yi - by, zi - bz  # b's bounding sphere holds each of its spheres
            if math.sqrt(dx * dx + dy * dy + dz * dz) - sr[i] - rb >= d_p:
                continue
            for j in range(gs[b], gs[b + 1]):
                if smask[i, j] == 0:
                    continue
                dx, dy, dz = xi - C[j, 0], yi - C[j, 1], zi - C[j, 2]
                d = math.sqrt(dx * dx + dy * dy + dz * dz) - sr[i] - sr[j]
                if d < d_p:
                    d_p = d
        sp[p] = d_p
        if d_p < best:
            best = d_p
    return e, best


@njit(cache=True)
def _bound(V: np.ndarray, a: int, m: int, e: float, sp: np.ndarray, lever: np.ndarray, rel: np.ndarray,
           f: float) -> float:  # pragma: no cover - compiled
    """The clearance bound at sample m from sample a (obstacle clearance e, pair distances sp), travel times f."""
    n = V.shape[1]
    t = 0.0
    for k in range(n):
        t += lever[k] * abs(V[m, k] - V[a, k])
    b = e - f * t
    for p in range(rel.shape[0]):
        if sp[p] >= e:  # never below the obstacles' bound: rel_p <= lever
            continue
        t = 0.0
        for k in range(n):
            t += rel[p, k] * abs(V[m, k] - V[a, k])
        b = min(b, sp[p] - f * t)
    return b


@njit(cache=True)
def _reach(V: np.ndarray, a: int, lo: int, hi: int, e: float, sp: np.ndarray, lever: np.ndarray, rel: np.ndarray,
           f: float, tau: float, forward: bool) -> int:  # pragma: no cover - compiled
    """Forward: the last m in [lo, hi] with bound from a >= tau (lo - 1 if none); backward: the first (hi + 1)."""
    if forward:  # the bound falls with m: gallop from lo, then bisect for the last m that keeps it
        if _bound(V, a, lo, e, sp, lever, rel, f) < tau:
            return lo - 1
        x, y, step = lo, hi + 1, 1  # bound(x) >= tau, y the first known below (or past hi)
        while x + step < y:
            if _bound(V, a, x + step, e, sp, lever, rel, f) >= tau:
                x, step = x + step, 2 * step
            else:
                y = x + step
                break
        while y - x > 1:
            mid = (x + y) // 2
            if _bound(V, a, mid, e, sp, lever, rel, f) >= tau:
                x = mid
            else:
                y = mid
        return x
    if _bound(V, a, hi, e, sp, lever, rel, f) < tau:
        return hi + 1
    x, y, step = lo - 1, hi, 1  # bound(y) >= tau, x the last known below (or before lo)
    while y - step > x:
        if _bound(V, a, y - step, e, sp, lever, rel, f) >= tau:
            y, step = y - step, 2 * step
        else:
            x = y - step
            break
    while y - x > 1:
        mid = (x + y) // 2
        if _bound(V, a, mid, e, sp, lever, rel, f) >= tau:
            y = mid
        else:
            x = mid
    return y


@njit(cache=True)
def span_clearance(Q: np.ndarray, V: np.ndarray, lo: int, hi: int, W: tuple, T: np.ndarray, C: np.ndarray,
                   G: np.ndarray, out: np.ndarray, lever: np.ndarray, floor: float, cap: float,
                   best: float) -> tuple[float, int, int]:  # pragma: no cover - compiled
    """Smallest clearance in ``W`` over the samples Q[lo:hi] (hi > lo), with ``best`` the smallest so far.

    ``V`` is the joints' total variation of :func:`limits_travel`, ``lever`` the environment's
    (``W[20]`` holds the pairs' relative levers). Returns (min(best, the smallest evaluated
    clearance), index of that sample or -1 when none was below ``best``, samples evaluated). Every
    skipped sample is proven >= min(the returned minimum, ``floor``) by the bounds from its
    evaluated neighbours (module doc), so the result is exact whenever it is below ``floor``;
    clearances are capped at ``cap``. The first sample is always evaluated.
    """
    rel = W[20]
    P = rel.shape[0]
    cap_r = 64
    re = np.empty(cap_r)  # records of the evaluated samples: obstacle clearance, pair distances
    rs = np.empty((cap_r, P))
    nr = 0
    worst = -1
    e, c = _evaluate(Q[lo], W, T, C, G, out, cap, rs[0])
    re[0] = e
    nr = 1
    evals = 1
    if c < best:
        best, worst = c, lo
    st_a = np.empty(64, np.int64)  # the unresolved intervals: sample and record of both ends
    st_b = np.empty(64, np.int64)
    st_ra = np.empty(64, np.int64)
    st_rb = np.empty(64, np.int64)
    k, rk = lo, 0
    while k < hi - 1:
        tau = min(best, floor) + TRAVEL_EPS
        if _bound(V, k, hi - 1, re[rk], rs[rk], lever, rel, 1.0) >= tau:
            break  # the rest is proven from k alone
        # the next sample at which equal distances would prove the whole interval from both sides (half the travel each)
        j = _reach(V, k, k + 1, hi - 1, re[rk], rs[rk], lever, rel, 0.5, tau, True)
        j = min(max(j, k + 1), hi - 1)
        if nr + 1 >= cap_r:  # grow the records
            re = np.concatenate((re, np.empty(cap_r)))
            rs = np.concatenate((rs, np.empty((cap_r, P))))
            cap_r *= 2
        e, c = _evaluate(Q[j], W, T, C, G, out, cap, rs[nr])
        re[nr] = e
        rj = nr
        nr += 1
        evals += 1
        if c < best:
            best, worst = c, j
        st_a[0], st_b[0], st_ra[0], st_rb[0] = k, j, rk, rj
        top = 1
        while top > 0:
            top -= 1
            a, b, ra, rb = st_a[top], st_b[top], st_ra[top], st_rb[top]
            if b - a <= 1:
                continue
            tau = min(best, floor) + TRAVEL_EPS
            f = _reach(V, a, a + 1, b - 1, re[ra], rs[ra], lever, rel, 1.0, tau, True)  # proven from a: m <= f
            g = _reach(V, b, f + 1, b - 1, re[rb], rs[rb], lever, rel, 1.0, tau, False) if f < b - 1 else b
            if f + 1 >= g:
                continue
            m = (f + 1 + g - 1) // 2
            if nr + 1 >= cap_r:
                re = np.concatenate((re, np.empty(cap_r)))
                rs = np.concatenate((rs, np.empty((cap_r, P))))
                cap_r *= 2
            e, c = _evaluate(Q[m], W, T, C, G, out, cap, rs[nr])
            re[nr] = e
            rm = nr
            nr += 1
            evals += 1
            if c < best:
                best, worst = c, m
            if top + 2 > st_a.shape[0]:  # grow the stack
                st_a = np.concatenate((st_a, np.empty(st_a.shape[0], np.int64)))
                st_b = np.concatenate((st_b, np.empty(st_b.shape[0], np.int64)))
                st_ra = np.concatenate((st_ra, np.empty(st_ra.shape[0], np.int64)))
                st_rb = np.concatenate((st_rb, np.empty(st_rb.shape[0], np.int64)))
            st_a[top], st_b[top], st_ra[top], st_rb[top] = m, b, rm, rb
            top += 1
            st_a[top], st_b[top], st_ra[top], st_rb[top] = a, m, ra, rm
            top += 1
        k, rk = j, rj
    return best, worst, evals


@njit(cache=True)
def env_below(Q: np.ndarray, V: np.ndarray, W: tuple, T: np.ndarray, C: np.ndarray, G: np.ndarray, out: np.ndarray,
              lever: np.ndarray, thresh: float) -> np.ndarray:  # pragma: no cover - compiled
    """Mask (K,) of the samples Q whose obstacle clearance (no self-collision) is below ``thresh``.

    The same mask as :func:`~robointel.planning._collision_kernels.samples_env_below` (True exactly
    where the clearance is below ``thresh``), with samples proven >= ``thresh`` from both sides
    (``V`` the joints' total variation of :func:`limits_travel`), and the samples after one below
    ``thresh`` proven below it for as long as its deficit outlasts the travel (the clearance rises
    no faster than it falls).
    """
    Kn = Q.shape[0]
    mask = np.zeros(Kn, np.bool_)
    if Kn == 0:
        return mask
    cap = thresh + 0.25
    none = np.full(0, np.inf)  # no pair bounds: the obstacles alone
    rel = np.zeros((0, Q.shape[1]))
    tau = thresh + TRAVEL_EPS
    st_a = np.empty(64, np.int64)
    st_b = np.empty(64, np.int64)
    st_ea = np.empty(64)
    st_eb = np.empty(64)
    K.sphere_centres(Q[0], W, T, C, G)
    ek = K.env_clearance(C, G, W, cap, -np.inf, out)
    mask[0] = ek < thresh
    k = 0
    while k < Kn - 1:
        if ek < thresh:  # the clearance rises at most as fast as it falls: a deficit holds for its travel
            jd = _reach(V, k, k + 1, Kn - 1, -ek, none, lever, rel, 1.0, TRAVEL_EPS - thresh, True)
            if jd > k:
                mask[k + 1:jd + 1] = True
                if jd >= Kn - 1:
                    break
                k = jd + 1
                K.sphere_centres(Q[k], W, T, C, G)
                ek = K.env_clearance(C, G, W, cap, -np.inf, out)
                mask[k] = ek < thresh
                continue
        if _bound(V, k, Kn - 1, ek, none, lever, rel, 1.0) >= tau:
            break
        j = _reach(V, k, k + 1, Kn - 1, ek, none, lever, rel, 0.5, tau, True)
        j = min(max(j, k + 1), Kn - 1)
        K.sphere_centres(Q[j], W, T, C, G)
        ej = K.env_clearance(C, G, W, cap, -np.inf, out)
        mask[j] = ej < thresh
        st_a[0], st_b[0], st_ea[0], st_eb[0] = k, j, ek, ej
        top = 1
        while top > 0:
            top -= 1
            a, b, ea, eb = st_a[top], st_b[top], st_ea[top], st_eb[top]
            if b - a <= 1:
                continue
            f = _reach(V, a, a + 1, b - 1, ea, none, lever, rel, 1.0, tau, True)
            g = _reach(V, b, f + 1, b - 1, eb, none, lever, rel, 1.0, tau, False) if f < b - 1 else b
            if f + 1 >= g:
                continue
            m = (f + 1 + g - 1) // 2
            K.sphere_centres(Q[m], W, T, C, G)
            em = K.env_clearance(C, G, W, cap, -np.inf, out)
            mask[m] = em < thresh
            if top + 2 > st_a.shape[0]:
                st_a = np.concatenate((st_a, np.empty(st_a.shape[0], np.int64)))
                st_b = np.concatenate((st_b, np.empty(st_b.shape[0], np.int64)))
                st_ea = np.concatenate((st_ea, np.empty(st_ea.shape[0])))
                st_eb = np.concatenate((st_eb, np.empty(st_eb.shape[0])))
            st_a[top], st_b[top], st_ea[top], st_eb[top] = m, b, em, eb
            top += 1
            st_a[top], st_b[top], st_ea[top], st_eb[top] = a, m, ea, em
            top += 1
        k, ek = j, ej
    return mask
