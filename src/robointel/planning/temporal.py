"""Temporal optimization (7.7)-(7.9): re-time a fixed path by CFS to shorten the cycle.

Given the planned path points x_0..x_N of one segment (stop-by waypoints at both ends, zero
velocity there), find the time intervals tau_1..tau_N > 0 that

    minimise   w3 sum_k tau_k + w4/2 sum_k (tau_{k+1} - tau_k)^2                      (7.7)
    subject to |x_k - x_{k-1}| <= vmax tau_k                     (velocity, linear in tau)
               |v_{k+1} - v_k| <= amax (tau_k + tau_{k+1}) / 2    (acceleration at knot k)   (7.8)
               2 |x_1 - x_0| <= amax tau_1^2,  2 |x_N - x_{N-1}| <= amax tau_N^2  (from/to rest) (7.9)

with v_k = (x_k - x_{k-1}) / tau_k. The quadratic term (w4) penalises changes of the time step, i.e.
the jerkiness of the discrete acceleration profile; it also makes the cost strictly convex as
Algorithm 2 requires. The pieces: a feasible starting schedule (:mod:`.temporal_start`), the CFS
solve of (7.7)-(7.9) (:mod:`.temporal_cfs`), the clamped spline and its limit ratios
(:mod:`.clamped_spline`), and the settings (:class:`TemporalSettings`).

The executable trajectory is the C2 cubic spline through ``(t_k, x_k)`` with zero velocity at the
segment ends; it is checked against the velocity and acceleration limits exactly, and the segment's
time is stretched uniformly by the (usually tiny) factor needed to meet them, so the output never
violates the limits.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline

from robointel._validate import as_array
from robointel.errors import InvalidInput, LimitViolation
from robointel.planning.cfs import CFSResult
from robointel.planning.clamped_spline import clamped_spline_knots, knot_ratios, limit_stretch, spline_segment
from robointel.planning.qp import DenseQP, SparseQP
from robointel.planning.temporal_cfs import solve_tau
from robointel.planning.temporal_settings import TemporalSettings
from robointel.planning.temporal_start import feasible_uniform_dt, start_schedule
from robointel.trajectory import Trajectory

__all__ = ["TemporalResult", "TemporalSettings", "concatenate_segments", "feasible_uniform_dt", "fixed_dt_segment",
           "limit_stretch", "spline_segment", "temporal_optimize"]


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
    tau: NDArray[np.float64]
    tau0: NDArray[np.float64]
    stretch: float
    cfs: CFSResult
    seconds: float

    @property
    def duration(self) -> float:
        """Duration of the re-timed segment, s."""
        return self.trajectory.duration


def _limits(v: ArrayLike, n: int, name: str) -> NDArray[np.float64]:
    """``v`` broadcast to (n,) and checked positive."""
    out = as_array(np.broadcast_to(np.asarray(v, float), (n,)), name, (n,))
    if np.any(out <= 0):
        raise LimitViolation(f"{name} must be positive for every joint, got {out}", value=out)
    return out


def _tighten(sig_a: NDArray[np.float64], sig_v: NDArray[np.float64], ra: NDArray[np.float64],
             rv: NDArray[np.float64], st: TemporalSettings) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rescaled per-knot acceleration and per-interval velocity factors (``st.refine_mode``)."""
    if st.refine_mode == "both":
        return np.clip(sig_a / np.maximum(ra, 1e-3), 0.2, 2.0), np.clip(sig_v / np.maximum(rv, 1e-3), 0.2, 2.0)
    if st.refine_mode == "spread":  # also tighten the neighbours of a tightened knot (damped)
        fa = np.minimum(1.0, 1.0 / np.maximum(ra, 1e-3))
        nb = np.minimum(np.r_[1.0, fa[:-1]], np.r_[fa[1:], 1.0]) ** st.spread
        fv = np.minimum(1.0, 1.0 / np.maximum(rv, 1e-3))
        return np.clip(sig_a * np.minimum(fa, nb), 0.2, 2.0), np.clip(sig_v * fv, 0.2, 2.0)
    pw = st.refine_power if st.refine_mode == "tighten" else 0.5
    return (np.clip(sig_a * np.minimum(1.0, 1.0 / np.maximum(ra, 1e-3)) ** pw, 0.2, 2.0),
            np.clip(sig_v * np.minimum(1.0, 1.0 / np.maximum(rv, 1e-3)) ** pw, 0.2, 2.0))


def temporal_optimize(path: ArrayLike, vmax: ArrayLike, amax: ArrayLike, *, dt: float | None = None,
                      w3: float = 1.0, w4: float = 1.0, eps: float = 1e-4, max_iter: int = 30, refine: int = 6,
                      upsample: int = 1, trust: float | None = None, qp: DenseQP | SparseQP | None = None,
                      settings: TemporalSettings | None = None) -> TemporalResult:
    """Solve (7.7)-(7.9) by CFS for one segment and return its spline trajectory.

    After each CFS solve the spline through the re-timed knots is compared with the limits: at
    knots where the spline's acceleration exceeds the limit (or intervals where its velocity does)
    the limit used by (7.8) is tightened by that ratio (and its neighbours' a little, see
    :attr:`TemporalSettings.refine_mode`), and CFS is re-run from the forward/backward pass under the new
    limits (``refine`` rounds at most, stopping once the spline is within
    :attr:`TemporalSettings.refine_tol` of the limits).
    The shortest result is kept and finally stretched uniformly so that the spline meets the limits
    exactly (knots and every piece's velocity extremum).

    Args:
        path: (N+1, n) path points (rad), N >= 1; zero velocity at both ends.
        vmax: (n,) or scalar velocity limits, rad/s.
        amax: (n,) or scalar acceleration limits, rad/s^2.
        dt: the fixed time step of the input path (only rescaled when up-sampling; the CFS starts
            from the smallest feasible uniform step).
        w3: weight of the total time in (7.7).
        w4: weight of the time-step changes in (7.7).
        eps: CFS stopping rule on the step length, s (per solve).
        max_iter: CFS iteration cap (per solve).
        refine: limit-rescaling rounds.
        upsample: the path is re-sampled with ``upsample`` points per input interval on its
            geometric spline (path parameter uniform over the input points; the input points are
            kept) before re-timing: finer knots bring the discrete model (7.8) closer to the
            executed spline.
        trust: ``None``: the curved sets (7.6) are handled by tangent cuts and an exact pull-back;
            a number: by the polyhedral inner approximation on a trust box of that fraction of the
            time step (one QP per iteration, see :func:`robointel.planning.cfs.cfs`).
        qp: QP solver (default: a fresh :class:`DenseQP`).
        settings: algorithm switches (default :class:`TemporalSettings`, the tuned ones).

    Returns:
        The re-timed segment: its :class:`Trajectory` (from t = 0) and the solver's figures.

    Raises:
        InvalidInput: bad shapes or NaN, fewer than two points, non-positive ``dt``, ``upsample`` < 1.
        LimitViolation: non-positive limits.
        InfeasibleProblem: the first convex subproblem is infeasible.
    """
    st = settings or TemporalSettings()
    P = as_array(path, "path", (None, None))
    if P.shape[0] < 2:
        raise InvalidInput(f"path needs at least 2 points, got {P.shape[0]}", value=P.shape)
    N, n = P.shape[0] - 1, P.shape[1]
    vmax, amax = _limits(vmax, n, "vmax"), _limits(amax, n, "amax")
    if dt is not None and not dt > 0:
        raise InvalidInput(f"dt must be positive, got {dt}", value=dt)
    qp = qp or DenseQP()
    if int(upsample) < 1:
        raise InvalidInput(f"upsample must be >= 1, got {upsample}", value=upsample)
    if upsample > 1:
        geo = CubicSpline(np.arange(N + 1), P, axis=0)
        P = geo(np.arange(N * int(upsample) + 1) / int(upsample))
        dt = None if dt is None else dt / int(upsample)
        N = P.shape[0] - 1
    dx = np.diff(P, axis=0)
    t0 = time.perf_counter()
    h_min = feasible_uniform_dt(P, vmax, amax, None)  # no floor at the input's dt
    sig_a = np.ones(N + 1)
    sig_v = np.ones(N)
    tau_start = start_schedule(dx, vmax, amax[None] * sig_a[:, None], sig_v, h_min, settings=st)
    tau_first = tau_start.copy()
    best: tuple[float, NDArray[np.float64], CFSResult] | None = None
    for _round in range(refine + 1):
        res = solve_tau(dx, vmax, amax[None] * sig_a[:, None], sig_v, tau_start, w3, w4, eps, max_iter, qp, trust,
                        settings=st)
        tau = np.maximum(res.z, 1e-6)
        t = np.concatenate([[0.0], np.cumsum(tau)])
        ra, rv = knot_ratios(t, P, vmax, amax)
        s = float(max(1.0, rv.max(), np.sqrt(ra.max())))
        if best is None or t[-1] * s < best[0]:
            best = (t[-1] * s, tau, res)
        if s <= 1.0 + st.refine_tol:
            break
        # rescale the limits where the spline and the discrete model disagree, warm start feasibly
        new_a, new_v = _tighten(sig_a, sig_v, ra, rv, st)
        c = float(max(1.0, np.sqrt(np.max(sig_a / new_a)), np.max(sig_v / new_v)))
        sig_a, sig_v = new_a, new_v
        if st.start == "pass":  # the pass under the new limits (nearer their optimum than tau * c)
            tau_start = start_schedule(dx, vmax, amax[None] * sig_a[:, None], sig_v, h_min, settings=st)
        else:
            tau_start = tau * c
    secs = time.perf_counter() - t0
    assert best is not None  # refine >= 0: at least one round
    _, tau, res = best
    t = np.concatenate([[0.0], np.cumsum(tau)])
    # the clamped spline's knot velocities/accelerations and its exact peak ratios (compiled; the
    # same spline as :func:`spline_segment`, the same factor as :func:`limit_stretch`)
    V, M, rv_max, ra_max = clamped_spline_knots(t, np.ascontiguousarray(P, dtype=float), vmax, amax)
    s = float(max(1.0, rv_max, np.sqrt(ra_max)) * (1 + 1e-7))
    t, V, M = t * s, V / s, M / (s * s)  # the same curve, slower by s
    return TemporalResult(trajectory=Trajectory(t, P.copy(), V, M), tau=tau, tau0=tau_first, stretch=s,
                          cfs=res, seconds=secs)


def fixed_dt_segment(path: ArrayLike, dt: float) -> Trajectory:
    """The clamped spline through the path at a fixed step, the baseline the FRMP is compared with.

    Args:
        path: (N+1, n) path points, rad.
        dt: The fixed time step, s.

    Returns:
        The trajectory from t = 0 through every point, at rest at both ends.

    Raises:
        ShapeError, NotFinite: bad path.
    """
    P = as_array(path, "path", (None, None))
    t = dt * np.arange(P.shape[0])
    s = spline_segment(t, P)
    return Trajectory(t.astype(float), P.copy(), s(t, 1), s(t, 2))


def concatenate_segments(parts: list[Trajectory], joint_names: list[str],
                         meta: dict[str, Any] | None = None) -> Trajectory:
    """Join per-segment trajectories sharing their end/start waypoints into one.

    Args:
        parts: The segments in order; each one's first point is the previous one's last.
        joint_names: n joint names of the result.
        meta: Metadata of the result.

    Returns:
        One trajectory from the first segment's start; each shared waypoint appears once.
    """
    T: list[NDArray[np.float64]] = []
    Q: list[NDArray[np.float64]] = []
    QD: list[NDArray[np.float64]] = []
    QDD: list[NDArray[np.float64]] = []
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
