"""Time-optimal parametrisation of a joint path under velocity and acceleration limits (TOPP).

The path is a C2 cubic spline q(s) through points spaced along the planner's polyline (at most
``step`` rad apart per joint, so the spline stays close to the checked edges), with s the chord
length. Along it, with x = sdot^2 and u = sddot, the limits are

    x |q'_j(s)|^2 <= vmax_j^2,        -amax_j <= q'_j(s) u + q''_j(s) x <= amax_j,

linear in (x, u) at every point of a grid s_0..s_N. With x_{i+1} = x_i + 2 (s_{i+1} - s_i) u_i
(u constant between grid points), the largest x at each grid point from which the end can still be
reached at rest is found by a backward pass (a two-variable linear programme per point: every lower
bound on u below every upper bound), and the fastest schedule by the forward pass that takes the
largest admissible u from rest (the reachability analysis of TOPP-RA, Pham & Pham 2018, for box
limits). The result is sampled every ``dt`` with exact q, qdot = q' sdot, qddot = q' sddot + q'' sdot^2;
the schedule is stretched uniformly when those samples exceed a limit between grid points.
"""
from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

from robointel._validate import as_array
from robointel.errors import InvalidInput
from robointel.trajectory import Trajectory

__all__ = ["topp_spline", "densify", "natural_spline"]

#: grid points per spline knot interval (at least)
GRID_PER_KNOT = 32
#: the limits the grid schedule aims at (samples between grid points may exceed them slightly)
GRID_MARGIN = 1.0


def densify(path: npt.ArrayLike, step: float) -> np.ndarray:
    """The polyline ``path`` (K, n) with points inserted so no joint moves more than ``step`` rad."""
    P = np.asarray(path, float)
    if len(P) < 2:
        return P.copy()
    D = P[1:] - P[:-1]
    ks = np.maximum(1, np.ceil(np.max(np.abs(D), axis=1) / step)).astype(np.int64)
    e = np.repeat(np.arange(len(D)), ks)  # the edge of every new point
    first = np.cumsum(ks) - ks
    f = (np.arange(len(e)) - first[e] + 1) / ks[e]  # its fraction 1/k .. k/k along the edge
    return np.concatenate([P[:1], P[:-1][e] + D[e] * f[:, None]])


@njit(cache=True)
def natural_spline(x: np.ndarray, y: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """The natural cubic spline through (x_k, y_k): coefficients c (4, K, n) on the K intervals.

    On [x_k, x_{k+1}], with z = s - x_k, y(s) = ((c0 z + c1) z + c2) z + c3 (scipy's ``PPoly``
    layout, as ``CubicSpline(x, y, bc_type="natural").c``). The second derivatives M solve the
    tridiagonal system h_{k-1} M_{k-1} + 2 (h_{k-1} + h_k) M_k + h_k M_{k+1} = 6 (slope_k -
    slope_{k-1}) with M_0 = M_K = 0 (Thomas' algorithm). x (K+1,) strictly increasing, y (K+1, n).
    """
    K = x.shape[0] - 1
    n = y.shape[1]
    M = np.zeros((K + 1, n))
    if K >= 2:
        cp = np.empty(K + 1)  # forward sweep: M_k = dp_k - cp_k M_{k+1}
        dp = np.zeros((K + 1, n))
        for k in range(1, K):
            h0, h1 = x[k] - x[k - 1], x[k + 1] - x[k]
            den = 2.0 * (h0 + h1) - (h0 * cp[k - 1] if k > 1 else 0.0)
            cp[k] = h1 / den
            for j in range(n):
                r = 6.0 * ((y[k + 1, j] - y[k, j]) / h1 - (y[k, j] - y[k - 1, j]) / h0)
                dp[k, j] = (r - (h0 * dp[k - 1, j] if k > 1 else 0.0)) / den
        for j in range(n):
            M[K - 1, j] = dp[K - 1, j]
        for k in range(K - 2, 0, -1):
            for j in range(n):
                M[k, j] = dp[k, j] - cp[k] * M[k + 1, j]
    c = np.empty((4, K, n))
    for k in range(K):
        h = x[k + 1] - x[k]
        for j in range(n):
            c[0, k, j] = (M[k + 1, j] - M[k, j]) / (6.0 * h)
            c[1, k, j] = 0.5 * M[k, j]
            c[2, k, j] = (y[k + 1, j] - y[k, j]) / h - h * (2.0 * M[k, j] + M[k + 1, j]) / 6.0
            c[3, k, j] = y[k, j]
    return c


@njit(cache=True)
def _grid_derivatives(knots: np.ndarray, c: np.ndarray,
                      per: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """The grid s (``per`` points per knot interval, and the last knot) with q'(s), q''(s) there."""
    K, n = c.shape[1], c.shape[2]
    N = K * per
    s = np.empty(N + 1)
    d1 = np.empty((N + 1, n))
    d2 = np.empty((N + 1, n))
    for m in range(N + 1):
        k = min(m // per, K - 1)
        h = knots[k + 1] - knots[k]
        z = h * ((m - k * per) / per)
        s[m] = knots[k] + z if m < N else knots[K]
        for j in range(n):
            d1[m, j] = (3.0 * c[0, k, j] * z + 2.0 * c[1, k, j]) * z + c[2, k, j]
            d2[m, j] = 6.0 * c[0, k, j] * z + 2.0 * c[1, k, j]
    return s, d1, d2


@njit(cache=True)
def _lines(cu: np.ndarray, cx: np.ndarray, amax: np.ndarray, lo_p: np.ndarray, lo_m: np.ndarray,
           up_p: np.ndarray, up_m: np.ndarray, m: int) -> tuple[int, float]:  # pragma: no cover - compiled
    """Append the u-bounds of -amax <= cu u + cx x <= amax as lines u >= p + m x, u <= p + m x.

    Returns the new line count and the cap on x of joints with cu = 0.
    """
    xcap = np.inf
    for j in range(cu.shape[0]):
        a, b, A = cu[j], cx[j], amax[j]
        if abs(a) < 1e-12:
            if abs(b) > 1e-12:
                xcap = min(xcap, A / abs(b))
            continue
        lo, up = (-A / a, A / a) if a > 0 else (A / a, -A / a)
        lo_p[m], lo_m[m] = lo, -b / a
        up_p[m], up_m[m] = up, -b / a
        m += 1
    return m, xcap


@njit(cache=True)
def _interval(dq: np.ndarray, ddq: np.ndarray, i: int, h: float, amax: np.ndarray, cu: np.ndarray,
              lo_p: np.ndarray, lo_m: np.ndarray, up_p: np.ndarray,
              up_m: np.ndarray) -> tuple[int, float]:  # pragma: no cover - compiled
    """Lines of the acceleration limits of interval i at both ends (x = x_i, x_{i+1} = x_i + 2 h u)."""
    m, c0 = _lines(dq[i], ddq[i], amax, lo_p, lo_m, up_p, up_m, int(np.int64(0)))  # int64, not a literal 0
    for j in range(cu.shape[0]):
        cu[j] = dq[i + 1, j] + 2.0 * h * ddq[i + 1, j]
    m, c1 = _lines(cu, ddq[i + 1], amax, lo_p, lo_m, up_p, up_m, m)
    return m, min(c0, c1)


@njit(cache=True)
def topp_grid(s: np.ndarray, dq: np.ndarray, ddq: np.ndarray, vmax: np.ndarray,
              amax: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:  # pragma: no cover - compiled
    """Backward/forward passes on the grid ``s`` (N+1,) with q' and q'' (N+1, n) there.

    The acceleration limits hold at both ends of every interval (u constant on it). Returns
    (x, u, ok): x = sdot^2 (N+1,), u = sddot (N,) per interval, ok False when the motion stalls.
    """
    N = s.shape[0] - 1
    n = dq.shape[1]
    lo_p, lo_m = np.empty(2 * n + 1), np.empty(2 * n + 1)
    up_p, up_m = np.empty(2 * n + 1), np.empty(2 * n + 1)
    cu = np.empty(n)
    xv = np.empty(N + 1)
    for i in range(N + 1):
        c = np.inf
        for j in range(n):
            a = abs(dq[i, j])
            if a > 1e-12:
                c = min(c, (vmax[j] / a) ** 2)
        xv[i] = c
    K = np.empty(N + 1)
    K[N] = 0.0
    for i in range(N - 1, -1, -1):
        h = s[i + 1] - s[i]
        m, xcap = _interval(dq, ddq, i, h, amax, cu, lo_p, lo_m, up_p, up_m)
        # reach the controllable set of i+1: u <= (K - x) / 2h and u >= -x / 2h
        up_p[m], up_m[m] = K[i + 1] / (2 * h), -1.0 / (2 * h)
        lo_p[m], lo_m[m] = 0.0, -1.0 / (2 * h)
        hi = min(xv[i], xcap)
        # the admissible x form an interval [0, x*] (x = 0 admits u = 0): when x = hi admits a u, x* >= hi
        # and no pair of lines can lower it; only otherwise the crossings of every lower with every upper line
        lb, ub = -np.inf, np.inf
        for p in range(m + 1):
            lb = max(lb, lo_p[p] + lo_m[p] * hi)
            ub = min(ub, up_p[p] + up_m[p] * hi)
        if not (lb <= ub):
            for p in range(m + 1):
                for q in range(m + 1):
                    dm = lo_m[p] - up_m[q]
                    if dm > 1e-15:
                        hi = min(hi, (up_p[q] - lo_p[p]) / dm)
        K[i] = max(hi, 0.0)
    x = np.zeros(N + 1)
    u = np.zeros(N)
    for i in range(N):
        h = s[i + 1] - s[i]
        m, _ = _interval(dq, ddq, i, h, amax, cu, lo_p, lo_m, up_p, up_m)
        ub = (K[i + 1] - x[i]) / (2 * h)
        for p in range(m):
            ub = min(ub, up_p[p] + up_m[p] * x[i])
        x[i + 1] = min(max(x[i] + 2 * h * ub, 0.0), K[i + 1])
        u[i] = (x[i + 1] - x[i]) / (2 * h)
    ok = True
    for i in range(1, N):
        if x[i] <= 0.0:
            ok = False
    return x, u, ok


@njit(cache=True)
def _sample(ts: np.ndarray, tg: np.ndarray, s: np.ndarray, sd: np.ndarray, u: np.ndarray, xk: np.ndarray,
            c: np.ndarray, vmax: np.ndarray, amax: np.ndarray, Q: np.ndarray, QD: np.ndarray,
            QDD: np.ndarray) -> float:  # pragma: no cover - compiled
    """Sample the schedule at times ``ts`` along the spline (knots ``xk``, coefficients ``c`` (4, k, n)).

    Fills Q, QD, QDD (len(ts), n) and returns the largest of max |qd| / vmax and sqrt(max |qdd| / amax).
    """
    n = Q.shape[1]
    N = u.shape[0]
    nk = xk.shape[0] - 1
    i, k = 0, 0
    mv, ma = np.zeros(n), np.zeros(n)  # per joint max |qd|, |qdd| (divided by the limits once, at the end)
    for m in range(ts.shape[0]):
        t = ts[m]
        while i < N - 1 and tg[i + 1] <= t:
            i += 1
        tau = t - tg[i]
        sdm = max(sd[i] + u[i] * tau, 0.0)
        sm = min(s[i] + sd[i] * tau + 0.5 * u[i] * tau * tau, s[-1])
        while k < nk - 1 and xk[k + 1] <= sm:
            k += 1
        z = sm - xk[k]
        for j in range(n):
            c0, c1, c2, c3 = c[0, k, j], c[1, k, j], c[2, k, j], c[3, k, j]
            d1 = (3.0 * c0 * z + 2.0 * c1) * z + c2
            d2 = 6.0 * c0 * z + 2.0 * c1
            Q[m, j] = ((c0 * z + c1) * z + c2) * z + c3
            vd = d1 * sdm
            ad = d1 * u[i] + d2 * sdm * sdm
            QD[m, j] = vd
            QDD[m, j] = ad
            mv[j] = max(mv[j], abs(vd))
            ma[j] = max(ma[j], abs(ad))
    rv, ra = 0.0, 0.0
    for j in range(n):  # max_m |x_m| / lim == max_m (|x_m| / lim): division by a positive number is monotone
        rv = max(rv, mv[j] / vmax[j])
        ra = max(ra, ma[j] / amax[j])
    return max(rv, math.sqrt(ra))


@njit(cache=True)
def _merge_times(tg: np.ndarray, step: float, gap: float) -> np.ndarray:  # pragma: no cover - compiled
    """The regular times k * step below tg[-1] not within ``gap`` of a grid time, merged with ``tg``."""
    N = tg.shape[0]
    T = tg[N - 1]
    nreg = int(math.ceil(T / step)) + 1
    out = np.empty(nreg + N)
    m, j = 0, 0
    for k in range(nreg):
        t = k * step
        if t >= T:
            break
        while j < N and tg[j] < t:  # grid times before t go first
            out[m] = tg[j]
            m += 1
            j += 1
        near = (j < N and tg[j] - t < gap) or (j > 0 and t - tg[j - 1] < gap)
        if not near:
            out[m] = t
            m += 1
    while j < N:
        out[m] = tg[j]
        m += 1
        j += 1
    return out[:m]


def _times(tg: np.ndarray, dt: float) -> np.ndarray:
    """Sample times: every ``dt`` and at every grid time ``tg`` (where the acceleration switches).

    With a sample at every switch, each sample interval lies on one grid interval, where the motion
    is smooth, so an interpolation of the samples (a cubic Hermite through q, qd) keeps the
    accelerations of the schedule. Regular samples (every 0.95 dt) closer than dt / 25 to a grid
    time are dropped, so no two samples are more than dt apart. ``tg`` must increase strictly.
    """
    return _merge_times(np.ascontiguousarray(tg, dtype=float), 0.95 * dt, dt / 25)


def topp_spline(path: npt.ArrayLike, vmax: npt.ArrayLike, amax: npt.ArrayLike, *, step: float = 0.1,
                dt: float = 1e-3, joint_names: list[str] | None = None) -> Trajectory:
    """Time-optimal motion from rest to rest along a spline through the polyline ``path``.

    Args:
        path: (K, n) vertices, rad (K >= 2).
        vmax: (n,) velocity limits, rad/s.
        amax: (n,) acceleration limits, rad/s^2.
        step: largest joint step between the spline's knots along the polyline, rad.
        dt: sampling step of the result, s.
        joint_names: names of the n joints.

    Returns:
        The trajectory sampled at most ``dt`` apart (and where the path acceleration switches),
        exact q, qd, qdd along the spline, within the limits at every sample; ``meta["timing"]``
        says how it was made.

    Raises:
        InvalidInput: bad shapes, non-positive limits, step or dt, or a path without length.
    """
    P = as_array(path, "path", (None, None))
    n = P.shape[1]
    vmax, amax = as_array(vmax, "vmax", (n,)), as_array(amax, "amax", (n,))
    if np.any(vmax <= 0) or np.any(amax <= 0) or not (dt > 0 and step > 0) or len(P) < 2:
        raise InvalidInput("TOPP needs >= 2 points, positive limits, step and dt", value=(vmax, amax, step, dt))
    keep = np.concatenate([[True], np.linalg.norm(np.diff(P, axis=0), axis=1) > 1e-12])
    P = densify(P[keep], step)
    if len(P) < 2:
        raise InvalidInput("the path has no length", value=path)
    knots = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    c = natural_spline(knots, np.ascontiguousarray(P))
    s, d1, d2 = _grid_derivatives(knots, c, GRID_PER_KNOT)  # GRID_PER_KNOT points per knot interval
    x, u, ok = topp_grid(s, d1, d2, GRID_MARGIN * vmax, GRID_MARGIN * amax)
    if not ok:
        raise InvalidInput("TOPP: the path admits no motion (a joint's derivative is not finite)", value=path)
    sd = np.sqrt(x)
    tg = np.concatenate([[0.0], np.cumsum(2 * np.diff(s) / (sd[:-1] + sd[1:]))])
    ratio = 1.0
    for _ in range(3):  # stretch uniformly until the samples between grid points are within the limits
        ts = _times(tg, dt / ratio)
        q, qd, qdd = (np.empty((len(ts), n)) for _ in range(3))
        r = _sample(ts, tg, s, sd, u, knots, c, vmax, amax, q, qd, qdd)
        if r <= ratio * (1 + 1e-9):
            break
        stretched = r * (1 + 1e-6)
        if float(np.max(np.diff(ts))) * stretched <= dt:  # the same samples, stretched, stay dt apart
            ratio = stretched
            break
        ratio = stretched
    q[0], q[-1] = P[0], P[-1]
    qd[0], qd[-1] = 0.0, 0.0
    if ratio != 1.0:  # in place: the same values as ts * ratio, qd / ratio, qdd / ratio ** 2
        ts *= ratio
        qd /= ratio
        qdd /= ratio ** 2
    return Trajectory(ts, q, qd, qdd, list(joint_names or []),
                      {"timing": f"time-optimal along a spline (TOPP, knots every {step:g} rad)",
                       "stretch": ratio})
