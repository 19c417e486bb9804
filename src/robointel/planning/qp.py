"""A sparse convex QP kept alive between CFS iterations (OSQP 1.x, warm-started, updated in place).

Every CFS iteration solves the QP (7.4) ``min 1/2 z'Pz + q'z  s.t.  l <= A z <= u``. Between
iterations only the numbers change (the linearised constraints move with the reference), so the
OSQP workspace is built once (factorisation pattern, scaling) and then updated with
``update(q=, l=, u=, Ax=)`` and warm-started from the previous primal/dual pair. When the sparsity
pattern of ``A`` changes, the problem is rebuilt.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import daqp
import numpy as np
import osqp
import scipy.linalg as sl
import scipy.sparse as sp
from numpy.typing import ArrayLike

from robointel.errors import SolverFailure

INF = 1e20

#: OSQP settings used by the planners: polished (exact active set) solutions, quiet, warm-started.
DEFAULT_SETTINGS = dict(verbose=False, eps_abs=1e-6, eps_rel=1e-6, polishing=True, warm_starting=True,
                        max_iter=20000, adaptive_rho=True, check_termination=10)


@dataclass
class QPSolution:
    """One QP solve: primal ``x`` (n,), dual ``y`` (m,), OSQP status string and iteration count."""

    x: np.ndarray
    y: np.ndarray
    status: str
    iterations: int
    solved: bool


class SparseQP:
    """``min 1/2 z'Pz + q'z  s.t.  l <= A z <= u`` with OSQP, rebuilt only when a pattern changes.

    Args:
        settings: OSQP settings overriding :data:`DEFAULT_SETTINGS`.
    """

    def __init__(self, **settings: Any) -> None:
        self.settings = dict(DEFAULT_SETTINGS, **settings)
        self._solver: osqp.OSQP | None = None
        self._P_key: tuple[Any, ...] | None = None
        self._A_key: tuple[Any, ...] | None = None
        self._last: QPSolution | None = None
        self.setups = 0

    @staticmethod
    def _key(M: sp.csc_matrix) -> tuple[Any, ...]:
        return (M.shape, M.indptr.tobytes(), M.indices.tobytes())

    def solve(self, P: sp.spmatrix, q: np.ndarray, A: sp.spmatrix, l: np.ndarray, u: np.ndarray,
              *, x0: np.ndarray | None = None) -> QPSolution:
        """Solve; ``P`` and ``A`` are sparse (P symmetric, only its upper triangle is used).

        ``x0`` warm-starts the primal (the previous solution is used otherwise).
        """
        P = sp.triu(sp.csc_matrix(P), format="csc")
        A = sp.csc_matrix(A)
        P.sort_indices()
        A.sort_indices()
        l = np.maximum(np.asarray(l, float), -INF)
        u = np.minimum(np.asarray(u, float), INF)
        kP, kA = self._key(P), self._key(A)
        if self._solver is None or kP != self._P_key or kA != self._A_key:
            self._solver = osqp.OSQP()
            self._solver.setup(P, np.asarray(q, float), A, l, u, **self.settings)
            self._P_key, self._A_key = kP, kA
            self.setups += 1
            self._last = None
        else:
            self._solver.update(q=np.asarray(q, float), l=l, u=u, Px=P.data, Ax=A.data)
        return self._run(x0)

    def update(self, *, q: np.ndarray | None = None, l: np.ndarray | None = None, u: np.ndarray | None = None,
               Ax: np.ndarray | None = None, x0: np.ndarray | None = None) -> QPSolution:
        """Change numbers of the current problem in place (same pattern) and solve."""
        if self._solver is None:
            raise SolverFailure("SparseQP.update called before solve()")
        kw = {}
        if q is not None:
            kw["q"] = np.asarray(q, float)
        if l is not None:
            kw["l"] = np.maximum(np.asarray(l, float), -INF)
        if u is not None:
            kw["u"] = np.minimum(np.asarray(u, float), INF)
        if Ax is not None:
            kw["Ax"] = np.asarray(Ax, float)
        self._solver.update(**kw)
        return self._run(x0)

    def _run(self, x0: ArrayLike | None) -> QPSolution:
        solver = self._solver
        assert solver is not None  # set up by solve()
        if x0 is not None:
            y = self._last.y if self._last is not None and self._last.y.shape[0] == solver.m else None
            if y is not None:
                solver.warm_start(x=np.asarray(x0, float), y=y)
            else:
                solver.warm_start(x=np.asarray(x0, float))
        res = solver.solve(raise_error=False)
        status = str(res.info.status)
        solved = status in ("solved", "solved inaccurate") and res.x is not None and np.all(np.isfinite(res.x))
        sol = QPSolution(np.array(res.x, float) if res.x is not None else np.full(solver.n, np.nan),
                         np.array(res.y, float) if res.y is not None else np.zeros(solver.m),
                         status, int(res.info.iter), bool(solved))
        if solved:
            self._last = sol
        return sol


def cholesky_factor(P: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(R, R^-1) with P = R'R, R upper triangular, for :meth:`DenseQP.solve`; None when P is not positive definite.

    Args:
        P: (n, n) symmetric cost matrix.
    """
    try:
        R = sl.cholesky(np.asarray(P, float), lower=False)
    except (np.linalg.LinAlgError, ValueError):
        return None
    return R, sl.solve_triangular(R, np.eye(R.shape[0]), lower=False)


class DenseQP:
    """Small dense QPs with DAQP (dual active set; microseconds for tens of variables).

    Same ``solve(P, q, A, l, u, x0=)`` interface as :class:`SparseQP`; the previous active set
    warm-starts the next solve (CFS iterations change only the numbers). Used for the temporal
    optimization, whose QPs have one variable per time step.
    """

    EXIT = {1: "solved", 2: "solved (soft)", -1: "primal infeasible", -2: "cycling", -3: "unbounded",
            -4: "iteration limit", -5: "nonconvex", -6: "initial point infeasible"}

    def __init__(self, **settings: Any) -> None:
        self.settings = dict(primal_tol=1e-9, iter_limit=2000)
        self.settings.update(settings)
        self._lam: np.ndarray | None = None
        self.setups = 0
        self.primal_start = True

    def solve(self, P: np.ndarray | sp.spmatrix, q: np.ndarray, A: np.ndarray | sp.spmatrix, l: np.ndarray,
              u: np.ndarray, *, x0: np.ndarray | None = None, full_P: bool = False,
              y0: np.ndarray | None = None, factor: tuple[np.ndarray, np.ndarray] | None = None) -> QPSolution:
        """Solve ``min 1/2 z'Pz + q'z  s.t.  l <= A z <= u`` with DAQP.

        With ``factor`` = (R, R^-1), P = R'R (:func:`cholesky_factor`), the QP is solved in v = R z
        as the least-distance problem ``min 1/2 |v|^2 + (R^-T q)'v  s.t.  l <= (A R^-1) v <= u``:
        the same solution and multipliers, with the product A R^-1 formed by one BLAS call (DAQP's
        own setup forms it row by row, most of its time on the CFS segment QPs).

        Args:
            P: (n, n) cost matrix (upper triangle used unless ``full_P``; dense or sparse).
            q: (n,) linear cost.
            A: (m, n) constraint matrix (dense or sparse).
            l: (m,) lower bounds (-inf allowed).
            u: (m,) upper bounds (inf allowed).
            x0: (n,) primal warm start (used when no dual warm start is known).
            full_P: ``P`` is already the full symmetric matrix (skip symmetrising).
            y0: (m,) dual warm start; its nonzero entries mark the initial active set.
            factor: (R, R^-1), both (n, n) upper triangular, of this ``P`` (P is then not read).

        Returns:
            The solution, its duals and DAQP's status.
        """
        Ad = A.toarray() if sp.issparse(A) else np.asarray(A, float)  # type: ignore[union-attr]
        qv = np.asarray(q, float)
        if factor is not None:
            R, Ri = factor
            Pd = np.eye(R.shape[0])
            Ad, qv = Ad @ Ri, Ri.T @ qv
            x0 = None if x0 is None else R @ np.asarray(x0, float)
        else:
            Pd = P.toarray() if sp.issparse(P) else np.asarray(P, float)  # type: ignore[union-attr]
            if not full_P:
                Pd = np.triu(Pd) + np.triu(Pd, 1).T  # accept an upper triangle like OSQP
        l = np.maximum(np.asarray(l, float), -INF)
        u = np.minimum(np.asarray(u, float), INF)
        kw: dict[str, Any] = dict(self.settings)
        if y0 is not None and np.shape(y0) == (Ad.shape[0],):
            kw["dual_start"] = np.asarray(y0, float)
        elif self._lam is not None and self._lam.shape[0] == Ad.shape[0]:
            kw["dual_start"] = self._lam
        elif x0 is not None and self.primal_start:
            kw["primal_start"] = np.asarray(x0, float)
        x, _fval, flag, info = daqp.solve(np.ascontiguousarray(Pd), qv, np.ascontiguousarray(Ad), u, l,
                                          np.zeros(Ad.shape[0], dtype=np.intc), **kw)
        x = np.asarray(x, float)
        if factor is not None:
            x = factor[1] @ x
        solved = flag in (1, 2) and np.all(np.isfinite(x))
        lam = np.asarray(info.get("lam", np.zeros(Ad.shape[0])), float)
        if solved:
            self._lam = lam
        return QPSolution(x, lam, self.EXIT.get(int(flag), str(flag)), int(info.get("iterations", 0)), bool(solved))
