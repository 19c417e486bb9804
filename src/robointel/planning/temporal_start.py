"""Feasible starting schedules for the CFS of temporal optimization (7.7)-(7.9).

Every CFS solve of (7.7)-(7.9) starts from a feasible, nearly optimal schedule: :func:`pass_start`
is a compiled TOPP-like backward/forward pass over the squared interval speeds, so CFS converges in
a few iterations instead of many from the uniform step. :func:`scaled_start` (velocity-shaped) and
the uniform step :func:`feasible_uniform_dt` are the alternatives (:class:`TemporalSettings.start`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from robointel.planning.temporal_settings import TemporalSettings

#: any numpy array (the compiled kernels take contiguous float64/int64/bool arrays)
Arr = NDArray[Any]

__all__ = ["accel_ratio", "feasible_uniform_dt", "pass_start", "scaled_start", "start_schedule", "step_bounds"]


def feasible_uniform_dt(path: np.ndarray, vmax: np.ndarray, amax: np.ndarray,
                        dt: float | None = None) -> float:
    """Smallest uniform step (>= ``dt`` if given) meeting (7.7)-(7.9) on the path."""
    dx = np.diff(path, axis=0)
    need = [np.max(np.abs(dx) / vmax)]
    if len(dx) > 1:
        need.append(np.sqrt(np.max(np.abs(np.diff(dx, axis=0)) / amax)))
    need.append(np.sqrt(np.max(2 * np.abs(dx[[0, -1]]) / amax)))
    h = max(float(max(need)), 1e-4)
    return max(h, dt) if dt is not None else h


def scaled_start(dx: np.ndarray, vmax: np.ndarray, amax: np.ndarray, h0: float) -> np.ndarray:
    """A feasible starting schedule shaped like the path.

    The velocity-limited steps ``b_k = max_j |dx_kj| / vmax_j`` scaled uniformly by the smallest factor c >= 1
    meeting (7.7)-(7.9) (accelerations scale by 1 / c^2); falls back to the uniform step ``h0``.
    """
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
def _pass_x(dx: Arr, A: Arr, xcap: Arr, xlo: float) -> Arr:  # pragma: no cover - compiled
    """Forward/backward pass over the squared interval speeds x_k = 1 / tau_k^2 in [xlo, xcap_k] (see pass_start).

    (xlo, xlo) must satisfy every pair constraint.
    """
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


def step_bounds(dx: np.ndarray, vmax: np.ndarray, amax_k: np.ndarray,
                vscale: np.ndarray | None = None) -> np.ndarray:
    """(N,) smallest admissible steps.

    Velocity limits |dx_k| <= vmax tau_k and the start/stop constraints (7.9) on the first and last step.
    """
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


def pass_start(dx: np.ndarray, vmax: np.ndarray, amax_k: np.ndarray,
               vscale: np.ndarray | None = None) -> np.ndarray:
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
        dx: (N, n) path increments, rad.
        vmax: (n,) velocity limits, rad/s.
        amax_k: (N+1, n) acceleration limit at each knot, rad/s^2.
        vscale: (N,) factors on the velocity limits per interval (None: 1).

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


def start_schedule(dx: NDArray[np.float64], vmax: NDArray[np.float64], amax_k: NDArray[np.float64],
                   vscale: NDArray[np.float64] | None, h_min: float, *,
                   settings: TemporalSettings) -> NDArray[np.float64]:
    """Starting schedule of a CFS solve according to ``settings.start`` (always feasible).

    Args:
        dx: (N, n) path increments, rad.
        vmax: (n,) velocity limits, rad/s.
        amax_k: (N+1, n) acceleration limit at each knot, rad/s^2.
        vscale: (N,) factors on the velocity limits per interval, or None.
        h_min: the smallest feasible uniform step, s.
        settings: the algorithm settings.

    Returns:
        (N,) steps tau, s.
    """
    N = len(dx)
    if settings.start == "pass":
        tau = pass_start(dx, vmax, amax_k, vscale)
        if np.all(np.isfinite(tau)):
            return tau
    if settings.start == "scaled":
        return scaled_start(dx, vmax, amax_k[0], h_min)
    return np.full(N, h_min)
