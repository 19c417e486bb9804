"""Algorithm 2 (CFS) written for the two-variable constraint rows of temporal optimization (7.7)-(7.9).

Each acceleration row (7.8), multiplied by tau_k tau_{k+1} > 0, couples only two steps:
``amax (tau_k + tau_{k+1}) tau_k tau_{k+1} / 2 -+ (dx_{k+1} tau_k - dx_k tau_{k+1}) >= 0``, neither convex
nor concave: CFS case (7.6), with the Hessian lower bound -amax * max(ub_k, ub_{k+1}) on the
(tau_k, tau_{k+1}) block. :func:`solve_tau` builds the rows and runs either :func:`cfs_tau`
(compiled linearisation, tangent cuts and exact pull-back; DAQP on a working set of rows near their
limit, warm-started with the active set carried over by row) or the general
:func:`robointel.planning.cfs.cfs`; both give the same iterates.
"""

from __future__ import annotations

import time
from functools import lru_cache
from typing import Any

import daqp
import numpy as np
from numba import njit
from numpy.typing import NDArray

from robointel.errors import InfeasibleProblem
from robointel.planning.cfs import CFSResult, NonlinearConstraint, cfs
from robointel.planning.qp import DenseQP, SparseQP
from robointel.planning.temporal_settings import TemporalSettings
from robointel.planning.temporal_start import step_bounds

#: any numpy array (the compiled kernels take contiguous float64/int64/bool arrays)
Arr = NDArray[Any]

__all__ = ["cfs_tau", "solve_tau"]


def solve_tau(dx: NDArray[np.float64], vmax: NDArray[np.float64], amax_k: NDArray[np.float64],
              vscale: NDArray[np.float64] | None, tau0: NDArray[np.float64], w3: float, w4: float,
              eps: float, max_iter: int, qp: DenseQP | SparseQP, trust: float | None = None, *,
              keep_iterates: bool = False, settings: TemporalSettings | None = None) -> CFSResult:
    """One CFS solve of (7.7)-(7.9) with per-knot acceleration limits and per-interval velocity factors.

    Args:
        dx: (N, n) path increments, rad.
        vmax: (n,) velocity limits, rad/s.
        amax_k: (N+1, n) acceleration limit at each knot, rad/s^2.
        vscale: (N,) factors on ``vmax`` per interval (None: 1).
        tau0: (N,) feasible starting steps, s.
        w3: weight of the total time in (7.7).
        w4: weight of the time-step changes in (7.7).
        eps: CFS stopping rule on the step length, s.
        max_iter: CFS iteration cap.
        qp: QP solver of the general CFS.
        trust: None (tangent cuts and exact pull-back) or the trust box as a fraction of the step
            (general CFS, polyhedral inner approximation).
        keep_iterates: keep every iterate in the result.
        settings: algorithm settings (default :class:`TemporalSettings`).

    Returns:
        The CFS result; ``z`` holds the (N,) steps tau, s.

    Raises:
        InfeasibleProblem: the first convex subproblem is infeasible.
    """
    st = settings or TemporalSettings()
    N, n = dx.shape
    lb = step_bounds(dx, vmax, amax_k, vscale)
    tau0 = np.maximum(tau0, lb)
    h = st.ub_factor * float(np.max(tau0))
    if st.local_ub:
        # per-step upper bounds around the start: a tighter Hessian bound mu_r of (7.6) per row
        t_nb = np.maximum.reduce([tau0, np.r_[tau0[1:], tau0[-1]], np.r_[tau0[0], tau0[:-1]]])
        ub = np.maximum(st.local_ub * t_nb, lb * (1 + 1e-9))
    else:
        ub = np.full(N, h)
    H = w4 * _second_difference(N) + (st.ridge * w3 / h) * np.eye(N)
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
    if st.solver == "dedicated" and trust is None:
        return cfs_tau(H, f, lb, ub, kk2, A2, d12, d02, sign, mu, tau0, eps=eps, max_iter=max_iter,
                       max_cuts=st.max_cuts, ftol=st.ftol, working_set=st.working_set, keep_iterates=keep_iterates)
    rows = np.arange(kk2.size)

    def fun(tau: np.ndarray) -> NDArray[np.float64]:
        a, b = tau[kk2], tau[kk2 + 1]
        return 0.5 * A2 * (a + b) * a * b - sign * (d12 * a - d02 * b)

    def jac(tau: np.ndarray) -> NDArray[np.float64]:
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
               tol=1e-9, max_cuts=st.max_cuts, qp=qp, trust=None if trust is None else trust * h, ftol=st.ftol,
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


def cfs_tau(H: np.ndarray, f: np.ndarray, lb: np.ndarray, ub: np.ndarray, kk: np.ndarray,
            A2: np.ndarray, d1: np.ndarray, d0: np.ndarray, sign: np.ndarray, mu: np.ndarray,
            z0: np.ndarray, *, eps: float, max_iter: int, tol: float = 1e-9, max_cuts: int = 2,
            ftol: float = 0.0, working_set: float = 0.5, keep_iterates: bool = False) -> CFSResult:
    """Algorithm 2 specialised to (7.7)-(7.9).

    The same iteration as :func:`robointel.planning.cfs.cfs` for case-(7.6) constraints with a diagonal Hessian
    bound, written for this problem's structure.

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
    t0 = time.perf_counter()
    N, R = z0.size, kk.size
    kk = np.ascontiguousarray(kk, dtype=np.int64)
    G = np.zeros((R, N))
    Hc = np.ascontiguousarray(H, dtype=float)
    INFV = 1e20
    up0 = np.concatenate([ub, np.full(R, INFV)])

    def cost(z: np.ndarray) -> float:
        return float(0.5 * z @ (Hc @ z) + f @ z)

    def feasible(z: np.ndarray) -> bool:
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
        p, ga, gb, h, inW = _rows_lin(z, kk, A2, d1, d0, sign, G, working_set, act_r)
        ref_ok = bool(R == 0 or p.min() >= -tol)
        if working_set and ref_ok:
            # working set: rows whose acceleration at the reference uses working_set of the limit, and
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
def _rows_lin(z: Arr, kk: Arr, A2: Arr, d1: Arr, d0: Arr,  # pragma: no cover - compiled
              sign: Arr, G: Arr, ws: float,
              act_r: Arr) -> tuple[Arr, Arr, Arr, Arr, Arr]:
    """phi_r(z), its two partials and the linearisation's right-hand side (writes G in place), and the working-set mask.

    Rows whose acceleration uses at least ``ws`` of the limit, or active.
    """
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
def _feasible(z: Arr, lb: Arr, ub: Arr, kk: Arr, A2: Arr, d1: Arr,  # pragma: no cover - compiled
              d0: Arr, sign: Arr, tol: float) -> bool:
    """Z within its bounds (1e-9) and every (7.8) row phi_r(z) >= -tol."""
    for i in range(z.size):
        if z[i] < lb[i] - 1e-9 or z[i] > ub[i] + 1e-9:
            return False
    for r in range(kk.size):
        a, b = z[kk[r]], z[kk[r] + 1]
        if 0.5 * A2[r] * (a + b) * a * b - sign[r] * (d1[r] * a - d0[r] * b) < -tol:
            return False
    return True


@njit(cache=True)
def _rows_phi_min(z: Arr, kk: Arr, A2: Arr, d1: Arr, d0: Arr,  # pragma: no cover - compiled
                  sign: Arr) -> float:
    """min_r phi_r(z)."""
    m = np.inf
    for r in range(kk.size):
        a, b = z[kk[r]], z[kk[r] + 1]
        m = min(m, 0.5 * A2[r] * (a + b) * a * b - sign[r] * (d1[r] * a - d0[r] * b))
    return m


@njit(cache=True)
def _rows_cuts(x: Arr, z: Arr, kk: Arr, p: Arr, ga: Arr, gb: Arr,  # pragma: no cover - compiled
               mu: Arr, tol: float, N: int) -> tuple[Arr, Arr, Arr]:
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
def _rows_lin_violated(x: Arr, kk: Arr, ga: Arr, gb: Arr, h: Arr,  # pragma: no cover - compiled
                       inW: Arr, tol: float) -> Arr:
    """Rows outside the working set whose linearisation ga x_a + gb x_b >= h fails at x."""
    out = []
    for r in range(kk.size):
        if not inW[r] and ga[r] * x[kk[r]] + gb[r] * x[kk[r] + 1] - h[r] < -tol * (1.0 + abs(h[r])):
            out.append(r)
    return np.array(out, dtype=np.int64)


@njit(cache=True)
def _warm_sense(m: int, N: int, act_b: Arr, act_r: Arr, row_of: Arr) -> Arr:  # pragma: no cover - compiled
    """DAQP constraint flags (m,) marking the last QP's active set.

    Simple bounds as given, and for every active constraint row its newest QP row (the latest tangent cut, else the
    row).
    """
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
def _active_from(lam: Arr, N: int, row_of: Arr, R: int) -> tuple[Arr, Arr]:  # pragma: no cover - compiled
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
def _rows_pull_back(dz: Arr, kk: Arr, p: Arr, ga: Arr, gb: Arr,  # pragma: no cover - compiled
                    mu: Arr) -> float:
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
