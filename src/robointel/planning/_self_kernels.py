"""Compiled (numba) self-collision clearances of sphere pairs with their gradients, for CFS.

For each configuration b and pair p = (i, k): d = ||c_i - c_k|| - r_i - r_k and its gradient
u^T (J_i - J_k), u the unit vector from sphere k to sphere i (:func:`robointel.planning.segment.self_clearances`).
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _offset(C: np.ndarray, s: int, i: int, k: int) -> tuple[float, float, float, float]:  # pragma: no cover
    """(c_i - c_k, ||c_i - c_k||) at configuration s of the centres C (B, m, 3)."""
    v0 = C[s, i, 0] - C[s, k, 0]
    v1 = C[s, i, 1] - C[s, k, 1]
    v2 = C[s, i, 2] - C[s, k, 2]
    return v0, v1, v2, (v0 * v0 + v1 * v1 + v2 * v2) ** 0.5


@njit(cache=True)
def pair_clearances(C: np.ndarray, J: np.ndarray, a: np.ndarray, b: np.ndarray, radii: np.ndarray, d: np.ndarray,
                    g: np.ndarray) -> None:  # pragma: no cover - compiled
    """Fill d (B, P) and g (B, P, n) from sphere centres C (B, m, 3) and linear Jacobians J (B, m, 3, n)."""
    B, P = d.shape
    n = J.shape[3]
    for s in range(B):
        for p in range(P):
            i, k = a[p], b[p]
            v0, v1, v2, L = _offset(C, s, i, k)
            d[s, p] = L - radii[i] - radii[k]
            if L < 1e-12:
                v0, v1, v2, L = 0.0, 0.0, 1.0, 1.0
            v0, v1, v2 = v0 / L, v1 / L, v2 / L
            for j in range(n):
                g[s, p, j] = (v0 * (J[s, i, 0, j] - J[s, k, 0, j]) + v1 * (J[s, i, 1, j] - J[s, k, 1, j])
                              + v2 * (J[s, i, 2, j] - J[s, k, 2, j]))


@njit(cache=True)
def pair_distances(C: np.ndarray, a: np.ndarray, b: np.ndarray, radii: np.ndarray,
                   d: np.ndarray) -> None:  # pragma: no cover - compiled
    """Fill d (B, P) from sphere centres C (B, m, 3): :func:`pair_clearances` without the gradients."""
    B, P = d.shape
    for s in range(B):
        for p in range(P):
            i, k = a[p], b[p]
            d[s, p] = _offset(C, s, i, k)[3] - radii[i] - radii[k]
