"""Compiled kernels of the dense check: the limits and the sphere travel in one pass, the clearance
of a run of samples with samples skipped by a two-sided travel bound.

The travel bound (:func:`~robointel.planning._collision_kernels.travel`) limits how far any sphere
centre moves between two samples, so a sample m between evaluated samples a and b has clearance

    c_m >= max(c_a - T(a, m), c_b - T(m, b)),

T the summed travel between them. Every sample that bound leaves above the threshold is skipped;
the others are evaluated (bisecting the unresolved stretch). From one side only (the bound of the
compiled ``samples_clearance``) a sample at clearance c proves c / travel-per-sample samples; from
both sides an interval between two such samples twice as long.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from robointel.planning import _collision_kernels as K

#: margin on the travel bound's comparisons, m (floating-point rounding of the summed travel)
TRAVEL_EPS = 1e-12


@njit(cache=True)
def limits_travel(Q: np.ndarray, QD: np.ndarray, QDD: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                  vmax: np.ndarray, amax: np.ndarray, lever: np.ndarray,
                  cum: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """The limits of every sample and the summed sphere travel, in one pass.

    Returns (first sample index out of [lower, upper] or -1 (1e-9 rad tolerance), rv, ra): rv, ra
    (n,) per joint max |qd| / vmax and max |qdd| / amax (NaN propagates, as in ``np.max``). Fills
    ``cum`` (K,): cum[0] = 0, cum[k] = cum[k-1] + travel(Q[k-1], Q[k]) (non-decreasing).
    """
    Kn, n = Q.shape
    first = -1
    rv = np.zeros(n)
    ra = np.zeros(n)
    acc = 0.0
    for k in range(Kn):
        tr = 0.0
        for j in range(n):
            x = Q[k, j]
            if first < 0 and (x < lower[j] - 1e-9 or x > upper[j] + 1e-9):
                first = k
            v = abs(QD[k, j]) / vmax[j]
            a = abs(QDD[k, j]) / amax[j]
            if v > rv[j] or v != v:
                rv[j] = v
            if a > ra[j] or a != a:
                ra[j] = a
            if k > 0:
                tr += lever[j] * abs(x - Q[k - 1, j])
        acc += tr
        cum[k] = acc
    return first, rv, ra


@njit(cache=True)
def _clear(Q: np.ndarray, k: int, W: tuple, T: np.ndarray, C: np.ndarray, G: np.ndarray, out: np.ndarray,
           cap: float) -> float:  # pragma: no cover - compiled
    K.sphere_centres(Q[k], W, T, C, G)
    return K.clearance(C, G, W, cap, -np.inf, out)


@njit(cache=True)
def span_clearance(Q: np.ndarray, cum: np.ndarray, lo: int, hi: int, W: tuple, T: np.ndarray, C: np.ndarray,
                   G: np.ndarray, out: np.ndarray, floor: float, cap: float,
                   best: float) -> tuple[float, int, int]:  # pragma: no cover - compiled
    """Smallest clearance in ``W`` over the samples Q[lo:hi] (hi > lo), with ``best`` the smallest so far.

    ``cum`` is the summed travel of :func:`limits_travel`. Returns (min(best, the smallest evaluated
    clearance), index of that sample or -1 when none was below ``best``, samples evaluated). Every
    skipped sample is proven >= min(the returned minimum, ``floor``) by the travel bound from its
    evaluated neighbours, so the result is exact whenever it is below ``floor``; clearances are
    capped at ``cap``. The first and the last sample are always evaluated.
    """
    worst = -1
    evals = 1
    ck = _clear(Q, lo, W, T, C, G, out, cap)
    if ck < best:
        best, worst = ck, lo
    st_a = np.empty(64, np.int64)  # the unresolved intervals (a, b), both ends evaluated
    st_b = np.empty(64, np.int64)
    st_ca = np.empty(64)
    st_cb = np.empty(64)
    k = lo
    while k < hi - 1:
        tau = min(best, floor)
        # the next sample at which an equal clearance would prove the whole interval from both sides
        j = int(np.searchsorted(cum, cum[k] + 2.0 * (ck - tau) - TRAVEL_EPS, side="right")) - 1
        j = min(max(j, k + 1), hi - 1)
        cj = _clear(Q, j, W, T, C, G, out, cap)
        evals += 1
        if cj < best:
            best, worst = cj, j
        top = 0
        st_a[0], st_b[0], st_ca[0], st_cb[0] = k, j, ck, cj
        top = 1
        while top > 0:
            top -= 1
            a, b, ca, cb = st_a[top], st_b[top], st_ca[top], st_cb[top]
            if b - a <= 1:
                continue
            tau = min(best, floor) + TRAVEL_EPS
            # proven from a: m <= f; proven from b: m >= g
            f = int(np.searchsorted(cum, cum[a] + ca - tau, side="right")) - 1
            g = int(np.searchsorted(cum, cum[b] - cb + tau, side="left"))
            if f + 1 >= g:
                continue
            lo_u, hi_u = max(f + 1, a + 1), min(g - 1, b - 1)
            if lo_u > hi_u:
                continue
            m = (lo_u + hi_u) // 2
            cm = _clear(Q, m, W, T, C, G, out, cap)
            evals += 1
            if cm < best:
                best, worst = cm, m
            if top + 2 > st_a.shape[0]:  # grow the stack (deep only on long stretches below the bound)
                st_a = np.concatenate((st_a, np.empty(st_a.shape[0], np.int64)))
                st_b = np.concatenate((st_b, np.empty(st_b.shape[0], np.int64)))
                st_ca = np.concatenate((st_ca, np.empty(st_ca.shape[0])))
                st_cb = np.concatenate((st_cb, np.empty(st_cb.shape[0])))
            st_a[top], st_b[top], st_ca[top], st_cb[top] = m, b, cm, cb
            top += 1
            st_a[top], st_b[top], st_ca[top], st_cb[top] = a, m, ca, cm
            top += 1
        k, ck = j, cj
    return best, worst, evals
