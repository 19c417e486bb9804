"""The SQP baseline of Table 7.1: the same nonconvex problem given to a general-purpose SQP.

``scipy.optimize.minimize(method="SLSQP")`` on ``min 1/2 z'Hz + f'z  s.t. phi(z) >= 0,
l <= Az <= u``, with the same cost, the same exact constraints, the same initial guess and the same
stopping tolerance as :func:`robointel.planning.cfs.cfs`.
"""
from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import minimize

from robointel.planning.cfs import NonlinearConstraint
from robointel.planning.waypoints import straight_reference

if TYPE_CHECKING:  # pragma: no cover
    from robointel.planning.waypoints import TrajectoryPlanner


@dataclass
class SQPResult:
    """SLSQP outcome: solution, iterations, success flag, message, final cost, wall time."""

    z: np.ndarray
    iterations: int
    success: bool
    message: str
    cost: float
    max_violation: float
    seconds: float


def slsqp(H: np.ndarray | sp.spmatrix, f: np.ndarray, *, constraints: Sequence[NonlinearConstraint] = (),
          A: np.ndarray | sp.spmatrix | None = None,
          l: np.ndarray | None = None, u: np.ndarray | None = None, z0: np.ndarray | None = None, tol: float = 1e-6,
          max_iter: int = 500, bounds: np.ndarray | None = None) -> SQPResult:
    """Solve the CFS problem with SLSQP (the baseline). Same arguments as :func:`cfs`.

    ``bounds`` ((n,), (n,)) may carry simple variable bounds separately (SLSQP handles them natively).
    """
    Hd = H.toarray() if sp.issparse(H) else np.asarray(H, float)  # type: ignore[union-attr]
    f = np.asarray(f, float)
    n = f.size
    z0 = np.zeros(n) if z0 is None else np.asarray(z0, float)
    cons: list[dict[str, Any]] = []
    for c in constraints:
        cons.append({"type": "ineq", "fun": c.fun, "jac": c.jac})
    if A is not None:
        Ad = A.toarray() if sp.issparse(A) else np.asarray(A, float)  # type: ignore[union-attr]
        lo = np.full(Ad.shape[0], -np.inf) if l is None else np.asarray(l, float)
        up = np.full(Ad.shape[0], np.inf) if u is None else np.asarray(u, float)
        eq = np.isfinite(lo) & np.isfinite(up) & (np.abs(up - lo) < 1e-12)
        if np.any(eq):
            cons.append({"type": "eq", "fun": lambda z, M=Ad[eq], b=lo[eq]: M @ z - b, "jac": lambda z, M=Ad[eq]: M})
        li = np.isfinite(lo) & ~eq
        if np.any(li):
            cons.append({"type": "ineq", "fun": lambda z, M=Ad[li], b=lo[li]: M @ z - b, "jac": lambda z, M=Ad[li]: M})
        ui = np.isfinite(up) & ~eq
        if np.any(ui):
            cons.append({"type": "ineq", "fun": lambda z, M=Ad[ui], b=up[ui]: b - M @ z, "jac": lambda z, M=-Ad[ui]: M})
    t0 = time.perf_counter()
    res = minimize(lambda z: 0.5 * z @ Hd @ z + f @ z, z0, jac=lambda z: Hd @ z + f, method="SLSQP",
                   constraints=cons, bounds=None if bounds is None else list(zip(*bounds)),
                   options={"maxiter": max_iter, "ftol": tol})
    secs = time.perf_counter() - t0
    viol = 0.0
    for con in cons:
        v = np.asarray(con["fun"](res.x))
        viol = max(viol, float(np.max(np.abs(v) if con["type"] == "eq" else -v, initial=0.0)))
    return SQPResult(z=res.x, iterations=int(res.nit), success=bool(res.success), message=str(res.message),
                     cost=float(res.fun), max_violation=max(viol, 0.0), seconds=secs)


def slsqp_segment(planner: TrajectoryPlanner, start: ArrayLike, goal: ArrayLike, *, reference: ArrayLike | None = None,
                  tol: float = 1e-4, max_iter: int = 500, pairs: str = "all") -> tuple[np.ndarray, SQPResult]:
    """The SQP baseline of Table 7.1 for one segment of a :class:`TrajectoryPlanner`.

    Same cost (7.1), same linear limits, same exact distance constraints
    ``d(x(s)) >= d_min + safety`` at the same samples (every movable sphere x every obstacle,
    ``pairs="all"``), same initial guess (the reference), solved by SLSQP.

    Returns:
        (path (N+1, n), :class:`SQPResult`).
    """
    n, N = planner.n, planner.N
    x0, xN = np.asarray(start, float), np.asarray(goal, float)
    Xr = straight_reference(x0, xN, N) if reference is None else np.asarray(reference, float)
    P, q = planner.cost_terms(x0, xN, Xr)
    lo, up = planner._linear_bounds(x0, xN)
    A_lin = planner.A[: planner._m_lin, : planner.nv]
    d_req = planner.settings.d_min + planner.settings.safety
    t_s, a_s = planner._sample_t, planner._sample_a
    S = len(t_s)

    def knots(z: np.ndarray) -> NDArray[np.float64]:
        X = np.empty((N + 1, n))
        X[0], X[N] = x0, xN
        X[1:N] = z.reshape(N - 1, n)
        return X

    cache: dict[bytes, Any] = {}

    def dist(z: np.ndarray) -> Any:
        key = z.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = planner.distances(knots(z), cull=False)  # a fixed set of constraints
        return cache[key]

    def fun(z: np.ndarray) -> NDArray[np.float64]:
        return dist(z).d.reshape(-1) - d_req

    def jac(z: np.ndarray) -> NDArray[np.float64]:
        D = dist(z)
        g = D.grad.reshape(S, -1, n)
        J = np.zeros((S, g.shape[1], N - 1, n))
        for side, w in ((0, 1 - a_s), (1, a_s)):
            b = t_s + side
            ok = (b >= 1) & (b <= N - 1) & (w > 0)
            J[np.flatnonzero(ok), :, b[ok] - 1, :] += w[ok, None, None] * g[ok]
        return J.reshape(S * g.shape[1], (N - 1) * n)

    cons = [NonlinearConstraint(fun, jac, kind="general", hess_lb=0.0, name="clearance")] if planner.obstacles else []
    res = slsqp(P, q, constraints=cons, A=A_lin, l=lo, u=up, z0=Xr[1:N].ravel(), tol=tol, max_iter=max_iter)
    return knots(res.z), res
