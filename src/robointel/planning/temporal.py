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
-amax * tau_max on the (tau_k, tau_{k+1}) block. The start/stop constraints are simple bounds.
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

import numpy as np
from scipy.interpolate import CubicSpline

from robointel._validate import as_array
from robointel.errors import InvalidInput, LimitViolation
from robointel.io.trajectory import Trajectory
from robointel.planning.cfs import CFSResult, NonlinearConstraint, cfs
from robointel.planning.qp import DenseQP, SparseQP

#: tangent-cut rounds per CFS iteration for the curved acceleration sets (7.6)
MAX_CUTS = 2
#: ridge on tau (times w3 / tau_max) making the cost strictly convex; it only favours shorter steps
RIDGE = 1e-2
#: limit rescaling between rounds: "tighten" (only where the spline exceeds), "sqrt" (damped),
#: "both" (also relax where it has slack)
REFINE_MODE = "tighten"
#: starting schedule of the first CFS solve: "scaled" (velocity-shaped, see scaled_start) or "uniform"
START = "uniform"
#: upper bound of every step = this factor x the largest starting step
UB_FACTOR = 1.5
#: refinement stops once the spline is within this fraction of the limits
REFINE_TOL = 0.005
#: CFS also stops when the total time fell by less than this fraction in one iteration
FTOL = 0.0


@dataclass
class TemporalResult:
    """Re-timed segment.

    Attributes:
        t: (N+1,) knot times, s, starting at 0.
        q, qd, qdd: (N+1, n) positions, velocities, accelerations of the spline at the knots.
        tau: (N,) optimised intervals before the limit stretch, s.
        tau0: (N,) the feasible starting schedule of the first CFS solve, s (the smallest
            feasible uniform step; the input's fixed dt is not used as a floor).
        stretch: uniform time factor applied after CFS to meet the limits on a 1 ms grid (>= 1).
        cfs: the CFS result.
        seconds: wall time of the CFS solve, s.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    tau0: np.ndarray
    stretch: float
    cfs: CFSResult
    seconds: float

    @property
    def duration(self) -> float:
        return float(self.t[-1])


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


def _knot_ratios(t: np.ndarray, path: np.ndarray, vmax: np.ndarray, amax: np.ndarray, sub: int = 8):
    """Spline acceleration / limit at each knot (exact: a cubic's acceleration is piecewise linear)
    and the largest velocity / limit inside each interval (sampled)."""
    s = spline_segment(t, path)
    ra = np.max(np.abs(s(t, 2)) / amax, axis=1)
    u = (np.arange(1, sub) / sub)
    ts = (t[:-1, None] + np.diff(t)[:, None] * u[None]).ravel()
    rv = np.max(np.abs(s(ts, 1)) / vmax, axis=1).reshape(len(t) - 1, sub - 1).max(1)
    return ra, rv


def _solve_tau(dx: np.ndarray, vmax: np.ndarray, amax_k: np.ndarray, vscale: np.ndarray, tau0: np.ndarray,
               w3: float, w4: float, eps: float, max_iter: int, qp, trust: float | None = None) -> CFSResult:
    """One CFS solve of (7.7)-(7.9) with per-knot acceleration limits amax_k (N+1, n) and per-interval
    velocity scale factors; ``tau0`` must be feasible."""
    N, n = dx.shape
    lb = np.maximum(np.max(np.abs(dx) / (vmax * vscale[:, None]), axis=1), 1e-6)
    lb[0] = max(lb[0], float(np.sqrt(np.max(2 * np.abs(dx[0]) / amax_k[0]))))
    lb[-1] = max(lb[-1], float(np.sqrt(np.max(2 * np.abs(dx[-1]) / amax_k[-1]))))
    tau0 = np.maximum(tau0, lb)
    h = UB_FACTOR * float(np.max(tau0))
    ub = np.full(N, h)
    D = np.diff(np.eye(N), axis=0)
    H = w4 * D.T @ D + RIDGE * w3 / h * np.eye(N)
    f = np.full(N, w3)
    cons = []
    if N >= 2:
        K = N - 1
        kk = np.repeat(np.arange(K), n)  # interior knot k+1 between intervals k and k+1 (0-based)
        jj = np.tile(np.arange(n), K)
        A_ = amax_k[1:-1].ravel()
        d1 = dx[kk + 1, jj]
        d0 = dx[kk, jj]
        sign = np.concatenate([np.ones(K * n), -np.ones(K * n)])
        kk2, A2, d12, d02 = (np.concatenate([a, a]) for a in (kk, A_, d1, d0))
        # drop rows that hold everywhere in the box lb <= tau <= ub (joints that barely move)
        lo_cubic = 0.5 * A2 * (lb[kk2] + lb[kk2 + 1]) * lb[kk2] * lb[kk2 + 1]
        hi_lin = np.maximum(np.abs(d12) * ub[kk2], 0) + np.abs(d02) * ub[kk2 + 1]
        keep = lo_cubic < hi_lin
        kk2, A2, d12, d02, sign = kk2[keep], A2[keep], d12[keep], d02[keep], sign[keep]
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
        mu = -A2 * h  # min eigenvalue of the cubic's Hessian on (0, h]^2 (7.6)
        Hd[rows, kk2] = mu
        Hd[rows, kk2 + 1] = mu
        cons.append(NonlinearConstraint(fun, jac, kind="general", hess_diag=Hd, name="acceleration (7.8)"))
    return cfs(H, f, constraints=cons, A=np.eye(N), l=lb, u=ub, z0=tau0, eps=eps, max_iter=max_iter,
               tol=1e-9, max_cuts=MAX_CUTS, qp=qp, trust=None if trust is None else trust * h, ftol=FTOL)


def temporal_optimize(path, vmax, amax, *, dt: float | None = None, w3: float = 1.0, w4: float = 1.0,
                      eps: float = 1e-4, max_iter: int = 30, refine: int = 6, upsample: int = 1,
                      trust: float | None = None, qp: DenseQP | SparseQP | None = None) -> TemporalResult:
    """Solve (7.7)-(7.9) by CFS for one segment and return its spline trajectory.

    After each CFS solve the spline through the re-timed knots is compared with the limits: at
    knots where the spline's acceleration exceeds the limit (or intervals where its velocity does)
    the limit used by (7.8) is tightened by that ratio, and CFS is re-run warm-started from the
    previous schedule scaled to be feasible (``refine`` rounds at most, stopping once the spline is
    within 0.5 % of the limits). The shortest result is kept and finally stretched uniformly so
    that the spline meets the limits exactly on the dense grid.

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
    tau_start = scaled_start(dx, vmax, amax, h_min) if START == "scaled" else np.full(N, h_min)
    sig_a = np.ones(N + 1)
    sig_v = np.ones(N)
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
        if REFINE_MODE == "both":
            new_a = np.clip(sig_a / np.maximum(ra, 1e-3), 0.2, 2.0)
            new_v = np.clip(sig_v / np.maximum(rv, 1e-3), 0.2, 2.0)
        else:
            pw = 1.0 if REFINE_MODE == "tighten" else 0.5
            new_a = np.clip(sig_a * np.minimum(1.0, 1.0 / np.maximum(ra, 1e-3)) ** pw, 0.2, 2.0)
            new_v = np.clip(sig_v * np.minimum(1.0, 1.0 / np.maximum(rv, 1e-3)) ** pw, 0.2, 2.0)
        c = float(max(1.0, np.sqrt(np.max(sig_a / new_a)), np.max(sig_v / new_v)))
        sig_a, sig_v = new_a, new_v
        tau_start = tau * c
    secs = time.perf_counter() - t0
    _, tau, res = best
    t = np.concatenate([[0.0], np.cumsum(tau)])
    sp_ = spline_segment(t, path)
    s = limit_stretch(sp_, t[-1], vmax, amax)
    if s > 1.0:
        t = t * s
        sp_ = spline_segment(t, path)
    return TemporalResult(t=t, q=path.copy(), qd=sp_(t, 1), qdd=sp_(t, 2), tau=tau, tau0=tau_first, stretch=s,
                          cfs=res, seconds=secs)


def fixed_dt_segment(path, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, q, qd, qdd) of the clamped spline through ``path`` at the fixed step ``dt``."""
    path = as_array(path, "path", (None, None))
    t = dt * np.arange(path.shape[0])
    s = spline_segment(t, path)
    return t, path.copy(), s(t, 1), s(t, 2)


def concatenate_segments(parts: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
                         joint_names: list[str], meta: dict | None = None) -> Trajectory:
    """Join per-segment (t, q, qd, qdd) (each from t=0, sharing end/start waypoints) into one
    :class:`Trajectory`; the shared waypoint appears once (zero velocity there)."""
    T, Q, QD, QDD = [], [], [], []
    offset = 0.0
    for i, (t, q, qd, qdd) in enumerate(parts):
        sl = slice(0 if i == 0 else 1, None)
        T.append(t[sl] + offset)
        Q.append(q[sl])
        QD.append(qd[sl])
        QDD.append(qdd[sl])
        offset += float(t[-1])
    return Trajectory(np.concatenate(T), np.concatenate(Q), np.concatenate(QD), np.concatenate(QDD),
                      list(joint_names), dict(meta or {}))
