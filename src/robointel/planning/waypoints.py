"""Collision-free trajectory planning by CFS, (7.1)-(7.3) (Sec. 7.3).

One path segment between two stop-by waypoints is x_0..x_N (joint positions, fixed step dt), with
x_0 and x_N fixed. The problem

    min  w1 sum_t ||x_t - x^r_t||_Q^2 + w2 sum_t ||u_t||_R^2,   u_t = (x_{t+1} - 2 x_t + x_{t-1}) / dt^2
    s.t. lower <= x_t <= upper,  |x_{t+1} - x_t| <= vmax dt,  |u_t| <= amax               (7.1)-(7.2)
         d(x(s), O_k) >= d_min  for every robot sphere, obstacle and sample s               (7.3)

is solved by CFS: at the reference the signed distances d (robot.spheres vs. the obstacles of
:mod:`robointel.geometry`) are linearised through the sphere Jacobians, d + grad d (x - x_r) >= d_min
(the half space (7.5) in Cartesian space, mapped to joint space), and the QP is solved. Samples are
the knots and ``substeps`` points on the joint-space segment between consecutive knots, so the
motion between knots is checked too. Each QP solution is checked with the exact distances; if a
feasible reference would be left for an infeasible point (the Jacobian linearisation is not exact
in joint space), the step is halved (at most ``backtracks`` times).

Speed: the cost is banded (double integrator) and constant; the constraint matrix has a fixed
sparsity pattern (``slots`` rows per sample, filled with the closest sphere/obstacle pairs within
``margin``, empty rows relaxed to -inf) whose entries are overwritten in place each iteration; all
samples' distances and gradients come from one compiled call
(:func:`robointel.geometry.sphere_distances_batch`). Each QP is solved by
:class:`~robointel.planning.segment_qp.SegmentQPSolver`: DAQP (default: dual active set on a working
set of rows -- clearance rows near activity, limit rows near their bounds, the rest added only if
violated -- warm-started with the previous duals) or OSQP (``solver="osqp"``: one workspace set up
once, then ``update(q=, l=, u=, Ax=)`` and warm start).

While the reference is still in collision (the straight line through an obstacle), the clearance
rows get elastic slacks penalised by ``elastic`` and steps are halved when the exact-penalty merit
grows; once the reference is clear the slacks are fixed at zero and CFS keeps every iterate clear.
"""
from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from robointel._validate import as_array, check_limits
from robointel.errors import CollisionAtStart, InfeasibleProblem, InvalidInput, LimitViolation
from robointel.planning.qp import INF
from robointel.planning.segment_qp import SegmentQPSolver

if TYPE_CHECKING:  # pragma: no cover
    from robointel.geometry.distance import SphereDistances
    from robointel.robot import Robot


from robointel.planning.segment import (  # noqa: F401
    Clearances,
    PlannerSettings,
    SegmentPlan,
    all_clearances,
    check_self_clear,
    sphere_clearances,
    straight_reference,
)


class TrajectoryPlanner:
    """CFS planner for segments of N steps of ``dt`` on one robot among obstacles.

    Args:
        robot: a :class:`robointel.robot.Robot` (its ``spheres`` are the collision model).
        obstacles: sequence of :mod:`robointel.geometry` obstacles.
        N: steps per segment (N+1 knots).
        dt: fixed time step (s).
        vmax: (n,) velocity limits, rad/s (default: the robot's).
        amax: (n,) acceleration limits, rad/s^2 (default: the robot's).
        settings: :class:`PlannerSettings`.
        solver: ``"daqp"`` (dense active set with lazy limit rows, default) or ``"osqp"``
            (sparse ADMM, pattern fixed, updated in place).
    """

    def __init__(self, robot: Robot, obstacles: Any = (), *, N: int, dt: float, vmax: ArrayLike | None = None,
                 amax: ArrayLike | None = None, settings: PlannerSettings | None = None, solver: str = "daqp") -> None:
        self.robot = robot
        self.n = n = robot.nq
        if int(N) < 2:
            raise InvalidInput(f"a segment needs N >= 2 steps, got {N}", value=N)
        if not (np.isfinite(dt) and dt > 0):
            raise InvalidInput(f"dt must be positive and finite, got {dt}", value=dt)
        self.N, self.dt = int(N), float(dt)
        self.settings = settings or PlannerSettings()
        self.vmax = as_array(robot.velocity_limit if vmax is None else np.broadcast_to(vmax, (n,)), "vmax", (n,))
        self.amax = as_array(robot.acceleration_limit if amax is None else np.broadcast_to(amax, (n,)), "amax", (n,))
        if np.any(self.vmax <= 0) or np.any(self.amax <= 0):
            raise LimitViolation("velocity and acceleration limits must be positive", value=(self.vmax, self.amax))
        self.set_obstacles(obstacles)
        self._build()
        self.solver = solver
        self._qp = SegmentQPSolver(self.P_z, self.A, nv=self.nv, always=self._always, slack_rows=self._slack_rows,
                                   reach=self._reach, solver=solver)
        self.qp_stats = self._qp.stats

    # ------------------------------------------------------------------ set-up
    def set_obstacles(self, obstacles: Any) -> None:
        """Replace the obstacles (same count keeps the QP pattern: used by replanning)."""
        self.obstacles = tuple(obstacles)
        self._movable = np.flatnonzero(np.asarray(self.robot.spheres.movable, bool))

    def _build(self) -> None:
        n, N, st = self.n, self.N, self.settings
        nv = (N - 1) * n  # interior knots x_1..x_{N-1}
        self.nv = nv
        Qw = np.ones(n) if st.Q is None else as_array(st.Q, "Q", (n,))
        Rw = np.ones(n) if st.R is None else as_array(st.R, "R", (n,))
        # full-trajectory quadratic over X = [x_0..x_N]: w1 ||X - Xr||_Q^2 + w2 ||D2 X / dt^2||_R^2
        D2 = sp.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(N - 1, N + 1)).tocsc()
        W1 = sp.diags(np.r_[0.0, np.ones(N - 1), 0.0])
        self._P_full = (2 * st.w1 * sp.kron(W1, sp.diags(Qw)) +
                        2 * st.w2 / self.dt ** 4 * sp.kron(D2.T @ D2, sp.diags(Rw))).tocsc()
        self._Qw = Qw
        idx = np.arange((N + 1) * n).reshape(N + 1, n)
        self._int = idx[1:N].ravel()
        self._ends = np.r_[idx[0], idx[N]]
        self.P = self._P_full[self._int][:, self._int].tocsc()
        self._P_ie = self._P_full[self._int][:, self._ends].tocsc()
        # linear constraints on z: box (limits), velocity, acceleration; the fixed ends enter the bounds
        I = sp.eye(nv, format="csc")
        D1 = sp.diags([-1.0, 1.0], [0, 1], shape=(N, N + 1)).tocsc()
        self._D1_int = sp.kron(D1[:, 1:N], sp.eye(n)).tocsc()
        self._D1_end = sp.kron(D1[:, [0, N]], sp.eye(n)).tocsc()
        self._D2_int = sp.kron(D2[:, 1:N], sp.eye(n)).tocsc()
        self._D2_end = sp.kron(D2[:, [0, N]], sp.eye(n)).tocsc()
        # collision rows: samples (knot t, fraction a) with a in {0, 1/(S+1), ...}
        S = int(st.substeps)
        samples = [(t, 0.0) for t in range(1, N)]
        samples += [(t, (j + 1) / (S + 1)) for t in range(N) for j in range(S)]
        self.samples = samples
        K = int(st.slots)
        nS = len(samples)
        self._sample_t = np.array([s_[0] for s_ in samples])
        self._sample_a = np.array([s_[1] for s_ in samples])
        self._coll_nrows = nS * K
        # variables z = [x_1..x_{N-1} (nv), s (nS elastic slacks, one per sample)]
        nz = nv + nS
        self.nz = nz
        lin = sp.vstack([I, self._D1_int, self._D2_int], format="coo")
        m_lin = lin.shape[0] + nS  # + slack bound rows
        self._m_lin = lin.shape[0]
        rows = [lin.row, nv + self._D1_int.shape[0] + self._D2_int.shape[0] + np.arange(nS)]
        cols = [lin.col, nv + np.arange(nS)]
        vals = [lin.data, np.ones(nS)]
        # collision rows: slot k of sample si touches x_t (and x_{t+1} between knots) and s_si
        self._pos = np.full((nS, K, 2, n), -1, dtype=np.int64)
        # entry ids of the collision x-coefficients, in self._pos order
        ids: list[tuple[int, int, int, int] | None] = []
        cr, cc, cv = [], [], []
        for si, (t, a_) in enumerate(samples):
            for k in range(K):
                r = m_lin + si * K + k
                for side, blk in enumerate((t, t + 1)):
                    if 1 <= blk <= N - 1 and (side == 0 or a_ > 0):
                        for j in range(n):
                            cr.append(r)
                            cc.append((blk - 1) * n + j)
                            cv.append(0.0)
                            ids.append((si, k, side, j))
                cr.append(r)
                cc.append(nv + si)
                cv.append(1.0)
                ids.append(None)
        rows.append(np.array(cr, dtype=np.int64))
        cols.append(np.array(cc, dtype=np.int64))
        vals.append(np.array(cv))
        R_ = np.concatenate(rows)
        C_ = np.concatenate(cols)
        V_ = np.concatenate(vals)
        m = m_lin + nS * K
        tag = sp.csc_matrix((np.arange(1, R_.size + 1, dtype=float), (R_, C_)), shape=(m, nz))
        tag.sort_indices()
        where = np.empty(R_.size, dtype=np.int64)
        where[tag.data.astype(np.int64) - 1] = np.arange(R_.size)  # entry id -> position in data
        data = np.empty(R_.size)
        data[where] = V_
        self.A = sp.csc_matrix((data, tag.indices.copy(), tag.indptr.copy()), shape=(m, nz))
        self._A_data = data.copy()
        n_before = R_.size - len(cr)
        for e, key in enumerate(ids):
            if key is not None:
                self._pos[key] = where[n_before + e]
        self._m_all_lin = m_lin
        always = np.zeros(m, dtype=bool)
        always[lin.shape[0]:lin.shape[0] + nS] = True  # slack bounds
        self._always = always
        self._slack_rows = np.arange(lin.shape[0], lin.shape[0] + nS)
        # a limit row joins the working set when the reference is within this distance of its bound
        # (clearance rows: within st.reach metres of active; the others are added lazily if violated)
        reach = np.r_[np.full(nv, 0.2), np.tile(self.vmax * self.dt, N) * 0.5,
                      np.tile(self.amax * self.dt ** 2, N - 1) * 0.5, np.zeros(nS),
                      np.full(nS * K, float(st.reach))]
        self._reach = reach
        # cost over z: the x block, a tiny ridge on the slacks (their linear weight is set per solve)
        self.P_z = sp.block_diag([self.P, sp.eye(nS) * 1.0], format="csc")

    def reset_warm_start(self) -> None:
        """Forget the QP solvers' previous solutions (for cold-start timings)."""
        self._qp.reset()

    # ------------------------------------------------------------------ pieces
    def _sample_configs(self, X: np.ndarray) -> np.ndarray:
        """Configurations at every sample, (S_total, n), from knots X (N+1, n)."""
        t, a = self._sample_t, self._sample_a[:, None]
        return (1 - a) * X[t] + a * X[t + 1]

    def distances(self, X: np.ndarray, *, cull: bool = True) -> Clearances | None:
        """Exact clearances at all samples of the knots X (N+1, n): :func:`all_clearances` (obstacles, self pairs).

        d (S, C) and grad (S, C, n); None when there is nothing to keep clear of. ``cull=False``: every
        self pair, so that C is the same at every call.
        """
        if not self.obstacles and not (self.settings.self_collision and len(self.robot.spheres.self_pairs)):
            return None
        return all_clearances(self.robot, self._sample_configs(X), self.obstacles, self.settings, cull=cull)

    def config_distances(self, Q: np.ndarray) -> SphereDistances:
        """Sphere/obstacle distances at configurations Q (B, n): see :func:`sphere_clearances`."""
        return sphere_clearances(self.robot, Q, self.obstacles)

    def _linear_bounds(self, x0: np.ndarray, xN: np.ndarray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        N = self.N
        ends = np.r_[x0, xN]
        lo = np.tile(self.robot.lower, N - 1)
        up = np.tile(self.robot.upper, N - 1)
        vb = np.tile(self.vmax * self.dt, N)
        v_off = self._D1_end @ ends
        ab = np.tile(self.amax * self.dt ** 2, N - 1)
        a_off = self._D2_end @ ends
        return (np.r_[lo, -vb - v_off, -ab - a_off], np.r_[up, vb - v_off, ab - a_off])

    def _collision_rows(self, X: np.ndarray, D: Clearances | None,
                        d_req: float) -> tuple[Any, NDArray[np.float64]]:
        """Fill A's collision entries and bounds from distances D at the samples of X."""
        st = self.settings
        K, n = int(st.slots), self.n
        S = len(self.samples)
        data = self._A_data.copy()
        lo = np.full((S, K), -INF)
        if D is None:
            return data, lo.ravel()
        d = D.d.reshape(S, -1)  # (S, m'*k)
        g = D.grad.reshape(S, -1, n)
        kk = min(K, d.shape[1])
        sel = np.argpartition(d, kk - 1, axis=1)[:, :kk] if kk < d.shape[1] else np.tile(np.arange(d.shape[1]), (S, 1))
        ds = np.take_along_axis(d, sel, 1)  # (S, kk)
        gs = np.take_along_axis(g, sel[:, :, None], 1)  # (S, kk, n)
        active = ds < d_req + st.margin
        a = self._sample_a
        t = self._sample_t
        Xs = self._sample_configs(X)
        # row: sum_side coef_side * g . x_side >= d_req - d + g . x_s  (fixed ends move to the bound)
        rhs = d_req - ds + np.einsum("skn,sn->sk", gs, Xs)
        w0 = (1 - a)[:, None, None] * gs  # coefficients on x_t
        w1 = a[:, None, None] * gs        # on x_{t+1}
        N = self.N
        fixed0 = (t == 0)
        fixedN = (t + 1 == N)
        rhs -= np.where(fixed0[:, None], np.einsum("skn,n->sk", w0, X[0]), 0.0)
        rhs -= np.where(fixedN[:, None], np.einsum("skn,n->sk", w1, X[N]), 0.0)
        pos = self._pos[:, :kk]
        w0 = np.where(active[:, :, None], w0, 0.0)
        w1 = np.where(active[:, :, None], w1, 0.0)
        m0 = pos[:, :, 0, :] >= 0
        data[pos[:, :, 0, :][m0]] = w0[m0]
        m1 = pos[:, :, 1, :] >= 0
        data[pos[:, :, 1, :][m1]] = w1[m1]
        lo[:, :kk] = np.where(active, rhs, -INF)
        return data, lo.ravel()

    def check_waypoints(self, waypoints: np.ndarray, names: list[str] | None = None) -> None:
        """Raise if a waypoint is outside the joint limits or in collision.

        Raise if a waypoint is outside the joint limits or in collision (CollisionAtStart naming the link and
        obstacle).
        """
        W = as_array(waypoints, "waypoints", (None, self.n))
        for i, w in enumerate(W):
            label = names[i] if names else f"waypoint {i}"
            check_limits(w, self.robot.lower, self.robot.upper, self.robot.joint_names, what=label)
        if self.settings.self_collision:
            check_self_clear(self.robot, W, self.settings.self_d_min, names)
        sm = self.robot.spheres
        if not self.obstacles:
            return
        D = self.config_distances(W)
        for i in range(len(W)):
            j, k = np.unravel_index(int(np.argmin(D.d[i])), D.d[i].shape)
            if D.d[i, j, k] < self.settings.d_min:
                label = names[i] if names else f"waypoint {i}"
                link = sm.links[int(D.spheres[j])]
                obs = self.obstacles[k].label(k)
                raise CollisionAtStart(
                    f"{label} is in collision: link {link!r} is {D.d[i, j, k] * 1000:.1f} mm from obstacle "
                    f"{obs!r} (required clearance {self.settings.d_min * 1000:.1f} mm); move the waypoint or "
                    "the obstacle", value={"waypoint": i, "link": link, "obstacle": obs,
                                           "distance": float(D.d[i, j, k])})

    # ------------------------------------------------------------------ solve
    def plan_segment(self, start: ArrayLike, goal: ArrayLike, *, reference: ArrayLike | None = None,
                     init: ArrayLike | None = None, keep_iterates: bool = False) -> SegmentPlan:
        """Plan x_0..x_N from ``start`` to ``goal`` (both (n,), fixed) by CFS.

        Args:
            start: (n,) start configuration x_0, rad.
            goal: (n,) goal configuration x_N, rad.
            reference: (N+1, n) x^r (default: the joint-space straight line).
            init: (N+1, n) initial guess (default: the reference); a previous plan warm-starts
                replanning.
            keep_iterates: keep every CFS iterate on the result.
        """
        t0 = time.perf_counter()
        n, N, st = self.n, self.N, self.settings
        x0 = as_array(start, "start", (n,))
        xN = as_array(goal, "goal", (n,))
        need = np.abs(xN - x0) / (N * self.dt)
        over = np.flatnonzero(need > self.vmax * (1 + 1e-9))
        if over.size:
            j = int(over[0])
            raise InfeasibleProblem(
                f"impossible limits: {self.robot.joint_names[j]} must move {abs(xN[j] - x0[j]):.3f} rad in "
                f"{N} steps of {self.dt:.4f} s, i.e. at least {need[j]:.3f} rad/s, above its velocity limit "
                f"{self.vmax[j]:.3f} rad/s; use more steps, a larger dt or a higher limit", value=need)
        Xr = straight_reference(x0, xN, N) if reference is None else as_array(reference, "reference", (N + 1, n))
        X = Xr.copy() if init is None else as_array(init, "init", (N + 1, n)).copy()
        X[0], X[N] = x0, xN
        X[1:N] = np.clip(X[1:N], self.robot.lower, self.robot.upper)
        _, q = self.cost_terms(x0, xN, Xr)
        lo_lin, up_lin = self._linear_bounds(x0, xN)
        d_req = st.d_min + st.safety
        D = self.distances(X)
        dmin = float(D.d.min()) if D is not None else np.inf
        blocked = dmin < st.d_min
        feas = dmin >= st.d_min - 1e-9
        cost = self._cost(X, Xr)
        costs = [cost]
        iterates = [X.copy()] if keep_iterates else []
        best = (X.copy(), cost, dmin) if feas else None
        status, it = "max_iter", 0
        up_coll = np.full(self._coll_nrows, INF)
        nS = len(self.samples)
        qz = np.r_[q, np.full(nS, st.elastic)]
        for it in range(1, st.max_iter + 1):  # noqa: B007 - the count is reported after the loop
            data, lo_c = self._collision_rows(X, D, d_req)
            # elastic slacks only while the reference is infeasible (Sec. 7.2: CFS from an infeasible start)
            smax = INF if not feas else 0.0
            l = np.r_[lo_lin, np.zeros(nS), lo_c]
            u = np.r_[up_lin, np.full(nS, smax), up_coll]
            z0 = np.r_[X[1:N].ravel(), np.zeros(nS)]
            sol = self._qp.solve(qz, l, u, data, z0)
            if not sol.solved:
                status = "qp_failed"
                break
            Znew = sol.x[: self.nv].reshape(N - 1, n)
            Xnew = X.copy()
            beta = 1.0
            merit0 = None if feas or not st.merit else self._merit(X, Xr, D, d_req)
            for _ in range(st.backtracks + 1):
                Xnew[1:N] = X[1:N] + beta * (Znew - X[1:N])
                Xnew[1:N] = np.clip(Xnew[1:N], self.robot.lower, self.robot.upper)
                Dn = self.distances(Xnew)
                dn = float(Dn.d.min()) if Dn is not None else np.inf
                if feas:
                    if dn >= st.d_min - 1e-9:  # CFS: stay in the feasible set
                        break
                elif merit0 is None or dn >= st.d_min - 1e-9 or self._merit(Xnew, Xr, Dn, d_req) <= merit0:
                    break  # elastic phase: the exact penalty merit must not grow
                beta *= 0.5
            step = float(np.max(np.abs(Xnew - X)))
            prev_feas = feas
            X, D, dmin = Xnew, Dn, dn
            feas = dmin >= st.d_min - 1e-9
            cost = self._cost(X, Xr)
            costs.append(cost)
            if keep_iterates:
                iterates.append(X.copy())
            if feas and (best is None or cost <= best[1]):
                best = (X.copy(), cost, dmin)
            if feas and (step <= st.eps or (prev_feas and costs[-2] - cost <= st.ftol * abs(cost))):
                status = "converged"
                break
        if status != "converged" and best is not None:
            X, cost, dmin = best
            feas = True
        if status == "qp_failed" and best is None and it == 1:
            raise InfeasibleProblem(f"the first CFS subproblem is infeasible (OSQP: {sol.status}); the limits "
                                    "may be too tight for N steps of dt, or the segment unreachable", value=sol.status)
        return SegmentPlan(path=X, iterations=it, costs=costs, status=status, feasible=bool(feas),
                           min_distance=float(dmin), seconds=time.perf_counter() - t0, blocked=bool(blocked),
                           iterates=iterates)

    def _q_full(self, Xr: np.ndarray) -> np.ndarray:
        """Linear term over all knots: -2 w1 Q x^r on interior knots, 0 at the fixed ends."""
        w = np.zeros_like(Xr)
        w[1:-1] = Xr[1:-1] * self._Qw[None]
        return -2 * self.settings.w1 * w.ravel()

    def _merit(self, X: np.ndarray, Xr: np.ndarray, D: Clearances | None, d_req: float) -> float:
        """Exact-penalty merit of the elastic phase.

        J + elastic * sum over samples of the clearance shortfall (the QP's slack objective evaluated with the true
        distances).
        """
        if D is None:
            return self._cost(X, Xr)
        short = np.maximum(d_req - D.d.reshape(len(self.samples), -1).min(axis=1), 0.0)
        return self._cost(X, Xr) + self.settings.elastic * float(short.sum())

    def _cost(self, X: np.ndarray, Xr: np.ndarray) -> float:
        """J of (7.1) at the knots X (constant terms included)."""
        st = self.settings
        E = (X[1:-1] - Xr[1:-1])
        U = (X[2:] - 2 * X[1:-1] + X[:-2]) / self.dt ** 2
        R = np.ones(self.n) if st.R is None else st.R
        return float(st.w1 * np.sum(E * E * self._Qw) + st.w2 * np.sum(U * U * R))

    def cost_terms(self, start: ArrayLike, goal: ArrayLike,
                   reference: ArrayLike | None = None) -> tuple[Any, NDArray[np.float64]]:
        """(P, q) of the QP in z = x_1..x_{N-1}: J = 1/2 z'Pz + q'z + const (also for the baselines)."""
        n, N = self.n, self.N
        x0 = as_array(start, "start", (n,))
        xN = as_array(goal, "goal", (n,))
        Xr = straight_reference(x0, xN, N) if reference is None else reference
        qfull = self._q_full(np.asarray(Xr, float))
        return self.P, qfull[self._int] + self._P_ie @ np.r_[x0, xN]
