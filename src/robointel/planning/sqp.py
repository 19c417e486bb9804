"""The SQP baseline of Table 7.1: the same nonconvex problem given to a general-purpose SQP.

``scipy.optimize.minimize(method="SLSQP")`` on ``min 1/2 z'Hz + f'z  s.t. phi(z) >= 0,
l <= Az <= u``, with the same cost, the same exact constraints, the same initial guess and the same
stopping tolerance as :func:`robointel.planning.cfs.cfs`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.sparse as sp
from scipy.optimize import minimize

from robointel.planning.cfs import NonlinearConstraint


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


def slsqp(H, f, *, constraints: Sequence[NonlinearConstraint] = (), A=None, l=None, u=None, z0=None,
          tol: float = 1e-6, max_iter: int = 500, bounds=None) -> SQPResult:
    """Solve the CFS problem with SLSQP (the baseline). Same arguments as :func:`cfs`.

    ``bounds`` ((n,), (n,)) may carry simple variable bounds separately (SLSQP handles them natively).
    """
    Hd = H.toarray() if sp.issparse(H) else np.asarray(H, float)
    f = np.asarray(f, float)
    n = f.size
    z0 = np.zeros(n) if z0 is None else np.asarray(z0, float)
    cons = []
    for c in constraints:
        cons.append({"type": "ineq", "fun": c.fun, "jac": c.jac})
    if A is not None:
        Ad = A.toarray() if sp.issparse(A) else np.asarray(A, float)
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
    for c in cons:
        v = np.asarray(c["fun"](res.x))
        viol = max(viol, float(np.max(np.abs(v) if c["type"] == "eq" else -v, initial=0.0)))
    return SQPResult(z=res.x, iterations=int(res.nit), success=bool(res.success), message=str(res.message),
                     cost=float(res.fun), max_violation=max(viol, 0.0), seconds=secs)
