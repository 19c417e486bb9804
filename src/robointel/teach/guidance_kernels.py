"""Compiled kernels of the guidance controller's 1 kHz loop (4.1)-(4.11).

Wrench checks and lead-twist filtering, the QP terms of (4.11), the active constraint rows and the
soft minimum of the distances: numba-compiled, with preallocated outputs written in place, so one
control step costs microseconds. Used by :class:`robointel.teach.guidance.GuidanceController`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

#: any numpy array (the compiled kernels take contiguous float64/int64/bool arrays)
Arr = NDArray[Any]

__all__ = ["active_rows", "check_wrench", "filter_lead", "qp_terms", "soft_min"]


@njit(cache=True)
def active_rows(dk: Arr, G: Arr, d0: float, x: Arr, A: Arr) -> tuple[int, bool]:  # pragma: no cover - compiled
    """Copy the rows G[k] of obstacles with dk[k] < d0 into A[:nact].

    Return nact and whether x satisfies all of them (A x >= 0).
    """
    K, n = G.shape
    nact = 0
    feasible = True
    for k in range(K):
        if dk[k] < d0:
            s = 0.0
            for j in range(n):
                A[nact, j] = G[k, j]
                s += G[k, j] * x[j]
            if s < 0.0:
                feasible = False
            nact += 1
    return nact, feasible


@njit(cache=True)
def check_wrench(w: Arr, last: Arr, has_last: bool, max_f: float,  # pragma: no cover - compiled
                  max_t: float, spike_f: float, spike_t: float) -> tuple[int, float, float]:
    """(code, a, b): 0 usable; 1 NaN/inf; 2 out of range (|f|, |tau|); 3 spike (|df|, |dtau|)."""
    for i in range(6):
        if not np.isfinite(w[i]):
            return 1, 0.0, 0.0
    f = np.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    t = np.sqrt(w[3] * w[3] + w[4] * w[4] + w[5] * w[5])
    if f > max_f or t > max_t:
        return 2, f, t
    if has_last:
        a = w[0] - last[0]
        b = w[1] - last[1]
        c = w[2] - last[2]
        df = np.sqrt(a * a + b * b + c * c)
        a = w[3] - last[3]
        b = w[4] - last[4]
        c = w[5] - last[5]
        dt = np.sqrt(a * a + b * b + c * c)
        if df > spike_f or dt > spike_t:
            return 3, df, dt
    return 0, 0.0, 0.0


@njit(cache=True)
def filter_lead(w: Arr, wf: Arr, beta: float, first: bool, par: Arr, V: Arr) -> None:  # pragma: no cover - compiled
    """Low-pass the wrench into wf (in place) and write V = C F (3.11) with deadbands and speed limits.

    par = [band_f, band_t, K_d, K_r, v_max, w_max].
    """
    for i in range(6):
        wf[i] = w[i] if first else wf[i] + beta * (w[i] - wf[i])
    for o in (0, 3):
        band, gain, vmax = (par[0], par[2], par[4]) if o == 0 else (par[1], par[3], par[5])
        nx = np.sqrt(wf[o] * wf[o] + wf[o + 1] * wf[o + 1] + wf[o + 2] * wf[o + 2])
        if nx <= band:
            V[o] = V[o + 1] = V[o + 2] = 0.0
        else:
            sc = min(gain * (nx - band), vmax) / nx
            V[o] = wf[o] * sc
            V[o + 1] = wf[o + 1] * sc
            V[o + 2] = wf[o + 2] * sc


@njit(cache=True)
def qp_terms(J: Arr, W: Arr, V: Arr, par: Arr, q: Arr, lower: Arr, upper: Arr,  # pragma: no cover - compiled
              vmax: Arr, H: Arr, f: Arr, lb: Arr, ub: Arr, x: Arr) -> bool:
    """Cost of (4.11).

    H = J^T W J + mu I (mu grows near singularities), f = -J^T W V; joint bounds containing 0; x = the unconstrained
    minimiser. Returns whether x is within the bounds. par = [mu_0, epsilon^2, lambda_max^2, k_limit].
    """
    n = J.shape[1]
    for i in range(n):
        s = 0.0
        for r in range(6):
            s -= J[r, i] * W[r] * V[r]
        f[i] = s
        for j in range(i, n):
            s = 0.0
            for r in range(6):
                s += J[r, i] * W[r] * J[r, j]
            H[i, j] = s
            H[j, i] = s
    smin2 = max(np.linalg.eigvalsh(H)[0], 0.0)
    mu = par[0]
    if smin2 < par[1]:
        mu += par[2] * (1.0 - smin2 / par[1])
    for i in range(n):
        H[i, i] += mu
    x[:] = np.linalg.solve(H, -f)
    inside = True
    k = par[3]
    for i in range(n):
        u = min(vmax[i], max(0.0, k * (upper[i] - q[i])))
        l = max(-vmax[i], min(0.0, k * (lower[i] - q[i])))
        ub[i] = u
        lb[i] = l
        if x[i] > u or x[i] < l:
            inside = False
    return inside


@njit(cache=True)
def soft_min(D: Arr, G3: Arr, beta: float, dk: Arr, dh: Arr, rows: Arr, G: Arr) -> None:  # pragma: no cover - compiled
    """Per obstacle k.

    Hard minimum dh[k] over control points (row rows[k]), the smooth minimum dk[k] = dh - log(sum exp(-beta (d -
    dh))) / beta and its gradient G[k] (softmax-weighted rows of G3 (m, K, n)); beta = 0 takes the hard minimum's
    row.
    """
    m, K = D.shape
    n = G3.shape[2]
    for k in range(K):
        i0 = 0
        for i in range(1, m):
            if D[i, k] < D[i0, k]:
                i0 = i
        rows[k] = i0
        dh[k] = D[i0, k]
        if beta <= 0.0:
            dk[k] = dh[k]
            for j in range(n):
                G[k, j] = G3[i0, k, j]
            continue
        S = 0.0
        for j in range(n):
            G[k, j] = 0.0
        for i in range(m):
            e = np.exp(-beta * (D[i, k] - dh[k]))
            S += e
            for j in range(n):
                G[k, j] += e * G3[i, k, j]
        for j in range(n):
            G[k, j] /= S
        dk[k] = dh[k] - np.log(S) / beta
