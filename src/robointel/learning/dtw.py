"""Dynamic time warping (5.1)-(5.6), multi-dimensional, Sakoe-Chiba band, compiled with numba.

For two series ``a`` (n, d) and ``b`` (m, d) the local cost is the squared Euclidean distance
``c(i, j) = ||a_i - b_j||^2`` (5.1); the accumulated cost obeys the recursion (5.2)-(5.3)

    D(i, j) = c(i, j) + min(D(i-1, j-1), D(i-1, j), D(i, j-1)),   D(-1, -1) = 0,

restricted to the Sakoe-Chiba band (5.4); the DTW distance is ``sqrt(D(n-1, m-1))`` and the warping
path the back-tracked minimum (5.5). Demonstrations are synchronised by warping each one onto a
reference demonstration's time axis (5.6).

The band and the distance follow ``dtaidistance``'s definitions exactly (``window`` = the maximal
shift from the two diagonals: for row ``i`` the columns ``max(0, i - max(0, n - m) - window + 1) <=
j < min(m, i + max(0, m - n) + window)``; result is the square root of the summed squared Euclidean
costs), so the two agree to rounding.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from robointel._validate import as_array
from robointel.errors import InvalidInput, ShapeError

#: any numpy array (the compiled kernels take contiguous float64/int64/bool arrays)
Arr = NDArray[Any]


@numba.njit(cache=True, nogil=True)
def _band(i: int, n: int, m: int, window: int) -> tuple[int, int]:
    lo = max(0, i - max(0, n - m) - window + 1)
    hi = min(m, i + max(0, m - n) + window)
    return lo, hi


@numba.njit(cache=True, nogil=True, error_model="numpy", boundscheck=False)
def _dtw_distance_sq(a: Arr, b: Arr, window: int) -> float:
    """Two rolling rows in padded indexing: row[j + 1] = D(i, j), row[0] = D(i, -1)."""
    n, d = a.shape
    m = b.shape[0]
    prev = np.full(m + 1, np.inf)
    cur = np.full(m + 1, np.inf)
    prev[0] = 0.0  # D(-1, -1) = 0
    for i in range(n):
        lo, hi = _band(i, n, m, window)
        cur[lo] = np.inf  # column lo - 1 is outside this row's band
        left = np.inf
        diag = prev[lo]
        ai = a[i]
        for j in range(lo, hi):
            bj = b[j]
            c = 0.0
            for k in range(d):
                t = ai[k] - bj[k]
                c += t * t
            up = prev[j + 1]
            best = diag
            if up < best:
                best = up
            if left < best:
                best = left
            left = c + best
            cur[j + 1] = left
            diag = up
        prev, cur = cur, prev
    return float(prev[m])


@numba.njit(cache=True, nogil=True)
def _dtw_matrix(a: Arr, b: Arr, window: int) -> tuple[Arr, Arr, Arr]:
    """Accumulated cost over the band, stored row-wise as (n, width) with column offset lo(i)."""
    n, d = a.shape
    m = b.shape[0]
    width = min(m, abs(n - m) + 2 * window)
    acc = np.full((n, width + 1), np.inf)
    los = np.empty(n, np.int64)
    his = np.empty(n, np.int64)
    for i in range(n):
        lo, hi = _band(i, n, m, window)
        los[i] = lo
        his[i] = hi
        for j in range(lo, hi):
            c = 0.0
            for k in range(d):
                t = a[i, k] - b[j, k]
                c += t * t
            if i == 0 and j == 0:
                best = 0.0
            else:
                best = np.inf
                if i > 0:
                    plo = los[i - 1]
                    if j - 1 >= plo and j - 1 < his[i - 1]:
                        best = acc[i - 1, j - 1 - plo]
                    if j >= plo and j < his[i - 1] and acc[i - 1, j - plo] < best:
                        best = acc[i - 1, j - plo]
                if j > lo and acc[i, j - 1 - lo] < best:
                    best = acc[i, j - 1 - lo]
            acc[i, j - lo] = c + best
    return acc, los, his


@numba.njit(cache=True, nogil=True)
def _get(acc: Arr, los: Arr, his: Arr, i: int, j: int) -> float:
    if i < 0 or j < 0:
        return np.inf
    if j < los[i] or j >= his[i]:
        return np.inf
    return acc[i, j - los[i]]


@numba.njit(cache=True, nogil=True)
def _backtrack(acc: Arr, los: Arr, his: Arr, n: int, m: int) -> Arr:
    path = np.empty((n + m, 2), np.int64)
    i, j = n - 1, m - 1
    k = 0
    path[k, 0] = i
    path[k, 1] = j
    k += 1
    while i > 0 or j > 0:
        if i == 0:
            j -= 1
        elif j == 0:
            i -= 1
        else:
            d0 = _get(acc, los, his, i - 1, j - 1)
            d1 = _get(acc, los, his, i - 1, j)
            d2 = _get(acc, los, his, i, j - 1)
            if d0 <= d1 and d0 <= d2:
                i -= 1
                j -= 1
            elif d1 <= d2:
                i -= 1
            else:
                j -= 1
        path[k, 0] = i
        path[k, 1] = j
        k += 1
    return path[:k][::-1].copy()


def _prep(a: ArrayLike, b: ArrayLike,
          window: int | None) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    a = as_array(a, "a")
    b = as_array(b, "b")
    if a.ndim == 1:
        a = a[:, None]
    if b.ndim == 1:
        b = b[:, None]
    if a.ndim != 2 or b.ndim != 2:
        raise ShapeError(f"series must be (N,) or (N, d), got {a.shape} and {b.shape}")
    if a.shape[1] != b.shape[1]:
        raise ShapeError(f"series have different dimensions: {a.shape[1]} vs {b.shape[1]}; "
                         "DTW compares samples of equal dimension", value=(a.shape, b.shape))
    if a.shape[0] == 0 or b.shape[0] == 0:
        raise ShapeError("series must not be empty")
    n, m = a.shape[0], b.shape[0]
    if window is None:
        w = max(n, m)
    else:
        w = int(window)
        if w < 1:
            raise InvalidInput(f"window must be a positive number of samples, got {window}", value=window)
    return np.ascontiguousarray(a), np.ascontiguousarray(b), w


def dtw_distance(a: ArrayLike, b: ArrayLike, *, window: int | None = None) -> float:
    """DTW distance (5.1)-(5.4) between ``a`` (n, d) and ``b`` (m, d) (1-D series allowed).

    Args:
        a: (n,) or (n, d) series; samples are compared with the Euclidean norm.
        b: (m,) or (m, d) series of the same dimension d.
        window: Sakoe-Chiba band half-width r in samples (None = unconstrained).

    Returns:
        ``sqrt`` of the minimal summed squared Euclidean cost (same as ``dtaidistance.dtw_ndim.distance``).

    Raises:
        ShapeError: different dimensions or empty series. NotFinite: NaN/inf samples.
    """
    a, b, w = _prep(a, b, window)
    return float(np.sqrt(_dtw_distance_sq(a, b, w)))


@dataclass(frozen=True)
class DTWResult:
    """DTW distance and warping path.

    ``distance`` (float) and warping ``path`` (K, 2) of index pairs (i into a, j into b), monotone, from (0, 0) to
    (n-1, m-1).
    """

    distance: float
    path: np.ndarray


def dtw(a: ArrayLike, b: ArrayLike, *, window: int | None = None) -> DTWResult:
    """DTW distance and warping path (5.5) between ``a`` (n, d) and ``b`` (m, d)."""
    a, b, w = _prep(a, b, window)
    acc, los, his = _dtw_matrix(a, b, w)
    path = _backtrack(acc, los, his, a.shape[0], b.shape[0])
    return DTWResult(float(np.sqrt(acc[-1, b.shape[0] - 1 - los[-1]])), path)


def warp_to(series: ArrayLike, reference: ArrayLike, *, window: int | None = None) -> np.ndarray:
    """Warp ``series`` (n, d) onto the time axis of ``reference`` (m, d) (5.6).

    Sample j of the result is the mean of the series samples the warping path matches to reference sample j.

    Returns:
        (m, d) array (or (m,) for 1-D input).
    """
    s = as_array(series, "series")
    res = dtw(s, reference, window=window)
    s2 = s[:, None] if s.ndim == 1 else s
    m = np.asarray(reference).shape[0]
    sums = np.zeros((m, s2.shape[1]))
    counts = np.zeros(m)
    np.add.at(sums, res.path[:, 1], s2[res.path[:, 0]])
    np.add.at(counts, res.path[:, 1], 1.0)
    out = sums / counts[:, None]
    return out[:, 0] if s.ndim == 1 else out


def align(series: Sequence, reference: int | np.ndarray = 0, *, window: int | None = None,
          columns: slice | np.ndarray | None = None) -> list[np.ndarray]:
    """Synchronise many demonstrations to one reference (5.6).

    Args:
        series: list of (n_i, d) arrays.
        reference: index into ``series`` or an (m, d) array chosen by the user.
        window: Sakoe-Chiba band (samples); must cover the length differences.
        columns: the feature columns used for matching (all by default); every column is warped.

    Returns:
        list of (m, d) arrays on the reference time axis.

    Raises:
        ShapeError: demonstrations of different dimensions.
    """
    if len(series) == 0:
        raise InvalidInput("align needs at least one series")
    arrs = [as_array(s, f"series[{k}]") for k, s in enumerate(series)]
    arrs = [a[:, None] if a.ndim == 1 else a for a in arrs]
    dims = {a.shape[1] for a in arrs}
    if len(dims) != 1:
        raise ShapeError(f"demonstrations have different dimensions {sorted(dims)}", value=sorted(dims))
    ref = arrs[int(reference)] if np.isscalar(reference) else as_array(reference, "reference")  # type: ignore[arg-type]
    ref = ref[:, None] if ref.ndim == 1 else ref
    if ref.shape[1] != arrs[0].shape[1]:
        raise ShapeError(f"reference has dimension {ref.shape[1]}, series {arrs[0].shape[1]}")
    cols = slice(None) if columns is None else columns
    out = []
    for a in arrs:
        res = dtw(a[:, cols], ref[:, cols], window=window)
        sums = np.zeros((ref.shape[0], a.shape[1]))
        counts = np.zeros(ref.shape[0])
        np.add.at(sums, res.path[:, 1], a[res.path[:, 0]])
        np.add.at(counts, res.path[:, 1], 1.0)
        out.append(sums / counts[:, None])
    return out
