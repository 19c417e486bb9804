"""The clamped C2 cubic spline of a re-timed segment: knot velocities/accelerations and limit ratios.

The executable trajectory of a segment is the C2 cubic spline through ``(t_k, x_k)`` with zero
velocity at both ends (scipy's ``CubicSpline(..., bc_type="clamped")``). The compiled functions
here solve its moment equations by the Thomas algorithm (the same spline, microseconds per call)
and give the exact largest velocity and acceleration over the limits, used by temporal
optimization (7.7)-(7.9) to check and stretch each segment.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline

#: any numpy array (the compiled kernels take contiguous float64/int64/bool arrays)
Arr = NDArray[Any]

__all__ = ["clamped_spline_knots", "knot_ratios", "knot_ratios_scipy", "limit_stretch", "spline_segment"]


def spline_segment(t: np.ndarray, path: np.ndarray) -> CubicSpline:
    """The C2 cubic spline through the knots with zero velocity at both ends."""
    return CubicSpline(t, path, axis=0, bc_type="clamped")


def limit_stretch(spline: CubicSpline, duration: float, vmax: ArrayLike, amax: ArrayLike,
                  dt: float = 1e-3) -> float:
    """Uniform time factor s >= 1 so that the spline's |qd| <= vmax and |qdd| <= amax.

    Accelerations at the knots (exact, a cubic's acceleration is piecewise linear), velocities on a ``dt`` grid plus
    the knots and the interior extrema of each cubic piece.
    """
    knots = np.asarray(spline.x)
    ts = np.union1d(np.linspace(0.0, duration, max(int(np.ceil(duration / dt)) + 1, 2)), knots)
    # velocity extrema inside each piece: roots of the acceleration (linear per piece)
    a0 = spline(knots[:-1], 2)
    a1 = spline(knots[1:], 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = a0 / (a0 - a1)
    inside = (frac > 0) & (frac < 1)
    h = np.diff(knots)[:, None]
    t_ext = (knots[:-1, None] + frac * h)[inside]
    v = max(np.max(np.abs(spline(ts, 1)) / vmax),
            np.max(np.abs(spline(t_ext, 1)) / vmax, axis=None, initial=0.0) if t_ext.size else 0.0)
    amax_ratio = np.max(np.abs(spline(knots, 2)) / amax)
    return float(max(1.0, v, np.sqrt(amax_ratio)) * (1 + 1e-7))


@njit(cache=True)
def _clamped_moments(h: Arr, y: Arr, M: Arr, cp: Arr, dp: Arr) -> None:  # pragma: no cover - compiled
    """Knot second derivatives M (N+1, n) of the clamped C2 cubic spline (zero end slopes).

    Knot second derivatives M (N+1, n) of the clamped C2 cubic spline (zero end slopes) through y with interval
    lengths h (N,): the moment equations solved by the Thomas algorithm (sub- diagonal a, diagonal b, super-diagonal
    c, right-hand side r). cp, dp: (N+1,) work arrays.
    """
    N1, n = y.shape
    N = N1 - 1
    for j in range(n):
        for i in range(N1):
            if i == 0:
                a_, b_, c_ = 0.0, 2 * h[0], h[0]
                r_ = 6 * ((y[1, j] - y[0, j]) / h[0])
            elif i == N:
                a_, b_, c_ = h[N - 1], 2 * h[N - 1], 0.0
                r_ = -6 * ((y[N, j] - y[N - 1, j]) / h[N - 1])
            else:
                a_, b_, c_ = h[i - 1], 2 * (h[i - 1] + h[i]), h[i]
                r_ = 6 * ((y[i + 1, j] - y[i, j]) / h[i] - (y[i, j] - y[i - 1, j]) / h[i - 1])
            if i == 0:
                cp[0] = c_ / b_
                dp[0] = r_ / b_
            else:
                den = b_ - a_ * cp[i - 1]
                cp[i] = c_ / den
                dp[i] = (r_ - a_ * dp[i - 1]) / den
        M[N, j] = dp[N]
        for i in range(N - 1, -1, -1):
            M[i, j] = dp[i] - cp[i] * M[i + 1, j]


@njit(cache=True)
def _clamped_ratios(t: Arr, y: Arr, vmax: Arr, amax: Arr,  # pragma: no cover - compiled
                    sub: int) -> tuple[Arr, Arr]:
    """Limit ratios of the clamped C2 cubic spline at its knots and inside its pieces.

    Knot accelerations of the clamped C2 cubic spline (Thomas algorithm on the moment equations) over amax, and the
    largest |velocity| / vmax at ``sub - 1`` interior samples of each piece.
    """
    N1, n = y.shape
    N = N1 - 1
    h = np.empty(N)
    for i in range(N):
        h[i] = t[i + 1] - t[i]
    ra = np.zeros(N1)
    rv = np.zeros(N)
    M = np.empty((N1, n))
    cp = np.empty(N1)
    dp = np.empty(N1)
    _clamped_moments(h, y, M, cp, dp)
    for j in range(n):
        for i in range(N1):
            ra[i] = max(ra[i], abs(M[i, j]) / amax[j])
        for i in range(N):
            hi = h[i]
            slope = (y[i + 1, j] - y[i, j]) / hi - (M[i + 1, j] - M[i, j]) * hi / 6
            for k in range(1, sub):
                s = hi * k / sub
                v = -M[i, j] * (hi - s) ** 2 / (2 * hi) + M[i + 1, j] * s * s / (2 * hi) + slope
                rv[i] = max(rv[i], abs(v) / vmax[j])
    return ra, rv


@njit(cache=True)
def clamped_spline_knots(t: Arr, y: Arr, vmax: Arr,  # pragma: no cover - compiled
                         amax: Arr) -> tuple[Arr, Arr, float, float]:
    """Knot velocities and accelerations of the clamped C2 cubic spline and its exact peak limit ratios.

    Knot velocities V (N+1, n) and accelerations M (N+1, n) of the clamped C2 cubic spline through (t, y), and the
    exact largest |velocity| / vmax (knots and interior extrema of every piece) and |acceleration| / amax (at the
    knots: it is piecewise linear).
    """
    N1, n = y.shape
    N = N1 - 1
    M = np.empty((N1, n))
    V = np.empty((N1, n))
    cp = np.empty(N1)
    dp = np.empty(N1)
    rv = 0.0
    ra = 0.0
    h = np.empty(N)
    for i in range(N):
        h[i] = t[i + 1] - t[i]
    _clamped_moments(h, y, M, cp, dp)
    for j in range(n):
        for i in range(N):
            hi = t[i + 1] - t[i]
            slope = (y[i + 1, j] - y[i, j]) / hi
            V[i, j] = slope - hi * (2 * M[i, j] + M[i + 1, j]) / 6
            if i == N - 1:
                V[N, j] = slope + hi * (M[i, j] + 2 * M[i + 1, j]) / 6
            rv = max(rv, abs(V[i, j]) / vmax[j])
            dm = M[i, j] - M[i + 1, j]
            if dm != 0.0:
                s = hi * M[i, j] / dm
                if 0.0 < s < hi:
                    v = -M[i, j] * (hi - s) ** 2 / (2 * hi) + M[i + 1, j] * s * s / (2 * hi) + slope \
                        - (M[i + 1, j] - M[i, j]) * hi / 6
                    rv = max(rv, abs(v) / vmax[j])
        rv = max(rv, abs(V[N, j]) / vmax[j])
        for i in range(N1):
            ra = max(ra, abs(M[i, j]) / amax[j])
    return V, M, rv, ra


def knot_ratios(t: np.ndarray, path: np.ndarray, vmax: np.ndarray, amax: np.ndarray,
                sub: int = 8) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Spline acceleration / limit at each knot (exact.

    A cubic's acceleration is piecewise linear) and the largest velocity / limit inside each interval (sampled at
    ``sub - 1`` interior points) of the clamped spline :func:`spline_segment` (compiled, same spline as scipy's).
    """
    return _clamped_ratios(np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(path, dtype=float),
                           np.asarray(vmax, float), np.asarray(amax, float), int(sub))


def knot_ratios_scipy(t: np.ndarray, path: np.ndarray, vmax: np.ndarray, amax: np.ndarray,
                      sub: int = 8) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Reference implementation of :func:`knot_ratios` with scipy's CubicSpline (for tests)."""
    s = spline_segment(t, path)
    ra = np.max(np.abs(s(t, 2)) / amax, axis=1)
    u = (np.arange(1, sub) / sub)
    ts = (t[:-1, None] + np.diff(t)[:, None] * u[None]).ravel()
    rv = np.max(np.abs(s(ts, 1)) / vmax, axis=1).reshape(len(t) - 1, sub - 1).max(1)
    return ra, rv
