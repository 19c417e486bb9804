"""Temporal optimization (7.7)-(7.9): re-time a fixed path by CFS to shorten the cycle.

Given the planned path points x_0..x_N of one segment (stop-by waypoints at both ends, zero
velocity there), find the time intervals tau_1..tau_N > 0 that

    minimise   w3 sum_k tau_k + w4/2 sum_k (tau_{k+1} - tau_k)^2                      (7.7)
    subject to |x_k - x_{k-1}| <= vmax tau_k                     (velocity, linear in tau)
               |v_{k+1} - v_k| <= amax (tau_k + tau_{k+1}) / 2    (acceleration at knot k)   (7.8)
               2 |x_1 - x_0| <= amax tau_1^2,  2 |x_N - x_{N-1}| <= amax tau_N^2  (from/to rest) (7.9)

with v_k = (x_k - x_{k-1}) / tau_k. Multiplying (7.8) by tau_k tau_{k+1} > 0 gives the smooth
constraints  amax (tau_k + tau_{k+1}) tau_k tau_{k+1} / 2 -+ (dx_{k+1} tau_k - dx_k tau_{k+1}) >= 0,
which are neither convex nor concave: CFS case (7.6), with the Hessian lower bound
-amax * max(ub_k, ub_{k+1}) on the (tau_k, tau_{k+1}) block (ub: the step bounds). The start/stop
constraints are simple bounds.

Speed (Table 7.1 workcell: 0.4-2.7 ms CPU per 19-step segment, was 6-16 ms): every CFS solve
starts from a feasible, nearly optimal schedule given by a compiled TOPP-like backward/forward pass
(:func:`pass_start`), so it converges in 3-6 iterations instead of up to ~40 from the uniform step;
the iterations run in :func:`_cfs_tau`, Algorithm 2 written for this problem's two-variable
constraint rows (compiled linearisation, tangent cuts and exact pull-back; DAQP on a working set of
rows near their limit, warm-started with the active set carried over by row), and gives the same
iterates as the general solver :func:`robointel.planning.cfs.cfs` (``SOLVER = "general"``). The
spline checks between refinement rounds and the final stretch use a compiled clamped-spline solve
(:func:`_clamped_spline_knots`, the same spline as scipy's ``CubicSpline``). Compiled with numba
(``cache=True``): the very first call in a fresh environment compiles for a few seconds.
The quadratic term (w4) penalises changes of the time step, i.e. the jerkiness of the discrete
acceleration profile; it also makes the cost strictly convex as Algorithm 2 requires.

The executable trajectory is the C2 cubic spline through ``(t_k, x_k)`` with zero velocity at the
segment ends; it is checked against the velocity and acceleration limits on a dense 1 ms grid, and
the segment's time is stretched uniformly by the (usually tiny) factor needed to meet them, so the
output never violates the limits.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit
from scipy.interpolate import CubicSpline

from robointel._validate import as_array
from robointel.errors import InfeasibleProblem, InvalidInput, LimitViolation
from robointel.planning.cfs import CFSResult, NonlinearConstraint, cfs
from robointel.planning.qp import DenseQP, SparseQP
from robointel.trajectory import Trajectory

#: tangent-cut rounds per CFS iteration for the curved acceleration sets (7.6)
MAX_CUTS = 2
#: ridge on tau (times w3 / tau_max) making the cost strictly convex; it only favours shorter steps
RIDGE = 1e-2
#: limit rescaling between rounds: "tighten" (only where the spline exceeds), "spread" (as tighten,
#: and the knot's neighbours by the factor ** SPREAD: the excess otherwise moves to them, costing a
#: round each), "sqrt" (damped), "both" (also relax where it has slack)
REFINE_MODE = "spread"
#: exponent of the tightening factor (1: divide by the excess ratio; > 1 overshoots, fewer rounds)
REFINE_POWER = 1.0
#: exponent on the neighbours' factor in REFINE_MODE "spread"
SPREAD = 0.25
#: starting schedule of every CFS solve: "pass" (forward/backward pass, see :func:`pass_start`),
#: "scaled" (velocity-shaped, see :func:`scaled_start`) or "uniform"
START = "pass"
#: upper bound of every step = this factor x the largest starting step
UB_FACTOR = 1.5
#: CFS implementation: "dedicated" (:func:`_cfs_tau`, Algorithm 2 written for this problem's
#: two-variable constraint rows) or "general" (:func:`robointel.planning.cfs.cfs`); same iteration
SOLVER = "dedicated"
#: per-step upper bound = this factor x the start's step (and neighbours); 0: one bound for all steps
LOCAL_UB = 0.0
#: QP working set of the dedicated CFS: rows whose acceleration at the reference is at least this
#: fraction of the limit, plus the last active ones; others are added when violated (0: all rows)
WORKING_SET = 0.5
#: refinement stops once the spline is within this fraction of the limits
REFINE_TOL = 0.01
#: CFS also stops when the total time fell by less than this fraction in one iteration
FTOL = 1e-3


@dataclass
class TemporalResult:
    """Re-timed segment.

    Attributes:
        trajectory: the segment's clamped C2 spline at its N+1 knots (starting at t = 0), s, rad,
            rad/s, rad/s^2 (default joint names).
        tau: (N,) optimised intervals before the limit stretch, s.
        tau0: (N,) the feasible starting schedule of the first CFS solve, s (by default the
            forward/backward pass :func:`pass_start`; the input's fixed dt is not used as a floor).
        stretch: uniform time factor applied after CFS to meet the limits on a 1 ms grid (>= 1).
        cfs: the CFS result.
        seconds: wall time of the CFS solve, s.
    """

    trajectory: Trajectory
    tau: np.ndarray
    tau0: np.ndarray
    stretch: float
    cfs: CFSResult
    seconds: float

    @property
    def duration(self) -> float:
        """Duration of the re-timed segment, s."""
        return self.trajectory.duration


def _limits(v, n: int, name: str) -> np.ndarray:
    v = as_array(np.broadcast_to(np.asarray(v, float), (n,)), name, (n,))
    if np.any(v <= 0):
        raise LimitViolation(f"{name} must be positive for every joint, got {v}", value=v)
    return v


def feasible_uniform_dt(path: np.ndarray, vmax: np.ndarray, amax: np.ndarray, dt: float | None = None) -> float:
    """Smallest uniform step (>= ``dt`` if given) meeting (7.7)-(7.9) on the path."""
    dx = np.diff(path, axis=0)
    need = [np.max(np.abs(dx) / vmax)]
    if len(dx) > 1:
        need.append(np.sqrt(np.max(np.abs(np.diff(dx, axis=0)) / amax)))
    need.append(np.sqrt(np.max(2 * np.abs(dx[[0, -1]]) / amax)))
    h = max(float(max(need)), 1e-4)
    return max(h, dt) if dt is not None else h


def spline_segment(t: np.ndarray, path: np.ndarray) -> CubicSpline:
    """The C2 cubic spline through the knots with zero velocity at both ends."""
    return CubicSpline(t, path, axis=0, bc_type="clamped")


def limit_stretch(spline: CubicSpline, duration: float, vmax, amax, dt: float = 1e-3) -> float:
    """Uniform time factor s >= 1 so that the spline's |qd| <= vmax and |qdd| <= amax: accelerations
    at the knots (exact, a cubic's acceleration is piecewise linear), velocities on a ``dt`` grid
    plus the knots and the interior extrema of each cubic piece."""
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


def scaled_start(dx: np.ndarray, vmax: np.ndarray, amax: np.ndarray, h0: float) -> np.ndarray:
    """A feasible starting schedule shaped like the path: the velocity-limited steps
    ``b_k = max_j |dx_kj| / vmax_j`` scaled uniformly by the smallest factor c >= 1 meeting
    (7.7)-(7.9) (accelerations scale by 1 / c^2); falls back to the uniform step ``h0``."""
    b = np.maximum(np.max(np.abs(dx) / vmax, axis=1), 1e-3 * h0)
    v = dx / b[:, None]
    need = [1.0, float(np.sqrt(np.max(2 * np.abs(dx[0]) / amax) / b[0] ** 2)),
            float(np.sqrt(np.max(2 * np.abs(dx[-1]) / amax) / b[-1] ** 2))]
    if len(b) > 1:
        a = (v[1:] - v[:-1]) / (0.5 * (b[1:] + b[:-1]))[:, None]
        need.append(float(np.sqrt(np.max(np.abs(a) / amax))))
    tau = b * max(need) * (1 + 1e-9)
    return tau if np.all(np.isfinite(tau)) and tau.sum() < h0 * len(b) else np.full(len(b), h0)


@njit(cache=True)
def _pass_x(dx, A, xcap, xlo):  # pragma: no cover - compiled
    """Forward/backward pass over the squared interval speeds x_k = 1 / tau_k^2 in [xlo, xcap_k]
    (see pass_start); (xlo, xlo) must satisfy every pair constraint."""
    N, n = dx.shape
    K = xcap.copy()
    lo_p = np.zeros(n + 1)
    lo_r = np.zeros(n + 1)
    up_p = np.zeros(n + 1)
    up_r = np.zeros(n + 1)
    # backward: K_k = largest x_k from which x_{k+1} in [0, K_{k+1}] is reachable
    for k in range(N - 2, -1, -1):
        nl, nu = 1, 1
        lo_p[0], lo_r[0] = 0.0, xlo
        up_p[0], up_r[0] = 0.0, K[k + 1]
        bound = xcap[k]
        for j in range(n):
            d0, d1, a4 = dx[k, j], dx[k + 1, j], 4.0 * A[k + 1, j]
            al, be = 3.0 * d1 - d0, 3.0 * d0 - d1
            if abs(al) < 1e-14:
                if abs(be) > 1e-14:
                    bound = min(bound, a4 / abs(be))
                continue
            # al x1 in [be x0 - a4, be x0 + a4]: a lower and an upper line x1 = p x0 + r
            r = a4 / abs(al)
            lo_p[nl], lo_r[nl] = be / al, -r
            up_p[nu], up_r[nu] = be / al, r
            nl += 1
            nu += 1
        for i in range(nl):
            for m in range(nu):
                dp = lo_p[i] - up_p[m]
                if dp > 1e-300:
                    bound = min(bound, (up_r[m] - lo_r[i]) / dp)
        K[k] = max(bound, xlo)
    # forward: the largest reachable x_{k+1} inside K_{k+1}
    x = np.empty(N)
    x[0] = K[0]
    for k in range(N - 1):
        u = K[k + 1]
        for j in range(n):
            d0, d1, a4 = dx[k, j], dx[k + 1, j], 4.0 * A[k + 1, j]
            al, be = 3.0 * d1 - d0, 3.0 * d0 - d1
            if al >= 1e-14:
                u = min(u, (be * x[k] + a4) / al)
            elif al <= -1e-14:
                u = min(u, (be * x[k] - a4) / al)
        x[k + 1] = max(u, xlo)
    return x


def step_bounds(dx: np.ndarray, vmax: np.ndarray, amax_k: np.ndarray, vscale: np.ndarray | None = None) -> np.ndarray:
    """(N,) smallest admissible steps: velocity limits |dx_k| <= vmax tau_k and the start/stop
    constraints (7.9) on the first and last step."""
    vs = 1.0 if vscale is None else vscale[:, None]
    lb = np.maximum(np.max(np.abs(dx) / (vmax * vs), axis=1), 1e-6)
    lb[0] = max(lb[0], float(np.sqrt(np.max(2 * np.abs(dx[0]) / amax_k[0]))))
    lb[-1] = max(lb[-1], float(np.sqrt(np.max(2 * np.abs(dx[-1]) / amax_k[-1]))))
    return lb


def accel_ratio(dx: np.ndarray, tau: np.ndarray, amax_k: np.ndarray) -> float:
    """Largest |v_{k+1} - v_k| / (amax (tau_k + tau_{k+1}) / 2) over interior knots and joints (7.8)."""
    if len(tau) < 2:
        return 0.0
    v = dx / tau[:, None]
    return float(np.max(np.abs(v[1:] - v[:-1]) / (0.5 * (tau[1:] + tau[:-1]))[:, None] / amax_k[1:-1]))


def pass_start(dx: np.ndarray, vmax: np.ndarray, amax_k: np.ndarray, vscale: np.ndarray | None = None) -> np.ndarray:
    """A feasible, nearly time-optimal starting schedule for the CFS of (7.7)-(7.9).

    With the squared interval speeds x_k = 1 / tau_k^2 and the approximations (valid for
    neighbouring steps of similar length) mean(tau_k, tau_{k+1}) ~ 2 / (s_k + s_{k+1}) and
    s_k s_{k+1} ~ (x_k + x_{k+1}) / 2, the acceleration constraint (7.8) at knot k becomes linear
    in (x_k, x_{k+1}):  |(3 dx_{k+1} - dx_k) x_{k+1} - (3 dx_k - dx_{k+1}) x_k| <= 4 amax.  With the
    velocity and start/stop bounds x_k <= 1 / lb_k^2 and a floor x_k >= 1 / h_u^2 (h_u: the smallest
    feasible uniform step, which meets both the linear and the exact model) this is the discrete
    form in which TOPP's backward (controllable sets) then forward (greedy) pass is exact; it costs
    microseconds (compiled). The result is then scaled uniformly by the smallest c >= 1 meeting the
    exact (7.8) (accelerations scale with 1 / c^2), so it is a feasible reference for CFS (the
    uniform step h_u is returned if it is shorter); CFS then solves (7.7)-(7.9) itself from there.

    Args:
        dx: (N, n) path increments (rad). amax_k: (N+1, n) acceleration limit at each knot.
        vmax: (n,) velocity limits; vscale: (N,) factors on them per interval.

    Returns:
        (N,) steps tau (s), >= the velocity and start/stop bounds and feasible for (7.8).
    """
    lb = step_bounds(dx, vmax, amax_k, vscale)
    N = len(dx)
    # the smallest uniform step meeting the bounds and (7.8) exactly; in the linear model too
    h_u = float(lb.max())
    if N > 1:
        h_u = max(h_u, float(np.sqrt(np.max(np.abs(dx[1:] - dx[:-1]) / amax_k[1:-1]))))
    h_u *= 1 + 1e-9
    x = _pass_x(np.ascontiguousarray(dx, dtype=float), np.ascontiguousarray(amax_k, dtype=float), 1.0 / lb ** 2,
                1.0 / h_u ** 2)
    tau = np.clip(1.0 / np.sqrt(x), lb, h_u)
    c = max(1.0, float(np.sqrt(accel_ratio(dx, tau, amax_k))))
    tau = tau * c * (1 + 1e-9)
    # keep the uniform step when the pass is no shorter (the linear model is poor for wildly uneven steps)
    return tau if tau.sum() < h_u * N else np.full(N, h_u)


def _start(dx, vmax, amax_k, vscale, h_min) -> np.ndarray:
    """Starting schedule of a CFS solve according to :data:`START` (always feasible)."""
    N = len(dx)
    if START == "pass":
        tau = pass_start(dx, vmax, amax_k, vscale)
        if np.all(np.isfinite(tau)):
            return tau
    if START == "scaled":
        return scaled_start(dx, vmax, amax_k[0], h_min)
    return np.full(N, h_min)


@njit(cache=True)
def _clamped_moments(h, y, M, cp, dp):  # pragma: no cover - compiled
    """Knot second derivatives M (N+1, n) of the clamped C2 cubic spline (zero end slopes) through
    y with interval lengths h (N,): the moment equations solved by the Thomas algorithm (sub-
    diagonal a, diagonal b, super-diagonal c, right-hand side r). cp, dp: (N+1,) work arrays."""
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
def _clamped_ratios(t, y, vmax, amax, sub):  # pragma: no cover - compiled
    """Knot accelerations of the clamped C2 cubic spline (Thomas algorithm on the moment equations)
    over amax, and the largest |velocity| / vmax at ``sub - 1`` interior samples of each piece."""
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
def _clamped_spline_knots(t, y, vmax, amax):  # pragma: no cover - compiled
    """Knot velocities V (N+1, n) and accelerations M (N+1, n) of the clamped C2 cubic spline
    through (t, y), and the exact largest |velocity| / vmax (knots and interior extrema of every
    piece) and |acceleration| / amax (at the knots: it is piecewise linear)."""
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


def _knot_ratios(t: np.ndarray, path: np.ndarray, vmax: np.ndarray, amax: np.ndarray, sub: int = 8):
    """Spline acceleration / limit at each knot (exact: a cubic's acceleration is piecewise linear)
    and the largest velocity / limit inside each interval (sampled at ``sub - 1`` interior points)
    of the clamped spline :func:`spline_segment` (compiled, same spline as scipy's)."""
    return _clamped_ratios(np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(path, dtype=float),
                           np.asarray(vmax, float), np.asarray(amax, float), int(sub))


def _knot_ratios_scipy(t: np.ndarray, path: np.ndarray, vmax: np.ndarray, amax: np.ndarray, sub: int = 8):
    """Reference implementation of :func:`_knot_ratios` with scipy's CubicSpline (for tests)."""
    s = spline_segment(t, path)
    ra = np.max(np.abs(s(t, 2)) / amax, axis=1)
    u = (np.arange(1, sub) / sub)
    ts = (t[:-1, None] + np.diff(t)[:, None] * u[None]).ravel()
    rv = np.max(np.abs(s(ts, 1)) / vmax, axis=1).reshape(len(t) - 1, sub - 1).max(1)
    return ra, rv


def _cfs_tau(H: np.ndarray, f: np.ndarray, lb: np.ndarray, ub: np.ndarray, kk: np.ndarray, A2: np.ndarray,
             d1: np.ndarray, d0: np.ndarray, sign: np.ndarray, mu: np.ndarray, z0: np.ndarray, *, eps: float,
             max_iter: int, tol: float = 1e-9, max_cuts: int = MAX_CUTS, ftol: float = 0.0,
             keep_iterates: bool = False) -> CFSResult:
    """Algorithm 2 specialised to (7.7)-(7.9): the same iteration as :func:`robointel.planning.cfs.cfs`
    for case-(7.6) constraints with a diagonal Hessian bound, written for this problem's structure.

    Constraint row r couples only tau_a (a = kk_r) and tau_b (b = kk_r + 1):
    ``phi_r = A_r (tau_a + tau_b) tau_a tau_b / 2 - sign_r (d1_r tau_a - d0_r tau_b) >= 0``. At the
    reference z_r the convex feasible set (7.6) is
    ``F_r = {phi_r(z_r) + grad phi_r (z - z_r) + mu_r/2 (|z_a - z_a,r|^2 + |z_b - z_b,r|^2) >= 0}``
    (mu_r <= 0 a lower bound of the Hessian's eigenvalues on the box). Each iteration solves one QP
    (DAQP, dense, tau bounds as simple bounds, warm-started with the previous multipliers) over the
    linearisation, adds tangent cuts of the violated F_r (``max_cuts`` rounds), and pulls the step
    back along the segment from z_r so that the iterate lies in every F_r (closed form: a quadratic
    in the step length per row). The Jacobian's two non-zeros per row are written in place into a
    preallocated matrix. Iterates are feasible whenever z0 is, and the cost never increases.

    Stops on ``||z(k+1) - z(k)|| <= eps`` or (``ftol > 0``) on a relative cost decrease <= ftol.
    """
    import daqp

    t0 = time.perf_counter()
    N, R = z0.size, kk.size
    kk = np.ascontiguousarray(kk, dtype=np.int64)
    G = np.zeros((R, N))
    Hc = np.ascontiguousarray(H, dtype=float)
    INFV = 1e20
    up0 = np.concatenate([ub, np.full(R, INFV)])

    def cost(z):
        return float(0.5 * z @ (Hc @ z) + f @ z)

    def feasible(z):
        return bool(_feasible(z, lb, ub, kk, A2, d1, d0, sign, tol))

    z = np.clip(np.asarray(z0, float), lb, ub)
    costs = [cost(z)]
    iterates = [z.copy()] if keep_iterates else []
    best, best_cost = (z.copy(), costs[0]) if feasible(z) else (None, np.inf)
    status, it, qp_iters, flag = "max_iter", 0, 0, 0
    # warm start: the active set of the last QP, carried over by constraint row (a row and its
    # tangent cuts share a row id), passed to DAQP as "active" flags
    act_b = np.zeros(N, dtype=np.int32)     # simple bounds: 3 active at lb, 1 at ub
    act_r = np.zeros(R, dtype=bool)
    for it in range(1, max_iter + 1):
        p, ga, gb, h, inW = _rows_lin(z, kk, A2, d1, d0, sign, G, WORKING_SET, act_r)
        ref_ok = bool(R == 0 or p.min() >= -tol)
        if WORKING_SET and ref_ok:
            # working set: rows whose acceleration at the reference uses WORKING_SET of the limit, and
            # the last active ones; a row left out enters as soon as a QP solution violates its
            # linearisation (so every QP solution is that of the full linearisation)
            row_of = np.flatnonzero(inW)
            Ablk, lo, up = G[row_of], np.concatenate((lb, h[row_of])), up0[:N + row_of.size]
        else:
            inW = np.ones(R, dtype=bool)
            Ablk, lo, up = G, np.concatenate([lb, h]), up0
            row_of = np.arange(R)
        x = None
        _round, _ws = 0, 0
        while _round <= max_cuts:
            sense = _warm_sense(lo.size, N, act_b, act_r, row_of)
            sol, _fv, flag, info = daqp.solve(Hc, f, Ablk, up, lo, sense, primal_tol=1e-9, iter_limit=2000)
            qp_iters += int(info.get("iterations", 0))
            if flag not in (1, 2) or not np.all(np.isfinite(sol)):
                act_b[:] = 0
                act_r[:] = False
                sol, _fv, flag, info = daqp.solve(Hc, f, Ablk, up, lo, np.zeros(lo.size, dtype=np.intc),
                                                  primal_tol=1e-9, iter_limit=2000)
                qp_iters += int(info.get("iterations", 0))
                if flag not in (1, 2) or not np.all(np.isfinite(sol)):
                    x = None
                    break
            x = np.asarray(sol, float)
            act_b, act_r = _active_from(np.asarray(info["lam"], float), N, row_of, R)
            if not inW.all():
                ids = _rows_lin_violated(x, kk, ga, gb, h, inW, 1e-9)
                if ids.size and _ws < 20:
                    _ws += 1
                    inW[ids] = True
                    Ablk = np.vstack((Ablk, G[ids]))
                    lo = np.concatenate((lo, h[ids]))
                    up = np.concatenate((up, np.full(ids.size, INFV)))
                    row_of = np.concatenate((row_of, ids))
                    continue
            if not ref_ok or _round == max_cuts:
                break
            _round += 1
            C, c, ids = _rows_cuts(x, z, kk, p, ga, gb, mu, tol, N)
            if c.size == 0:
                break
            Ablk = np.vstack((Ablk, C))
            lo = np.concatenate((lo, c))
            up = np.concatenate((up, np.full(c.size, INFV)))
            row_of = np.concatenate((row_of, ids))
        if x is None:
            if best is None and it == 1:
                raise InfeasibleProblem("temporal CFS: the convex subproblem at the start is infeasible "
                                        f"(DAQP exit {flag})", value=flag)
            status = "qp_failed"
            break
        d = x - z
        alpha = _rows_pull_back(d, kk, p, ga, gb, mu) if ref_ok and R else 1.0
        z = z + alpha * d
        step = alpha * float(np.linalg.norm(d))
        costs.append(cost(z))
        if keep_iterates:
            iterates.append(z.copy())
        if costs[-1] <= best_cost and feasible(z):
            best, best_cost = z.copy(), costs[-1]
        if step <= eps:
            status = "converged"
            break
        if ftol > 0 and ref_ok and costs[-2] - costs[-1] <= ftol * max(abs(costs[-1]), 1e-12):
            status = "converged"
            break
    if status != "converged" and best is not None:
        z = best
    viol = float(max(-_rows_phi_min(z, kk, A2, d1, d0, sign) if R else 0.0, np.max(lb - z), np.max(z - ub), 0.0))
    return CFSResult(z=z, iterations=it, costs=costs, status=status, feasible=feasible(z), max_violation=viol,
                     seconds=time.perf_counter() - t0, iterates=iterates, qp_iterations=qp_iters)


@njit(cache=True)
def _rows_lin(z, kk, A2, d1, d0, sign, G, ws, act_r):  # pragma: no cover - compiled
    """phi_r(z), its two partials and the linearisation's right-hand side (writes G in place), and
    the working-set mask: rows whose acceleration uses at least ``ws`` of the limit, or active."""
    R = kk.size
    p = np.empty(R)
    ga = np.empty(R)
    gb = np.empty(R)
    h = np.empty(R)
    inW = np.empty(R, dtype=np.bool_)
    for r in range(R):
        a, b = z[kk[r]], z[kk[r] + 1]
        cub = 0.5 * A2[r] * (a + b) * a * b
        p[r] = cub - sign[r] * (d1[r] * a - d0[r] * b)
        inW[r] = act_r[r] or p[r] <= (1.0 - ws) * cub
        ga[r] = 0.5 * A2[r] * (2 * a * b + b * b) - sign[r] * d1[r]
        gb[r] = 0.5 * A2[r] * (a * a + 2 * a * b) + sign[r] * d0[r]
        G[r, kk[r]] = ga[r]
        G[r, kk[r] + 1] = gb[r]
        h[r] = ga[r] * a + gb[r] * b - p[r]
    return p, ga, gb, h, inW


@njit(cache=True)
def _feasible(z, lb, ub, kk, A2, d1, d0, sign, tol):  # pragma: no cover - compiled
    """z within its bounds (1e-9) and every (7.8) row phi_r(z) >= -tol."""
    for i in range(z.size):
        if z[i] < lb[i] - 1e-9 or z[i] > ub[i] + 1e-9:
            return False
    for r in range(kk.size):
        a, b = z[kk[r]], z[kk[r] + 1]
        if 0.5 * A2[r] * (a + b) * a * b - sign[r] * (d1[r] * a - d0[r] * b) < -tol:
            return False
    return True


@njit(cache=True)
def _rows_phi_min(z, kk, A2, d1, d0, sign):  # pragma: no cover - compiled
    """min_r phi_r(z)."""
    m = np.inf
    for r in range(kk.size):
        a, b = z[kk[r]], z[kk[r] + 1]
        m = min(m, 0.5 * A2[r] * (a + b) * a * b - sign[r] * (d1[r] * a - d0[r] * b))
    return m


@njit(cache=True)
def _rows_cuts(x, z, kk, p, ga, gb, mu, tol, N):  # pragma: no cover - compiled
    """Tangent cuts (rows C, lower bounds c) of the concave g_r of (7.6) at x where g_r(x) < -tol."""
    R = kk.size
    bad = np.zeros(R, dtype=np.bool_)
    nb = 0
    for r in range(R):
        da, db = x[kk[r]] - z[kk[r]], x[kk[r] + 1] - z[kk[r] + 1]
        if p[r] + ga[r] * da + gb[r] * db + 0.5 * mu[r] * (da * da + db * db) < -tol:
            bad[r] = True
            nb += 1
    C = np.zeros((nb, N))
    c = np.empty(nb)
    ids = np.empty(nb, dtype=np.int64)
    i = 0
    for r in range(R):
        if bad[r]:
            ids[i] = r
            k = kk[r]
            da, db = x[k] - z[k], x[k + 1] - z[k + 1]
            gv = p[r] + ga[r] * da + gb[r] * db + 0.5 * mu[r] * (da * da + db * db)
            ca, cb = ga[r] + mu[r] * da, gb[r] + mu[r] * db
            C[i, k] = ca
            C[i, k + 1] = cb
            c[i] = ca * x[k] + cb * x[k + 1] - gv
            i += 1
    return C, c, ids


@njit(cache=True)
def _rows_lin_violated(x, kk, ga, gb, h, inW, tol):  # pragma: no cover - compiled
    """Rows outside the working set whose linearisation ga x_a + gb x_b >= h fails at x."""
    out = []
    for r in range(kk.size):
        if not inW[r] and ga[r] * x[kk[r]] + gb[r] * x[kk[r] + 1] - h[r] < -tol * (1.0 + abs(h[r])):
            out.append(r)
    return np.array(out, dtype=np.int64)


@njit(cache=True)
def _warm_sense(m, N, act_b, act_r, row_of):  # pragma: no cover - compiled
    """DAQP constraint flags (m,) marking the last QP's active set: simple bounds as given, and
    for every active constraint row its newest QP row (the latest tangent cut, else the row)."""
    sense = np.zeros(m, dtype=np.int32)
    sense[:N] = act_b
    last = np.full(act_r.size, -1)
    for i in range(row_of.size):
        last[row_of[i]] = i
    for r in range(act_r.size):
        if act_r[r] and last[r] >= 0:
            sense[N + last[r]] = 3
    return sense


@njit(cache=True)
def _active_from(lam, N, row_of, R):  # pragma: no cover - compiled
    """Active set of a DAQP solution by constraint row: bounds (3 lower, 1 upper) and rows."""
    act_b = np.zeros(N, dtype=np.int32)
    act_r = np.zeros(R, dtype=np.bool_)
    for i in range(N):
        act_b[i] = 3 if lam[i] < 0 else (1 if lam[i] > 0 else 0)
    for i in range(row_of.size):
        if lam[N + i] != 0:
            act_r[row_of[i]] = True
    return act_b, act_r


@njit(cache=True)
def _rows_pull_back(dz, kk, p, ga, gb, mu):  # pragma: no cover - compiled
    """Largest alpha in [0, 1] with g_r(z_r + alpha dz) >= 0 for every row (g_r(z_r) = phi_r >= 0)."""
    alpha = 1.0
    for r in range(kk.size):
        da, db = dz[kk[r]], dz[kk[r] + 1]
        qa = 0.5 * mu[r] * (da * da + db * db)
        qb = ga[r] * da + gb[r] * db
        c0 = max(p[r], 0.0)
        if c0 + qb + qa >= 0:
            continue
        if qa < -1e-300:
            root = (-qb - np.sqrt(max(qb * qb - 4 * qa * c0, 0.0))) / (2 * qa)
        elif qb < 0:
            root = -c0 / qb
        else:
            root = 1.0
        alpha = min(alpha, max(root, 0.0))
    return alpha


def _solve_tau(dx: np.ndarray, vmax: np.ndarray, amax_k: np.ndarray, vscale: np.ndarray, tau0: np.ndarray,
               w3: float, w4: float, eps: float, max_iter: int, qp, trust: float | None = None,
               keep_iterates: bool = False) -> CFSResult:
    """One CFS solve of (7.7)-(7.9) with per-knot acceleration limits amax_k (N+1, n) and per-interval
    velocity scale factors; ``tau0`` must be feasible."""
    N, n = dx.shape
    lb = step_bounds(dx, vmax, amax_k, vscale)
    tau0 = np.maximum(tau0, lb)
    h = UB_FACTOR * float(np.max(tau0))
    if LOCAL_UB:
        # per-step upper bounds around the start: a tighter Hessian bound mu_r of (7.6) per row
        t_nb = np.maximum.reduce([tau0, np.r_[tau0[1:], tau0[-1]], np.r_[tau0[0], tau0[:-1]]])
        ub = np.maximum(LOCAL_UB * t_nb, lb * (1 + 1e-9))
    else:
        ub = np.full(N, h)
    H = w4 * _second_difference(N) + (RIDGE * w3 / h) * np.eye(N)
    f = np.full(N, w3)
    if N < 2:  # one step: only the bounds (7.9)
        return cfs(H, f, A=np.eye(N), l=lb, u=ub, z0=tau0, eps=eps, max_iter=max_iter, tol=1e-9, qp=qp)
    kk, jj = _row_pattern(N - 1, n)
    A2 = np.tile(amax_k[1:-1].ravel(), 2)
    d12 = np.tile(dx[kk + 1, jj], 2)
    d02 = np.tile(dx[kk, jj], 2)
    kk2 = np.tile(kk, 2)
    sign = np.repeat([1.0, -1.0], kk.size)
    # drop rows that hold everywhere in the box lb <= tau <= ub (joints that barely move)
    la, lb_ = lb[kk2], lb[kk2 + 1]
    keep = 0.5 * A2 * (la + lb_) * la * lb_ < np.abs(d12) * ub[kk2] + np.abs(d02) * ub[kk2 + 1]
    kk2, A2, d12, d02, sign = kk2[keep], A2[keep], d12[keep], d02[keep], sign[keep]
    # lower bound of the cubic's Hessian eigenvalues on the box: -A max(ub_a, ub_b) (7.6)
    mu = -A2 * np.maximum(ub[kk2], ub[kk2 + 1])
    if SOLVER == "dedicated" and trust is None:
        return _cfs_tau(H, f, lb, ub, kk2, A2, d12, d02, sign, mu, tau0, eps=eps, max_iter=max_iter,
                        max_cuts=MAX_CUTS, ftol=FTOL, keep_iterates=keep_iterates)
    rows = np.arange(kk2.size)

    def fun(tau):
        a, b = tau[kk2], tau[kk2 + 1]
        return 0.5 * A2 * (a + b) * a * b - sign * (d12 * a - d02 * b)

    def jac(tau):
        a, b = tau[kk2], tau[kk2 + 1]
        J = np.zeros((rows.size, N))
        J[rows, kk2] = 0.5 * A2 * (2 * a * b + b * b) - sign * d12
        J[rows, kk2 + 1] = 0.5 * A2 * (a * a + 2 * a * b) + sign * d02
        return J

    Hd = np.zeros((rows.size, N))
    Hd[rows, kk2] = mu
    Hd[rows, kk2 + 1] = mu
    cons = [NonlinearConstraint(fun, jac, kind="general", hess_diag=Hd, name="acceleration (7.8)")]
    return cfs(H, f, constraints=cons, A=np.eye(N), l=lb, u=ub, z0=tau0, eps=eps, max_iter=max_iter,
               tol=1e-9, max_cuts=MAX_CUTS, qp=qp, trust=None if trust is None else trust * h, ftol=FTOL,
               keep_iterates=keep_iterates)


@lru_cache(maxsize=32)
def _second_difference(N: int) -> np.ndarray:
    """D'D for the first-difference matrix D ((N-1) x N): the w4 term of (7.7)."""
    D = np.diff(np.eye(N), axis=0)
    M = D.T @ D
    M.setflags(write=False)
    return M


@lru_cache(maxsize=32)
def _row_pattern(K: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(knot index k of interval pair (k, k+1), joint j) of the K*n rows of (7.8), one sign."""
    kk, jj = np.repeat(np.arange(K), n), np.tile(np.arange(n), K)
    kk.setflags(write=False)
    jj.setflags(write=False)
    return kk, jj


def _tighten(sig_a: np.ndarray, sig_v: np.ndarray, ra: np.ndarray, rv: np.ndarray):
    """Rescaled per-knot acceleration and per-interval velocity factors (see :data:`REFINE_MODE`)."""
    if REFINE_MODE == "both":
        return np.clip(sig_a / np.maximum(ra, 1e-3), 0.2, 2.0), np.clip(sig_v / np.maximum(rv, 1e-3), 0.2, 2.0)
    if REFINE_MODE == "spread":  # also tighten the neighbours of a tightened knot (damped)
        fa = np.minimum(1.0, 1.0 / np.maximum(ra, 1e-3))
        nb = np.minimum(np.r_[1.0, fa[:-1]], np.r_[fa[1:], 1.0]) ** SPREAD
        fv = np.minimum(1.0, 1.0 / np.maximum(rv, 1e-3))
        return np.clip(sig_a * np.minimum(fa, nb), 0.2, 2.0), np.clip(sig_v * fv, 0.2, 2.0)
    pw = REFINE_POWER if REFINE_MODE == "tighten" else 0.5
    return (np.clip(sig_a * np.minimum(1.0, 1.0 / np.maximum(ra, 1e-3)) ** pw, 0.2, 2.0),
            np.clip(sig_v * np.minimum(1.0, 1.0 / np.maximum(rv, 1e-3)) ** pw, 0.2, 2.0))


def temporal_optimize(path, vmax, amax, *, dt: float | None = None, w3: float = 1.0, w4: float = 1.0,
                      eps: float = 1e-4, max_iter: int = 30, refine: int = 6, upsample: int = 1,
                      trust: float | None = None, qp: DenseQP | SparseQP | None = None) -> TemporalResult:
    """Solve (7.7)-(7.9) by CFS for one segment and return its spline trajectory.

    After each CFS solve the spline through the re-timed knots is compared with the limits: at
    knots where the spline's acceleration exceeds the limit (or intervals where its velocity does)
    the limit used by (7.8) is tightened by that ratio (and its neighbours' a little, see
    :data:`REFINE_MODE`), and CFS is re-run from the forward/backward pass under the new limits
    (``refine`` rounds at most, stopping once the spline is within :data:`REFINE_TOL` of the limits).
    The shortest result is kept and finally stretched uniformly so that the spline meets the limits
    exactly (knots and every piece's velocity extremum).

    Args:
        path: (N+1, n) path points (rad), N >= 1; zero velocity at both ends.
        vmax, amax: (n,) or scalar velocity (rad/s) and acceleration (rad/s^2) limits.
        dt: the fixed time step of the input path (only rescaled when up-sampling; the CFS starts
            from the smallest feasible uniform step).
        w3, w4: weights of total time and of time-step changes.
        eps, max_iter: CFS stopping rule and cap (per solve).
        refine: limit-rescaling rounds.
        upsample: the path is re-sampled with ``upsample`` points per input interval on its
            geometric spline (path parameter uniform over the input points; the input points are
            kept) before re-timing: finer knots bring the discrete model (7.8) closer to the
            executed spline.
        trust: ``None``: the curved sets (7.6) are handled by tangent cuts and an exact pull-back;
            a number: by the polyhedral inner approximation on a trust box of that fraction of the
            time step (one QP per iteration, see :func:`robointel.planning.cfs.cfs`).
        qp: QP solver (default: a fresh :class:`DenseQP`).

    Raises:
        InvalidInput: bad shapes or NaN. LimitViolation: non-positive limits.
    """
    path = as_array(path, "path", (None, None))
    if path.shape[0] < 2:
        raise InvalidInput(f"path needs at least 2 points, got {path.shape[0]}", value=path.shape)
    N, n = path.shape[0] - 1, path.shape[1]
    vmax, amax = _limits(vmax, n, "vmax"), _limits(amax, n, "amax")
    if dt is not None and not dt > 0:
        raise InvalidInput(f"dt must be positive, got {dt}", value=dt)
    qp = qp or DenseQP()
    if int(upsample) < 1:
        raise InvalidInput(f"upsample must be >= 1, got {upsample}", value=upsample)
    if upsample > 1:
        geo = CubicSpline(np.arange(N + 1), path, axis=0)
        path = geo(np.arange(N * int(upsample) + 1) / int(upsample))
        dt = None if dt is None else dt / int(upsample)
        N = path.shape[0] - 1
    dx = np.diff(path, axis=0)
    t0 = time.perf_counter()
    h_min = feasible_uniform_dt(path, vmax, amax, None)  # no floor at the input's dt
    sig_a = np.ones(N + 1)
    sig_v = np.ones(N)
    tau_start = _start(dx, vmax, amax[None] * sig_a[:, None], sig_v, h_min)
    tau_first = tau_start.copy()
    best = None
    for _round in range(refine + 1):
        res = _solve_tau(dx, vmax, amax[None] * sig_a[:, None], sig_v, tau_start, w3, w4, eps, max_iter, qp, trust)
        tau = np.maximum(res.z, 1e-6)
        t = np.concatenate([[0.0], np.cumsum(tau)])
        ra, rv = _knot_ratios(t, path, vmax, amax)
        s = float(max(1.0, rv.max(), np.sqrt(ra.max())))
        if best is None or t[-1] * s < best[0]:
            best = (t[-1] * s, tau, res)
        if s <= 1.0 + REFINE_TOL:
            break
        # rescale the limits where the spline and the discrete model disagree, warm start feasibly
        new_a, new_v = _tighten(sig_a, sig_v, ra, rv)
        c = float(max(1.0, np.sqrt(np.max(sig_a / new_a)), np.max(sig_v / new_v)))
        sig_a, sig_v = new_a, new_v
        if START == "pass":  # the pass under the new limits (nearer their optimum than tau * c)
            tau_start = _start(dx, vmax, amax[None] * sig_a[:, None], sig_v, h_min)
        else:
            tau_start = tau * c
    secs = time.perf_counter() - t0
    _, tau, res = best
    t = np.concatenate([[0.0], np.cumsum(tau)])
    # the clamped spline's knot velocities/accelerations and its exact peak ratios (compiled; the
    # same spline as :func:`spline_segment`, the same factor as :func:`limit_stretch`)
    V, M, rv, ra = _clamped_spline_knots(t, np.ascontiguousarray(path, dtype=float), vmax, amax)
    s = float(max(1.0, rv, np.sqrt(ra)) * (1 + 1e-7))
    t, V, M = t * s, V / s, M / (s * s)  # the same curve, slower by s
    return TemporalResult(trajectory=Trajectory(t, path.copy(), V, M), tau=tau, tau0=tau_first, stretch=s,
                          cfs=res, seconds=secs)


def fixed_dt_segment(path, dt: float) -> Trajectory:
    """The clamped spline through ``path`` (N+1, n) at the fixed step ``dt`` (s), from t = 0."""
    path = as_array(path, "path", (None, None))
    t = dt * np.arange(path.shape[0])
    s = spline_segment(t, path)
    return Trajectory(t, path.copy(), s(t, 1), s(t, 2))


def concatenate_segments(parts: list[Trajectory], joint_names: list[str], meta: dict | None = None) -> Trajectory:
    """Join per-segment trajectories (each from t=0, sharing end/start waypoints) into one
    :class:`Trajectory`; the shared waypoint appears once (zero velocity there)."""
    T, Q, QD, QDD = [], [], [], []
    offset = 0.0
    for i, p in enumerate(parts):
        sl = slice(0 if i == 0 else 1, None)
        T.append(p.t[sl] - p.t[0] + offset)
        Q.append(p.q[sl])
        QD.append(p.qd[sl])
        QDD.append(p.qdd[sl])
        offset += p.duration
    return Trajectory(np.concatenate(T), np.concatenate(Q), np.concatenate(QD), np.concatenate(QDD),
                      list(joint_names), dict(meta or {}))
