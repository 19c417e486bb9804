"""The Convex Feasible Set algorithm (Algorithm 2, Sec. 7.2).

Problem:  ``min_z J(z) = 1/2 z'Hz + f'z``  (H positive definite)
subject to ``phi_i(z) >= 0`` (nonlinear, i = 1..m) and ``l <= A z <= u`` (linear).

At a reference ``z_r`` the infeasible set of each ``phi_i`` is replaced by a convex feasible set
``F_i(z_r)`` contained in ``Gamma_i = {phi_i >= 0}``; the QP ``min J(z) s.t. z in F(z_r)`` is solved
and its solution becomes the next reference, until ``||z(k+1) - z(k)|| <= eps``. The three cases:

* ``"convex"``: Gamma_i itself is convex (phi_i concave): F_i = Gamma_i.
* ``"complement_convex"`` (7.5): the complement of Gamma_i is convex (phi_i convex):
  F_i = {z : phi_i(z_r) + grad phi_i(z_r)(z - z_r) >= 0}, a half space inside Gamma_i.
* ``"general"`` (7.6): neither; with a lower bound ``H*_i`` on the Hessian of phi_i,
  F_i = {z : phi_i(z_r) + grad phi_i(z_r)(z - z_r) + 1/2 (z - z_r)' H*_i (z - z_r) >= 0}.

Sets that are convex but not polyhedral (the first and third case) are handled inside the QP by
outer tangent cuts (a few rounds) followed by an exact pull-back along the segment from ``z_r``
(which lies in F) to the QP solution, so every iterate lies in F(z_r) and hence in the feasible
set: the iterates are feasible and the cost never increases once the reference is feasible.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike

from robointel._validate import as_array
from robointel.errors import InfeasibleProblem, InvalidInput
from robointel.planning.qp import INF, DenseQP, SparseQP

KINDS = ("convex", "complement_convex", "general")


@dataclass
class NonlinearConstraint:
    """``phi(z) >= 0`` with its Jacobian, and which CFS case it is.

    Attributes:
        fun: ``z (n,) -> phi (m,)``.
        jac: ``z (n,) -> dphi/dz (m, n)``.
        kind: ``"convex"``, ``"complement_convex"`` or ``"general"`` (see module docstring).
        hess_lb: for ``"general"``: lower bound of each phi_i's Hessian, a scalar mu <= 0
            (H* = mu I for all i), an (m,) array of such scalars, an (n, n) matrix H* (<= 0) shared by
            all, or an (m, n, n) stack of matrices, one per phi_i.
        name: used in messages.
        hess_diag: for ``"general"``, alternative to ``hess_lb``: an (m, n) array whose row i is the
            diagonal of a diagonal H*_i (cheap for many constraints on many variables).
    """

    fun: Callable[[np.ndarray], np.ndarray]
    jac: Callable[[np.ndarray], np.ndarray]
    kind: str = "complement_convex"
    hess_lb: float | np.ndarray | None = None
    name: str = "phi"
    hess_diag: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InvalidInput(f"constraint {self.name!r}: kind must be one of {KINDS}, got {self.kind!r}",
                               value=self.kind)
        if self.kind == "general" and self.hess_lb is None and self.hess_diag is None:
            raise InvalidInput(f"constraint {self.name!r}: kind 'general' needs hess_lb (the Hessian lower "
                               "bound H* of (7.6))")


@dataclass
class CFSResult:
    """Outcome of :func:`cfs`.

    Attributes:
        z: the solution (the best feasible iterate when the iteration cap was hit).
        iterations: CFS iterations run (QPs solved, not counting cut rounds).
        costs: J at each iterate, ``costs[0]`` at the initial guess.
        status: ``"converged"``, ``"max_iter"`` (cap hit: ``z`` is the best feasible iterate) or
            ``"qp_failed"`` (a QP failed after some progress; ``z`` is the best feasible iterate).
        feasible: whether ``z`` satisfies every constraint within ``tol``.
        max_violation: largest constraint violation at ``z`` (0 when feasible).
        seconds: wall time.
        iterates: every iterate (only with ``keep_iterates=True``).
        qp_iterations: OSQP iterations summed over all QPs.
    """

    z: np.ndarray
    iterations: int
    costs: list[float]
    status: str
    feasible: bool
    max_violation: float
    seconds: float
    iterates: list[np.ndarray] = field(default_factory=list)
    qp_iterations: int = 0

    @property
    def converged(self) -> bool:
        """Whether the stopping rule was met."""
        return self.status == "converged"


def _hlb_matrix(c: NonlinearConstraint, i: int, n: int) -> np.ndarray:
    h = np.asarray(c.hess_lb, float)
    if h.ndim == 0:
        return min(float(h), 0.0) * np.eye(n)
    if h.ndim == 1:
        return min(float(h[i]), 0.0) * np.eye(n)
    if h.ndim == 3:
        return h[i]
    return h


class _ConvexSet:
    """F(z_r) of one nonlinear constraint block: linear rows plus the exact test g >= 0."""

    def __init__(self, c: NonlinearConstraint, z_r: np.ndarray, tol: float) -> None:
        self.c = c
        self.z_r = z_r
        n = z_r.size
        self.phi = np.atleast_1d(np.asarray(c.fun(z_r), float))
        self.G = np.atleast_2d(np.asarray(c.jac(z_r), float)).reshape(self.phi.size, n)
        self.ref_feasible = bool(np.all(self.phi >= -tol))
        self.H = None
        self.Hd = None
        if c.kind == "general" and c.hess_diag is not None:
            self.Hd = np.minimum(np.asarray(c.hess_diag, float).reshape(self.phi.size, n), 0.0)
        elif c.kind == "general":
            h = np.asarray(c.hess_lb, float)
            self.H = h if h.ndim == 3 else np.array([_hlb_matrix(c, i, n) for i in range(self.phi.size)])

    def rows(self, rho: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Linearisation ``G z >= G z_r - phi(z_r)`` (exact F for case 2, outer for 1 and 3).

        With a trust box ``|z - z_r| <= rho`` and case 3, the curvature term of (7.6) is bounded
        below on the box (``1/2 d'H*d >= -1/2 rho'|H*|rho``), giving half spaces inside F_i.
        """
        h = self.G @ self.z_r - self.phi
        if rho is not None and self.c.kind == "general" and self.ref_feasible:
            if self.Hd is not None:
                h = h - 0.5 * (self.Hd @ (rho * rho))
            else:
                h = h + 0.5 * np.einsum("i,kij,j->k", rho, np.abs(self.H), rho)  # type: ignore[arg-type]
        return self.G, h

    def curved_with(self, trust: bool) -> bool:
        return self.curved and not (trust and self.c.kind == "general")

    @property
    def curved(self) -> bool:
        return self.c.kind != "complement_convex" and self.ref_feasible

    def g(self, z: np.ndarray) -> np.ndarray:
        """The function whose superlevel set {g >= 0} is F_i (concave in z)."""
        if self.c.kind == "convex":
            return np.atleast_1d(np.asarray(self.c.fun(z), float))
        d = z - self.z_r
        return self.phi + self.G @ d + 0.5 * self._quad(d)

    def _quad(self, d: np.ndarray) -> np.ndarray:
        """Quadratic terms d' H*_i d for every i."""
        if self.Hd is not None:
            return self.Hd @ (d * d)
        return np.einsum("i,kij,j->k", d, self.H, d)  # type: ignore[arg-type]

    def g_jac(self, z: np.ndarray) -> np.ndarray:
        if self.c.kind == "convex":
            return np.atleast_2d(np.asarray(self.c.jac(z), float)).reshape(self.phi.size, z.size)
        d = z - self.z_r
        if self.Hd is not None:
            return self.G + self.Hd * d[None]
        return self.G + np.einsum("kij,j->ki", self.H, d)  # type: ignore[arg-type]

    def max_step(self, d: np.ndarray, tol: float) -> float:
        """Largest alpha in [0, 1] with g(z_r + alpha d) >= 0 (F is convex and contains z_r)."""
        if self.c.kind == "general":
            a = 0.5 * self._quad(d)  # <= 0
            b = self.G @ d
            c0 = self.phi
            alpha = 1.0
            g1 = a + b + c0
            for k in np.flatnonzero(g1 < 0):
                if a[k] < -1e-300:
                    disc = b[k] ** 2 - 4 * a[k] * c0[k]
                    root = (-b[k] - np.sqrt(max(disc, 0.0))) / (2 * a[k])
                else:
                    root = -c0[k] / b[k] if b[k] < 0 else 1.0
                alpha = min(alpha, max(0.0, root))
            return alpha
        if np.all(self.g(self.z_r + d) >= 0):
            return 1.0
        lo, hi = 0.0, 1.0
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if np.all(self.g(self.z_r + mid * d) >= 0):
                lo = mid
            else:
                hi = mid
            if hi - lo < tol:
                break
        return lo


def cfs(H: np.ndarray | sp.spmatrix, f: ArrayLike, *, constraints: Sequence[NonlinearConstraint] = (),
        A: np.ndarray | sp.spmatrix | None = None,
        l: np.ndarray | None = None, u: np.ndarray | None = None, z0: np.ndarray | None = None, eps: float = 1e-6,
        max_iter: int = 100, tol: float = 1e-9, max_cuts: int = 5, keep_iterates: bool = False,
        qp: SparseQP | DenseQP | None = None, trust: ArrayLike | None = None, ftol: float = 0.0) -> CFSResult:
    """Solve ``min 1/2 z'Hz + f'z  s.t. phi_i(z) >= 0, l <= Az <= u`` by CFS (Algorithm 2).

    Args:
        H: (n, n) positive definite cost Hessian (dense or sparse).
        f: (n,) linear cost term.
        constraints: nonlinear constraints, each tagged with its CFS case.
        A: (m, n) linear constraint matrix (dense or sparse); ``None`` for none.
        l: (m,) lower bounds of ``A z`` (default -inf).
        u: (m,) upper bounds of ``A z`` (default +inf).
        z0: (n,) initial guess (should be feasible for the nonlinear constraints; if it is not,
            the first iterations use plain linearisations until an iterate is feasible).
        eps: stop when ``||z(k+1) - z(k)|| <= eps`` ...
        ftol: ... or (if > 0) when a feasible iterate after a feasible one lowered the cost by
            no more than ``ftol`` relative (the iterates of CFS are feasible and J is monotone).
        max_iter: iteration cap; when hit, the best feasible iterate is returned with
            ``status="max_iter"``.
        tol: feasibility tolerance on phi.
        max_cuts: tangent-cut rounds per iteration for the curved sets (cases 1 and 3).
        keep_iterates: keep every iterate on the result (for inspection and tests).
        qp: the QP solver to use and reuse (warm start across calls): a :class:`SparseQP` (OSQP;
            default above 200 variables) or a :class:`DenseQP` (DAQP; default for small problems).
        trust: for case-3 constraints, instead of cuts use a polyhedral inner approximation of
            (7.6) on a trust box ``|z - z_r| <= rho`` (scalar or (n,) initial radius); the radius
            follows the step length (twice the last step, at most the initial radius). One QP of
            fixed pattern per iteration.

    Returns:
        :class:`CFSResult`.

    Raises:
        InvalidInput: bad shapes, NaN.
        InfeasibleProblem: the first QP is infeasible (contradictory linear constraints).
    """
    t0 = time.perf_counter()
    Hs = sp.csc_matrix(H) if sp.issparse(H) else np.asarray(H, float)
    n = Hs.shape[0]
    if Hs.ndim != 2 or Hs.shape != (n, n):
        raise InvalidInput(f"H must be square, got {Hs.shape}", value=Hs.shape)
    if not np.all(np.isfinite(Hs.data if sp.issparse(Hs) else Hs)):
        raise InvalidInput("H contains NaN or inf", value=H)
    f = as_array(f, "f", (n,))
    z = as_array(z0 if z0 is not None else np.zeros(n), "z0", (n,)).copy()
    if A is None:
        A_lin, l_lin, u_lin = np.zeros((0, n)), np.zeros(0), np.zeros(0)
    else:
        A_lin = sp.csc_matrix(A) if sp.issparse(A) else np.atleast_2d(np.asarray(A, float))
        if A_lin.shape[1] != n:
            raise InvalidInput(f"A must have {n} columns, got {A_lin.shape}", value=A_lin.shape)
        m = A_lin.shape[0]
        l_lin = np.full(m, -np.inf) if l is None else np.asarray(l, float).reshape(m)
        u_lin = np.full(m, np.inf) if u is None else np.asarray(u, float).reshape(m)
        if np.any(np.isnan(l_lin)) or np.any(np.isnan(u_lin)):
            raise InvalidInput("linear bounds contain NaN", value=(l, u))
        if np.any(l_lin > u_lin):
            i = int(np.flatnonzero(l_lin > u_lin)[0])
            raise InfeasibleProblem(f"linear constraint {i}: lower bound {l_lin[i]} > upper bound {u_lin[i]}",
                                    value=i)
    qp = qp or (DenseQP() if n <= 200 else SparseQP())

    def cost(x: np.ndarray) -> float:
        return float(0.5 * x @ (Hs @ x) + f @ x)

    def violation(x: np.ndarray) -> float:
        v = 0.0
        if A_lin.shape[0]:
            Ax = A_lin @ x
            v = max(v, float(np.max(np.maximum(l_lin - Ax, Ax - u_lin), initial=0.0)))
        for c in constraints:
            v = max(v, float(np.max(-np.asarray(c.fun(x), float), initial=0.0)))
        return v

    # linear-constraint violations of an OSQP solution are ~1e-6; judge them on that scale
    lin_tol = 1e-5

    def feasible(x: np.ndarray) -> bool:
        ok = True
        if A_lin.shape[0]:
            Ax = A_lin @ x
            ok = bool(np.all(Ax >= l_lin - lin_tol * (1 + np.abs(l_lin))) and
                      np.all(Ax <= u_lin + lin_tol * (1 + np.abs(u_lin))))
        return ok and all(np.all(np.asarray(c.fun(x), float) >= -tol) for c in constraints)

    costs = [cost(z)]
    iterates = [z.copy()] if keep_iterates else []
    prev_feasible = feasible(z)
    best, best_cost = (z.copy(), costs[0]) if prev_feasible else (None, np.inf)
    status, it, qp_iters = "max_iter", 0, 0
    dense = isinstance(qp, DenseQP)
    if dense:
        Hup = Hs.toarray() if sp.issparse(Hs) else Hs  # type: ignore[union-attr]
        Hup = 0.5 * (Hup + Hup.T)
    else:
        Hup = sp.triu(sp.csc_matrix(Hs), format="csc")
    A_dense = (A_lin.toarray() if sp.issparse(A_lin) else A_lin) if dense else None  # type: ignore[union-attr,attr-defined]
    qp_kw: dict[str, Any] = {"full_P": True} if dense else {}
    y_base = y_last = None
    use_trust = trust is not None and any(c.kind == "general" for c in constraints)
    if use_trust:
        rho0 = np.broadcast_to(np.asarray(trust, float), (n,)).copy()
        if np.any(rho0 <= 0) or not np.all(np.isfinite(rho0)):
            raise InvalidInput("trust radius must be positive and finite", value=trust)
        kappa = 1.0
        A_lin_all = sp.vstack([sp.csc_matrix(A_lin), sp.eye(n, format="csc")], format="csc")
        A_dense = A_lin_all.toarray() if dense else None  # type: ignore[attr-defined]
    for it in range(1, max_iter + 1):
        sets = [_ConvexSet(c, z, tol) for c in constraints]
        G_rows, h_rows = [], []
        rho = kappa * rho0 if use_trust else None
        for s in sets:
            G, h = s.rows(rho)
            G_rows.append(G)
            h_rows.append(h)
        if use_trust:
            A_cur, l_cur, u_cur = A_lin_all, np.concatenate([l_lin, z - rho]), np.concatenate([u_lin, z + rho])
        else:
            A_cur, l_cur, u_cur = A_lin, l_lin, u_lin
        cuts_G: list[np.ndarray] = []
        cuts_h: list[np.ndarray] = []
        z_new = None
        for _round in range(max_cuts + 1):
            if dense:
                Ablk = np.vstack([A_dense] + G_rows + cuts_G)  # type: ignore[operator,arg-type]
            else:
                Ablk = sp.vstack([A_cur] + [sp.csc_matrix(G) for G in G_rows + cuts_G], format="csc")
            lo = np.concatenate([l_cur] + h_rows + cuts_h)
            up = np.concatenate([u_cur] + [np.full(len(h), INF) for h in h_rows + cuts_h])
            if dense:
                m_base = len(l_cur) + sum(len(h) for h in h_rows)
                y0 = np.zeros(len(lo))
                if y_base is not None and y_base.size == m_base:
                    y0[:m_base] = y_base
                if _round > 0 and y_last is not None:
                    y0[:y_last.size] = y_last
                sol = qp.solve(Hup, f, Ablk, lo, up, x0=z, y0=y0, **qp_kw)  # type: ignore[call-arg]
            else:
                sol = qp.solve(Hup, f, Ablk, lo, up, x0=z, **qp_kw)
            qp_iters += sol.iterations
            if not sol.solved:
                break
            z_new = sol.x
            if dense:
                y_last = sol.y
                if _round == 0:
                    y_base = sol.y[:m_base].copy()
            added = False
            for s in sets:
                if not s.curved_with(use_trust):
                    continue
                gv = s.g(z_new)
                bad = gv < -tol
                if np.any(bad):
                    Gc = s.g_jac(z_new)[bad]
                    cuts_G.append(Gc)
                    cuts_h.append(Gc @ z_new - gv[bad])
                    added = True
            if not added:
                break
        if z_new is None:
            if best is None and it == 1:
                raise InfeasibleProblem(f"the convex subproblem at the initial guess is infeasible (OSQP: "
                                        f"{sol.status}); check that the limits are consistent and z0 feasible",
                                        value=sol.status)
            status = "qp_failed"
            break
        # pull back into the curved convex sets along the segment from the reference
        d = z_new - z
        alpha = 1.0
        for s in sets:
            if s.curved:
                alpha = min(alpha, s.max_step(d, 1e-12))
        z_new = z + alpha * d
        step = float(np.linalg.norm(z_new - z))
        at_box = False
        if use_trust:
            at_box = bool(np.max(np.abs(z_new - z) / rho) > 0.99)
            kappa = float(np.clip(2.0 * np.max(np.abs(z_new - z) / rho0), 1e-6, 1.0))
        z = z_new
        costs.append(cost(z))
        if keep_iterates:
            iterates.append(z.copy())
        now_feasible = feasible(z)
        if now_feasible and costs[-1] <= best_cost:
            best, best_cost = z.copy(), costs[-1]
        if step <= eps and not at_box:
            status = "converged"
            break
        if ftol > 0 and now_feasible and prev_feasible and not at_box and \
                costs[-2] - costs[-1] <= ftol * max(abs(costs[-1]), 1e-12):
            status = "converged"
            break
        prev_feasible = now_feasible
    if status != "converged" and best is not None:
        z = best
    viol = violation(z)
    return CFSResult(z=z, iterations=it, costs=costs, status=status, feasible=feasible(z),
                     max_violation=viol, seconds=time.perf_counter() - t0, iterates=iterates,
                     qp_iterations=qp_iters)
