"""The checks of a trajectory planned with relaxed spheres at its start and goal edges.

Between the first and the last inner vertex of the path the mesh-covering spheres decide; on the
start and goal edges the exact distance to the collision meshes (:class:`MeshGeometry`, coal). The
exact check looks at the clock so that a plan's time budget holds inside an attempt.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from robointel.errors import CollisionAtStart
from robointel.planning import _dense_kernels as D
from robointel.planning.between_samples import BetweenProofs, OutOfTime, half_steps, pair_half_steps
from robointel.planning.budget_clock import now as clock_now
from robointel.planning.environment import Environment
from robointel.planning.exact_geometry import MeshGeometry
from robointel.planning.exact_self import next_due, self_geometry
from robointel.planning.motion_check import CLEARANCE_TOL, DenseCheck, window_clearance
from robointel.planning.self_tree import EXPAND
from robointel.trajectory import Trajectory


def mesh_geometry(env: Environment) -> MeshGeometry:
    """The environment's exact (coal) geometry, built on first use and kept with it."""
    mg = getattr(env, "_mesh_geometry", None)
    if mg is None:
        mg = MeshGeometry(env.robot, env.obstacles)
        env._mesh_geometry = mg  # type: ignore[attr-defined]
    return mg


#: samples of the collision-mesh check between two looks at the clock
MESH_CHUNK = 64
#: samples ahead of its due one a pair is measured at when others are measured there (fewer placements)
SELF_EARLY = 128
#: how close above the mesh check's threshold a refused timing's path may pass, at the point nearest the
#: refusal, and still be timed again (:func:`path_touches`), m
TOUCH_MARGIN = 0.002


def _travel(Q: np.ndarray) -> np.ndarray:
    """(K, n): each joint's travel from sample 0 to each sample of Q (K, n) (the schedules' clock), rad."""
    Cq = np.empty(Q.shape)
    D.variation(Q, Cq)
    return Cq


@njit(cache=True)
def _front(due: np.ndarray, m: int, early: int, out: np.ndarray) -> tuple[int, int]:  # pragma: no cover - compiled
    """The next sample to measure at, k = min(due[:m]), and the pairs due by k + ``early``.

    Writes their positions in ``due`` to ``out[:c]``; returns (k, c).
    """
    k = due[0]
    for i in range(1, m):
        if due[i] < k:
            k = due[i]
    c = 0
    for i in range(m):
        if due[i] <= k + early:
            out[c] = i
            c += 1
    return k, c


def timed_out(what: str, chk: DenseCheck) -> DenseCheck:
    """``chk`` turned into a failed check of kind ``"timeout"`` (the budget ran out during ``what``)."""
    return DenseCheck(False, f"the time budget ran out during {what}", "timeout", chk.min_clearance_m, chk.samples)


@njit(cache=True)
def _nearest(Q: np.ndarray, q: np.ndarray, last: bool) -> int:  # pragma: no cover - compiled
    """Index of the sample of Q (K, n) nearest to q (Euclidean): the first of equals, or the last."""
    best, bi = np.inf, 0
    for k in range(Q.shape[0]):
        d = 0.0
        for j in range(Q.shape[1]):
            e = Q[k, j] - q[j]
            d += e * e
        if d < best or (last and d == best):
            best, bi = d, k
    return bi


def interior_window(traj: Trajectory, path: np.ndarray) -> tuple[float, float]:
    """(t0, t1): the times of the samples of ``traj`` nearest the first and the last inner vertex of ``path``.

    Between them a trajectory planned with relaxed spheres at its start/goal edges must clear the
    mesh-covering spheres; before t0 and after t1 the collision meshes decide. Without an inner
    vertex, t0 is the end and t1 the start (no interior: the meshes decide everywhere).
    """
    if len(path) < 3:
        return float(traj.t[-1]), float(traj.t[0])
    Q = np.ascontiguousarray(traj.q)
    i0 = _nearest(Q, np.ascontiguousarray(path[1], dtype=float), False)
    i1 = _nearest(Q, np.ascontiguousarray(path[-2], dtype=float), True)
    return float(traj.t[i0]), float(traj.t[i1])


def interior_check(env: Environment, traj: Trajectory, path: np.ndarray, Wc: tuple, chk: DenseCheck, *,
                   d_min: float, dt: float, deadline: float = float("inf"), window_checked: bool = False,
                   window: tuple[float, float] | None = None) -> DenseCheck:
    """Check a trajectory planned with partially grown spheres at the start/goal edges.

    Between the first and the last inner vertex (:func:`interior_window`) it must clear the
    mesh-covering spheres (skipped when ``window_checked``: ``chk`` came from
    :func:`~robointel.planning.motion_check.check_dense` with that window in ``Wc``); before and
    after them (the start and goal edges) the exact distance to the collision meshes
    (:class:`MeshGeometry`: convex hulls, refined on the meshes) must be >= max(d_min - 1 mm, 0), over
    the motion between the samples too (as :func:`exact_check`). The mesh check looks at the clock
    every ``MESH_CHUNK`` exact samples: past ``deadline`` it returns a failed check of kind
    ``"timeout"``. ``window``: ``interior_window(traj, path)`` when the caller has it already.
    """
    t0, t1 = interior_window(traj, path) if window is None else window
    if len(path) >= 3 and not window_checked:
        d = window_clearance(env, traj, Wc, t0, t1, d_min=d_min, dt=dt)
        if d < d_min - CLEARANCE_TOL:
            return DenseCheck(False, f"the covering spheres come {d * 1e3:.1f} mm from the obstacles between "
                              f"t = {t0:.3f} s and {t1:.3f} s", "collision", min(d, chk.min_clearance_m),
                              chk.samples)
    dense = traj if float(np.max(np.diff(traj.t))) <= dt * (1 + 1e-9) else traj.resample(dt)
    n = len(dense.t)  # the samples with t <= t0 and those with t >= t1
    spans = ((0, int(np.searchsorted(dense.t, t0, side="right"))), (int(np.searchsorted(dense.t, t1, side="left")), n))
    return _mesh_check(env, dense, spans, Wc, chk, d_min=d_min, deadline=deadline)


def exact_check(env: Environment, traj: Trajectory, Wc: tuple, chk: DenseCheck, *, d_min: float, dt: float,
                deadline: float = float("inf")) -> DenseCheck:
    """Check a whole trajectory planned with spheres that may leave parts of the meshes uncovered.

    Every ``dt`` sample that the mesh-covering spheres ``Wc`` leave closer than max(d_min - 1 mm, 0)
    plus the largest :func:`~robointel.planning.between_samples.half_steps` to the obstacles is measured
    on the collision meshes (:class:`MeshGeometry`: lower bounds by the hulls and by collision queries
    at margins, the exact distance only in contact), which must keep that bound; where a pair's bound
    is less than it plus the sample's own half steps, the motion to the neighbouring samples is proven
    by halving (:class:`~robointel.planning.between_samples.BetweenProofs`). The bound then holds over
    the motion between the samples too (the trajectory's cubic interpolant, as an independent check
    resampling it at other instants sees it). Clock and
    result as :func:`interior_check`.
    """
    dense = traj if float(np.max(np.diff(traj.t))) <= dt * (1 + 1e-9) else traj.resample(dt)
    return _mesh_check(env, dense, ((0, len(dense.t)),), Wc, chk, d_min=d_min, deadline=deadline)


def _mesh_check(env: Environment, dense: Trajectory, spans: tuple[tuple[int, int], ...], Wc: tuple, chk: DenseCheck,
                *, d_min: float, deadline: float) -> DenseCheck:
    """The exact mesh check of the samples ``dense``[lo:hi] of each (lo, hi) in ``spans``."""
    mg = mesh_geometry(env)
    if mg.empty:
        return chk
    thr = max(d_min - CLEARANCE_TOL, 0.0)  # the real geometry may not be penetrated at all
    s = env.scratch
    reach = mg.pair_lever.max(axis=0) if len(mg.pair_lever) else np.zeros(dense.q.shape[1])
    proofs: BetweenProofs | None = None  # made at the first pair that needs one
    hall = half_steps(np.ascontiguousarray(dense.q), reach)
    for s0, s1 in spans:
        Q = np.ascontiguousarray(dense.q[s0:s1])
        if len(Q) == 0:
            continue
        # each sample must keep thr plus its half-steps' travel, so that the motion between samples keeps thr
        h = hall[s0:s1]
        top = thr + float(h.max())
        # the covering spheres contain the meshes: only samples they leave below that need coal
        V = np.empty(Q.shape)
        D.variation(Q, V)
        doubt = D.env_below(Q, V, Wc, s.T, s.C, s.G, s.out, env.lever, top)
        if not doubt.any():
            continue
        idx = np.flatnonzero(doubt)
        # each (part, obstacle) pair measured at the first doubtful sample, then again only at the first
        # doubtful sample where its travel since (pair_lever) may have eaten its margin (as in self_check)
        Cq = V
        due = np.zeros(len(mg.pair_lever), np.int64)
        n = 0
        while True:
            j = int(np.searchsorted(idx, int(due.min())))
            if j >= len(idx):
                break
            k = int(idx[j])
            if n % MESH_CHUNK == 0 and clock_now() >= deadline:
                return timed_out("the collision-mesh check", chk)
            n += 1
            which = np.flatnonzero(due <= k + SELF_EARLY)
            # lower bounds (hull, collision queries at margins); exact only in contact (the error says how deep)
            d = mg.pair_distances(Q[k], which, thresh=thr)
            m = int(np.argmin(d))
            bad = m if d[m] < thr else -1
            close = np.flatnonzero(d < thr + h[k]) if bad < 0 and d[m] < thr + h[k] else np.zeros(0, np.int64)
            if len(close):  # (h: the largest lever's; then each pair's own)
                close = close[d[close] < thr + pair_half_steps(dense.q, s0 + k, mg.pair_lever[which[close]])]
            if len(close):
                try:
                    proofs = proofs or BetweenProofs(mg, dense, thr, deadline=deadline)
                    u = proofs.first_refused(s0 + k, which[close], d[close])
                except OutOfTime:
                    return timed_out("the collision-mesh check", chk)
                bad = int(close[u]) if u >= 0 else -1
            if bad >= 0:
                link, obs = mg.pair_names(int(which[bad]))
                what = (f"is {d[bad] * 1e3:.2f} mm from {obs!r} at t = {dense.t[s0 + k]:.3f} s" if d[bad] < thr else
                        f"comes closer than {thr * 1e3:.2f} mm to {obs!r} next to t = {dense.t[s0 + k]:.3f} s")
                return DenseCheck(False, f"collision-mesh check: link {link!r} {what}", "collision",
                                  min(float(d[bad]), chk.min_clearance_m), chk.samples, (link,), Q[k].copy())
            next_due(Cq, mg.pair_lever, which, k, d - top, due)
    return chk


def self_check(env: Environment, traj: Trajectory, chk: DenseCheck, *, dt: float,
               deadline: float = float("inf")) -> DenseCheck:
    """Check self-collision on the exact geometry at every ``dt`` sample (``env.exact_self``).

    Fitted spheres lie inside the meshes and a sphere file's leave parts of them uncovered, so
    the spheres' self-collision verdict may miss a contact: every self-collision pair of
    :class:`~robointel.planning.exact_self.SelfGeometry` is proven on the collision meshes and
    primitives by walking its :class:`~robointel.planning.self_tree.SelfTree`: the pairs of the
    joints' root nodes are measured (GJK on their hulls) at the first sample; a node pair within
    ``EXPAND`` of ``max(env.self_padding - 1 mm, 0)`` is replaced by its children's pairs, down to
    the solid pairs, measured exactly below it; every node pair is measured again only at the
    first sample where its last distance minus the relative travel since (its ``lever``) may have
    fallen below the threshold: the samples in between are proven. A node pair due within
    ``SELF_EARLY`` samples of one being measured is measured with it (one placement update serves
    both). A solid pair closer than the threshold fails the check (kind ``"collision"``). Clock as
    :func:`interior_check`.
    """
    if not chk.ok or not env.exact_self:
        return chk
    sg = self_geometry(env.robot, env.disabled)
    if sg.empty:
        return chk
    thr = max(env.self_padding - CLEARANCE_TOL, 0.0)
    dense = traj if float(np.max(np.diff(traj.t))) <= dt * (1 + 1e-9) else traj.resample(dt)
    Q = np.ascontiguousarray(dense.q)
    K = len(Q)
    proofs: BetweenProofs | None = None  # made at the first pair that needs one
    # each sample keeps thr plus its half steps (the motion halfway to its neighbours), or is proven between
    h = half_steps(Q, sg.pair_lever.max(axis=0))
    top = thr + float(h.max())
    # Cq[k]: each joint's travel from sample 0 to sample k; pair p's distance changes by at most
    # pair_lever[p] . (Cq[j] - Cq[k]) from sample k to sample j
    Cq = _travel(Q)
    tree = sg.tree
    # the front of node pairs: item i is node pair item[i], due at sample due[i] (K: proven to the end;
    # RETIRED: replaced by its children, out of reach of the early window)
    RETIRED = K + SELF_EARLY + 1
    cap = max(2 * len(tree.roots), 64)
    item, due, lever = np.empty(cap, np.int64), np.full(cap, RETIRED, np.int64), np.empty((cap, Q.shape[1]))
    m = len(tree.roots)
    item[:m], due[:m], lever[:m] = tree.roots, 0, tree.lever[tree.roots]
    n = 0
    front = np.empty(cap, np.int64)
    while True:
        if len(front) < m:
            front = np.empty(len(due), np.int64)
        k, c = _front(due, m, SELF_EARLY, front)
        if k >= K:
            return chk
        which = front[:c]  # (front is written again only at the next round)
        if n % MESH_CHUNK == 0 and clock_now() >= deadline:
            return timed_out("the self-collision check", chk)
        n += 1
        its = item[which]
        d, hits, near = tree.measure(Q[k], its, thresh=thr, expand=top + EXPAND)
        w = min(hits, key=lambda i: d[i]) if hits else -1
        if w < 0 and float(d.min()) < thr + h[k]:  # solid pairs close to thr: proven over the motion between
            leaves = tree.leaf[its]
            close = np.flatnonzero((leaves >= 0) & (d < thr + h[k]))  # (h: the largest lever's; then their own)
            if len(close):
                close = close[d[close] < thr + pair_half_steps(Q, k, sg.pair_lever[leaves[close]])]
            if len(close):
                try:
                    proofs = proofs or BetweenProofs(sg, dense, thr, deadline=deadline)
                    u = proofs.first_refused(k, leaves[close], d[close])
                except OutOfTime:
                    return timed_out("the self-collision check", chk)
                w = int(close[u]) if u >= 0 else -1
        if w >= 0:
            p = int(tree.leaf[its[w]])
            la, lb = sg.solids[sg.pairs[p, 0]].link, sg.solids[sg.pairs[p, 1]].link
            what = (f"is {d[w] * 1e3:.2f} mm from link {lb!r} at t = {dense.t[k]:.3f} s" if d[w] < thr else
                    f"comes closer than {thr * 1e3:.2f} mm to link {lb!r} next to t = {dense.t[k]:.3f} s")
            return DenseCheck(False, f"self-collision check: link {la!r} {what}", "collision",
                              min(float(d[w]), chk.min_clearance_m), chk.samples, (la, lb), Q[k].copy())
        if not near:  # proven until the relative travel since eats the margin
            next_due(Cq, lever, which, k, d - top, due)
            continue
        for w in near:  # replaced by its children's pairs, measured at this sample
            due[which[w]] = RETIRED
            kids = tree.children[its[w]]
            if m + len(kids) > cap:
                cap = 2 * (m + len(kids))
                grown = np.full(cap, RETIRED, np.int64)
                grown[:len(due)] = due
                item, due, lever = np.resize(item, cap), grown, np.resize(lever, (cap, Q.shape[1]))
            item[m:m + len(kids)], due[m:m + len(kids)], lever[m:m + len(kids)] = kids, k, tree.lever[kids]
            m += len(kids)
        keep = np.ones(len(which), bool)
        keep[near] = False
        next_due(Cq, lever, which[keep], k, d[keep] - top, due)


def path_touches(env: Environment, path: np.ndarray, chk: DenseCheck, *, d_min: float) -> bool:
    """Whether the polyline ``path`` itself fails the collision-mesh check that a timing of it failed.

    The point of the polyline nearest (in joint space) to the failed sample ``chk.q`` is measured on
    the collision meshes: against the obstacles when ``chk.links`` names one link (threshold
    max(d_min - 1 mm, 0), as :func:`exact_check`), between the links when it names two (threshold
    max(``env.self_padding`` - 1 mm, 0), as :func:`self_check`). When that point is closer than the
    threshold plus :data:`TOUCH_MARGIN`, timings that follow the polyline more closely (closer spline
    knots, rest-to-rest motion along it) do not pass there either (a timing refused between its samples
    grazes the meshes where the polyline does): the path itself must change.

    Args:
        env: the environment the check ran in.
        path: (k, n) the polyline the trajectory was timed along, rad.
        chk: a failed collision-mesh check (``chk.q`` set); any other check gives False.
        d_min: the planner's clearance, m.

    Returns:
        True when the polyline's nearest point is closer than the threshold plus :data:`TOUCH_MARGIN` on the
        meshes.
    """
    if chk.q is None or chk.kind != "collision" or len(path) < 2:
        return False
    a, b = path[:-1], path[1:]
    e = b - a
    ee = np.maximum(np.einsum("ij,ij->i", e, e), 1e-300)
    s = np.clip(np.einsum("ij,ij->i", chk.q - a, e) / ee, 0.0, 1.0)
    near = a + s[:, None] * e
    p = near[int(np.argmin(np.linalg.norm(near - chk.q, axis=1)))]
    if len(chk.links) == 2:
        top = max(env.self_padding - CLEARANCE_TOL, 0.0) + TOUCH_MARGIN
        d = self_geometry(env.robot, env.disabled).clearance(p, cap=top + TOUCH_MARGIN, thresh=top)[0]
    elif len(chk.links) == 1:
        top = max(d_min - CLEARANCE_TOL, 0.0) + TOUCH_MARGIN
        d = mesh_geometry(env).clearance(p, cap=top + TOUCH_MARGIN, thresh=top)[0]
    else:
        return False
    return bool(d < top)


def exact_roots(env: Environment, q0: np.ndarray, goals: np.ndarray, floor: float) -> np.ndarray:
    """The start and goals judged on the exact geometry: the goals kept, or :class:`CollisionAtStart`.

    A configuration is refused only when the collision meshes (obstacles: the moving links'
    meshes, :class:`MeshGeometry`; self: :class:`~robointel.planning.exact_self.SelfGeometry`)
    come closer than ``floor`` (obstacles) or ``max(self_padding - 1 mm, 0)`` (self).

    Returns:
        The indices into ``goals`` of the goals whose exact clearance holds (at least one).

    Raises:
        CollisionAtStart: the start, or every goal, is closer than that (the pair named).
    """
    mg, sg = mesh_geometry(env), self_geometry(env.robot, env.disabled)
    sthr = max(env.self_padding - CLEARANCE_TOL, 0.0)

    def why(q: np.ndarray) -> str:
        # (capped just above the floor: only a pair closer than it is looked into)
        d, link, obs = mg.clearance(q, cap=floor + 1e-4, thresh=floor)
        if d < floor:
            return f"robot link {link!r} is {d * 1e3:.1f} mm from obstacle {obs!r}"
        hit = sg.tree.closest_below(q, sthr)
        if hit is not None:
            la, lb = (sg.solids[i].link for i in sg.pairs[hit[1]])
            return f"robot link {la!r} is {hit[0] * 1e3:.1f} mm from link {lb!r}"
        return ""

    w = why(q0)
    if w:
        raise CollisionAtStart(f"start configuration is in collision on the collision meshes: {w}; move it",
                               value=np.asarray(q0, float))
    reasons = [why(g) for g in goals]
    keep = [k for k, r in enumerate(reasons) if not r]
    if not keep:
        raise CollisionAtStart(f"{'goal configuration' if len(goals) == 1 else 'every goal; goal 0'} is in "
                               f"collision on the collision meshes: {reasons[0]}; move it", value=goals[0])
    return np.asarray(keep, int)


__all__ = ["MESH_CHUNK", "TOUCH_MARGIN", "exact_check", "exact_roots", "interior_check", "interior_window",
           "mesh_geometry", "self_check", "timed_out"]
