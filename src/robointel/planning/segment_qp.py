"""The QP of one CFS iteration of a waypoint segment, solved by DAQP on a working set or by OSQP in place.

The waypoint planner (:class:`robointel.planning.waypoints.TrajectoryPlanner`) builds the QP once --
cost ``P_z`` and a constraint matrix ``A`` of fixed sparsity -- and at each CFS iteration overwrites
``A``'s entries, the bounds and the linear cost. :class:`SegmentQPSolver` solves it:

- ``"daqp"`` (default): DAQP (dual active set, dense, exact) on a working set of rows -- every
  clearance row and slack bound, plus the limit rows within reach of the current iterate -- with
  violated rows added and the QP re-solved until none is violated (lazy constraint generation;
  usually one round, since the joint limits are rarely active), warm-started with the previous duals.
  Once the elastic slacks are fixed at zero (the reference is clear), they leave the QP.
- ``"osqp"``: the whole QP on OSQP, one workspace set up once, then ``update(q=, l=, u=, Ax=)`` and
  warm start.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from robointel.errors import InvalidInput
from robointel.planning.qp import INF, DenseQP, QPSolution, SparseQP, cholesky_factor

SOLVERS = ("daqp", "osqp")
"""The solvers :class:`SegmentQPSolver` offers."""


class SegmentQPSolver:
    """Solves min 1/2 z'P_z z + q'z s.t. l <= A z <= u for one segment, keeping warm-start state between calls.

    Args:
        P_z: (nz, nz) sparse cost matrix (constant).
        A: (m, nz) sparse constraint matrix of fixed pattern (its ``data`` is given at each solve).
        nv: the number of path variables; z[nv:] are the elastic slacks.
        always: (m,) rows always in DAQP's working set (the slack bounds).
        slack_rows: indices of the slack bound rows.
        reach: (m,) a row joins the working set when the iterate is within this of its bound.
        solver: ``"daqp"`` or ``"osqp"``.

    Raises:
        InvalidInput: an unknown solver.
    """

    def __init__(self, P_z: Any, A: Any, *, nv: int, always: np.ndarray, slack_rows: np.ndarray,
                 reach: np.ndarray, solver: str = "daqp") -> None:
        if solver not in SOLVERS:
            raise InvalidInput(f"solver must be 'daqp' or 'osqp', got {solver!r}", value=solver)
        self.solver = solver
        self.P_z, self.A = P_z, A
        self.nv, self.nz = int(nv), int(A.shape[1])
        self._always, self._slack_rows, self._reach = always, slack_rows, reach
        self.qp = SparseQP(eps_abs=1e-5, eps_rel=1e-5, polishing=False, max_iter=20000)
        self._dense = DenseQP()
        self._Pz_dense: np.ndarray | None = None
        self._factors: dict[bool, tuple[np.ndarray, np.ndarray] | None] = {}  # per "slacks in the QP"
        self._Ad: np.ndarray | None = None
        self._data_rc: tuple[np.ndarray, np.ndarray] | None = None
        self._y_full: np.ndarray | None = None
        self._qp_ready = False
        self.stats: dict[str, int] = {"osqp": 0, "daqp": 0}
        """QPs solved by each solver, and DAQP's iterations (``daqp_iterations``)."""

    def reset(self) -> None:
        """Forget the previous solutions (for cold-start timings); the counts in :attr:`stats` stay."""
        self._dense = DenseQP()
        self._y_full = None
        self.qp = SparseQP(**{k: v for k, v in self.qp.settings.items()})
        self._qp_ready = False

    def solve(self, qz: np.ndarray, l: np.ndarray, u: np.ndarray, data: np.ndarray, z0: np.ndarray) -> QPSolution:
        """Solve the QP with linear cost ``qz`` (nz,), bounds ``l``, ``u`` (m,) and ``A``'s entries ``data``.

        Args:
            qz: (nz,) linear cost.
            l: (m,) lower bounds (-INF: none).
            u: (m,) upper bounds (INF: none); slack rows with ``u`` = 0 fix the slacks at zero.
            data: ``A``'s CSC data in its fixed pattern.
            z0: (nz,) the current iterate (warm start; the working set is chosen around it).

        Returns:
            The solution; ``x`` is always (nz,) (zero slacks when they were left out).
        """
        if self.solver == "osqp":
            if not self._qp_ready:
                self.A.data = data
                osqp_sol = self.qp.solve(self.P_z, qz, self.A, l, u, x0=z0)
                self._qp_ready = True
            else:
                osqp_sol = self.qp.update(q=qz, l=l, u=u, Ax=data, x0=z0)
            self.stats["osqp"] += 1
            return osqp_sol
        Ad = self._dense_A(data)
        if self._Pz_dense is None:
            P = self.P_z.toarray()
            self._Pz_dense = np.ascontiguousarray(np.triu(P) + np.triu(P, 1).T)
        Pz = self._Pz_dense
        finite = (l > -INF / 2) | (u < INF / 2)
        Az = Ad @ z0
        span = np.where(np.isfinite(u - l), u - l, np.inf)
        near = ((Az - l < 0.5 * span + 1e-9) & (Az - l < self._reach)) | (u - Az < self._reach)
        work = finite & (self._always | near)
        # the elastic slacks are fixed at zero once the reference is clear: drop them from the QP
        elastic = bool(np.any(u[self._slack_rows] > 0))
        nvar = self.nz if elastic else self.nv
        if not elastic:
            work[self._slack_rows] = False
        P = Pz if elastic else Pz[: self.nv, : self.nv]
        if elastic not in self._factors:  # P is the same at every call: factored once
            self._factors[elastic] = cholesky_factor(P)
        factor = self._factors[elastic]
        sol: QPSolution | None = None
        for _ in range(8):
            y0 = self._y_full[work] if self._y_full is not None else None
            sol = self._dense.solve(P, qz[:nvar], np.ascontiguousarray(Ad[work, :nvar]), l[work], u[work],
                                    x0=z0[:nvar], full_P=True, y0=y0, factor=factor)
            self.stats["daqp"] += 1
            self.stats["daqp_iterations"] = self.stats.get("daqp_iterations", 0) + sol.iterations
            if not sol.solved:
                return sol
            y_full = np.zeros(len(l))
            y_full[work] = sol.y
            self._y_full = y_full
            x = sol.x if elastic else np.r_[sol.x, np.zeros(self.nz - self.nv)]
            Ax = Ad @ x
            viol = finite & ~work & ((Ax < l - 1e-7) | (Ax > u + 1e-7))
            if not elastic:
                viol[self._slack_rows] = False
            if not np.any(viol):
                sol.x = x
                return sol
            work |= viol
        assert sol is not None  # the loop ran at least once
        if not elastic:
            sol.x = np.r_[sol.x, np.zeros(self.nz - self.nv)]
        return sol

    def _dense_A(self, data: np.ndarray) -> np.ndarray:
        """The constraint matrix as a dense array, filled in place from CSC ``data``."""
        if self._Ad is None or self._data_rc is None:
            self._Ad = self.A.toarray()
            # position of each CSC data entry: row/col of data index p
            cols = np.repeat(np.arange(self.A.shape[1]), np.diff(self.A.indptr))
            self._data_rc = (self.A.indices.copy(), cols)
        Ad = self._Ad
        Ad[self._data_rc] = data
        return Ad
