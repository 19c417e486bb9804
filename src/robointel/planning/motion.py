"""Start-to-goal motion planning in cluttered cells for any arm.

The pipeline: a global stage (RRT-Connect on the compiled sphere checks, edges checked so that no
sphere centre moves more than ``resolution`` between checks, then shortcutting), then timing: by
default the time-optimal parametrisation (TOPP, :mod:`robointel.planning.topp`) of a spline through
knots along the path, so the horizon and the number of steps come from the path itself; or
temporal optimization (7.7)-(7.9) of knots along the path; or jerk-limited rest-to-rest timing
with ruckig; and finally the dense check of the executed trajectory (1 ms samples: joint limits,
velocity and acceleration limits, clearance >= d_min - 1 mm
to obstacles and between non-adjacent links). ``success`` is True only when that check passed.
"""
from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from robointel.errors import IKFailure, InvalidInput
from robointel.outcome import Failure
from robointel.planning import _batch_edges as BE
from robointel.planning import _collision_kernels as K
from robointel.planning import _dense_kernels as D
from robointel.planning import _rrt_kernels as R
from robointel.planning import _time_shortcut as TS
from robointel.planning.budget_clock import budget_clock
from robointel.planning.budget_clock import now as clock_now
from robointel.planning.environment import Environment
from robointel.planning.exact_geometry import MeshGeometry, warm_broad_phase
from robointel.planning.hybrid_check import exact_roots
from robointel.planning.motion_check import CLEARANCE_TOL, DenseCheck
from robointel.planning.motion_settings import MotionSettings
from robointel.planning.smoothing import smooth_and_check
from robointel.planning.stage_times import StageTimes, cpu_clock
from robointel.planning.topp import topp_spline
from robointel.planning.tree_search import TreeCarry, batch_state, path_valid, search, warm_search
from robointel.robot.model import Robot
from robointel.trajectory import Trajectory

#: how far the fitted spheres (inside the meshes) are grown for self-collision during a plan, at most, m
SELF_MARGIN = 0.003
#: a search with a fallback pending gives way to it when neither tree has gained a node in this many
#: iterations: a root walled in by the covering spheres (the goal tree of the Fetch's bookshelf_thin 3
#: added none in 200,000; this many take about 50 ms). Searches that do find their way can pause long
#: too: on 235 hard Fetch problems the longest pause of those that succeeded had a median of 7,000
#: iterations and a p90 of 27,000 (4,096 stopped 91 of 116 of them, this 11)
FALLBACK_STALL = 32768
#: in the fallback, a search stalls (gives way) only while a tree holds at most this many nodes: a root
#: walled in (Fetch bookshelf_thin goals between shelves: 5 to 15 nodes in both trees after 1 s), not a
#: search pausing on its way
WALLED_NODES = 16
#: in the fallback, a stalled search halves the spheres' growth toward the covering ones; below this
#: blend they are the spheres as given
FALLBACK_MIN_BLEND = 0.05
#: random seeds of the numeric IK for a pose goal (each distinct solution joins the goal set)
IK_SEEDS = 32


@dataclass
class MotionPlan:
    """Result of :func:`plan_motion`.

    Attributes:
        success: True only if the final trajectory passed the dense check.
        reason: "" on success, else why.
        failure: the shared failure reason (``Failure.NONE`` on success).
        trajectory: the time-parametrised trajectory (None when no path was found).
        path: (k, n) geometric waypoints before timing, rad.
        plan_ms: wall time of the whole call, ms.
        timings: wall time per stage, ms (summed over the attempts).
        min_clearance_m: smallest clearance of the checked trajectory, m (capped at d_min + 0.1;
            see :class:`~robointel.planning.motion_check.DenseCheck`).
        goal_index: index of the goal reached in the goal set (-1 when none).
        cpu_timings: process CPU time per stage, ms (the keys of ``timings``; on a shared machine the
            wall time also counts the other processes' turns).
    """

    success: bool
    reason: str
    failure: Failure
    trajectory: Trajectory | None
    path: np.ndarray | None
    plan_ms: float
    timings: dict[str, float] = field(default_factory=dict)
    min_clearance_m: float = float("nan")
    goal_index: int = -1
    cpu_timings: dict[str, float] = field(default_factory=dict)


def _goal_set(robot: Robot, goal: npt.ArrayLike | Sequence[npt.ArrayLike], seed: int) -> np.ndarray:
    """Goal configurations (G, n) from one configuration, a set, or a 4x4 TCP pose (IK solutions)."""
    try:
        g = np.asarray(goal, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInput("goal must be a configuration (n,), a set (G, n) or a 4x4 TCP pose", value=goal) from None
    n = robot.nq
    is_pose = g.shape == (4, 4) and np.allclose(g[3], [0, 0, 0, 1]) and (n != 4 or np.isfinite(g).all())
    if is_pose and np.allclose(g[:3, :3].T @ g[:3, :3], np.eye(3), atol=1e-6):
        sols: list[np.ndarray] = []
        rng = np.random.default_rng(seed)
        for _ in range(IK_SEEDS):
            try:
                q = robot.ik_numeric(g, q0=robot.random_configuration(rng), restarts=0, rng=int(rng.integers(1 << 31)))
            except IKFailure:
                continue
            if all(np.linalg.norm(q - s) > 1e-3 for s in sols):
                sols.append(q)
        if not sols:
            raise IKFailure(f"no IK solution for the goal pose at {np.round(g[:3, 3], 4).tolist()} m", value=g)
        return np.array(sols)
    if g.ndim == 1:
        g = g[None]
    if g.ndim != 2 or g.shape[1] != n or len(g) == 0:
        raise InvalidInput(f"goal must be ({n},), (G, {n}) or a 4x4 pose, got shape {g.shape}", value=goal)
    return np.array([robot.check_q(robot.snap_to_limits(robot.check_q(q, f"goal[{k}]")), f"goal[{k}]", limits=True)
                     for k, q in enumerate(g)])


def _fail(reason: str, failure: Failure, t0: float, timings: StageTimes, path: np.ndarray | None = None,
          traj: Trajectory | None = None, clearance: float = float("nan"), goal: int = -1) -> MotionPlan:
    return MotionPlan(False, reason, failure, traj, path, (time.perf_counter() - t0) * 1e3, dict(timings), clearance,
                      goal, dict(timings.cpu))


def plan_motion(robot: Robot, environment: Environment, start: npt.ArrayLike,
                goal: npt.ArrayLike | Sequence[npt.ArrayLike], *,
                settings: MotionSettings = MotionSettings()) -> MotionPlan:
    """Plan a collision-free, time-parametrised motion from ``start`` to ``goal``.

    Args:
        robot: the arm (the one ``environment`` was built for).
        environment: obstacles, spheres and self-collision pairs.
        start: (n,) start configuration, rad.
        goal: (n,) goal configuration, (G, n) goal set (the first reached wins), or a 4x4 TCP pose
            (its IK solutions are the goal set).
        settings: see :class:`MotionSettings`.

    Returns:
        The :class:`MotionPlan`; ``success`` only after the dense check of the final trajectory.

    Raises:
        InvalidInput: bad shapes, NaN, limits, or an environment built for another robot.
        CollisionAtStart: the start, or every goal, is closer than max(``d_min`` - 1 mm, 0) (the
            dense check's tolerance; names the pair).
        IKFailure: a pose goal without IK solutions.
    """
    if not isinstance(environment, Environment) or environment.robot is not robot:
        raise InvalidInput("environment must be an Environment built for this robot", value=environment)
    _warmup(environment)
    t0, c0 = time.perf_counter(), cpu_clock()
    timings = StageTimes()
    if not isinstance(settings, MotionSettings):
        raise InvalidInput("settings must be a MotionSettings", value=settings)
    st = settings
    if not (st.d_min >= 0 and st.time_budget_s > 0 and st.resolution > 0 and st.rrt_range > 0 and st.rrt_domain > 0
            and 0 < st.velocity_scale <= 1 and st.knot_step > 0 and st.spline_step > 0 and st.check_dt > 0
            and st.root_relaxed_rad > 0 and st.timing in ("topp", "temporal") and 0 < st.fitted_fallback <= 1
            and st.budget_clock in ("wall", "cpu")):
        raise InvalidInput("settings need d_min >= 0, time_budget_s, resolution, rrt_range, rrt_domain, knot_step, "
                           "spline_step, check_dt, root_relaxed_rad > 0, 0 < velocity_scale, fitted_fallback <= 1, "
                           "timing 'topp' or 'temporal' and budget_clock 'wall' or 'cpu'",
                           value=st)
    q0 = robot.check_q(robot.snap_to_limits(robot.check_q(start, "start")), "start", limits=True)  # a writable copy
    goals = _goal_set(robot, goal, st.seed)
    if robot.continuous.any():  # continuous joints: each goal by the shorter turn
        goals = np.array([robot.wrap_goal(g, q0) for g in goals])
    env = environment
    model = env.model
    env.set_self_offset(st.d_min)
    try:
        with budget_clock(st.budget_clock):
            return _plan(env, q0, goals, st, t0, c0, timings)
    finally:
        env.set_self_offset(0.0)
        env.set_self_blend(0.0)
        env.use(model)


def _roots_free(env: Environment, q0: np.ndarray, goals: np.ndarray, d_min: float) -> bool:
    return (env.clearance(q0, cap=d_min + 1.0) >= d_min
            and any(env.clearance(g, cap=d_min + 1.0) >= d_min for g in goals))


def _grow(env: Environment, chk: DenseCheck, q0: np.ndarray, goals: np.ndarray, thr: float, obstacles: bool) -> bool:
    """Move the spheres of the links the collision meshes caught toward the covering ones, for the next attempt.

    A self-collision pair (``chk.links``: two links) grows their self-collision radii; with
    ``obstacles`` (the fitted-sphere fallback, or a hybrid plan, whose start and goal edges run in the
    fitted spheres), a link the obstacle mesh check caught grows its obstacle radii. Each goes all the
    way, else half, a quarter... (5 tries) as far as the start and every goal keep clearance ``thr``.
    Returns whether a radius grew.
    """
    if len(chk.links) == 2:
        cur = np.broadcast_to(np.asarray(env.self_blend, float), (len(env.sphere_links),)).copy()

        def put(b: np.ndarray) -> None:
            env.set_self_blend(b)
    elif len(chk.links) == 1 and obstacles:
        cur = env.blend.copy()

        def put(b: np.ndarray) -> None:
            env.use("fitted", blend=b)
    else:
        return False
    mask = env.link_spheres(chk.links)
    if not np.any(cur[mask] < 1.0):
        return False
    step = 1.0
    for _ in range(5):
        b = cur.copy()
        b[mask] = np.minimum(1.0, cur[mask] + step)
        put(b)
        if all(env.clearance(q, cap=thr + 1.0) >= thr for q in [q0, *goals]):
            return True
        step *= 0.5
    put(cur)
    return False


def _plan(env: Environment, q0: np.ndarray, goals: np.ndarray, st: MotionSettings, t0: float, c0: float,
          timings: StageTimes) -> MotionPlan:
    robot = env.robot
    exact_ids = np.arange(len(goals))  # the caller's index of each goal kept
    if env.exact_self:  # the roots judged on the exact geometry (fitted spheres lie inside it, a file's miss parts)
        exact_ids = exact_roots(env, q0, goals, max(st.d_min - CLEARANCE_TOL, 0.0))
        goals = goals[exact_ids]
        # the fitted spheres grown toward the meshes for self-collision, as far as the roots allow
        gap = min(env.self_clearance(q, cap=1.0) for q in [q0, *goals])
        # (the roots must keep the dense check's floor max(d_min - 1 mm, 0): d_min - floor below d_min)
        slack = st.d_min - max(st.d_min - CLEARANCE_TOL, 0.0)
        margin = float(np.clip(0.5 * (gap - env.self_padding + slack) - 1e-4, 0.0, SELF_MARGIN))
        env.set_self_offset(st.d_min, margin)
    # the mesh-covering spheres where start and a goal allow them, else the spheres as given
    env.use("cover")
    hybrid = env.cover_meshes and not _roots_free(env, q0, goals, st.d_min)
    lo = 0.0  # how far the fitted spheres grow toward the covering ones with start and goals still free
    if hybrid:  # edges at the start and goals in spheres grown as far as they allow, the rest covering
        env.use("fitted")
        hi = 1.0
        if _roots_free(env, q0, goals, st.d_min):
            for _ in range(8):
                mid = 0.5 * (lo + hi)
                env.use("fitted", blend=mid)
                lo, hi = (mid, hi) if _roots_free(env, q0, goals, st.d_min) else (lo, mid)
        env.use("fitted", blend=lo)
    Wc = env.world_cover
    Wr = env.world if hybrid else Wc
    rcap = float(st.root_relaxed_rad) if hybrid else float("inf")
    # the roots may be up to the dense check's tolerance closer than d_min, never below 0 (e.g. sphere
    # pairs of a folded wrist whose meshes are clear); the search then keeps the smallest root clearance
    floor = max(st.d_min - CLEARANCE_TOL, 0.0)
    env.check_free(q0, d_min=floor, what="start configuration")
    cg = np.array([env.clearance(g, cap=st.d_min + 1.0) for g in goals])
    ok = cg >= floor
    if not any(ok):
        env.check_free(goals[0], d_min=floor, what="goal configuration" if len(goals) == 1 else "every goal; goal 0")
    goal_ids = exact_ids[np.flatnonzero(ok)]
    goals = goals[np.flatnonzero(ok)]
    thr = min(st.d_min, env.clearance(q0, cap=st.d_min + 1.0), float(cg[ok].min()))
    vmax = robot.velocity_limit * st.velocity_scale
    amax = np.asarray(st.acceleration_limit if st.acceleration_limit is not None else robot.acceleration_limit, float)
    if amax.shape != (robot.nq,) or np.any(amax <= 0):
        raise InvalidInput(f"acceleration_limit must be ({robot.nq},) positive", value=amax)
    timings.add("validate", t0, c0)

    now = clock_now()
    deadline = now + st.time_budget_s
    fallback = env.cover_meshes and len(env._cloud[0]) == 0 and st.fitted_fallback < 1
    search_end = now + st.fitted_fallback * st.time_budget_s if fallback else deadline
    attempt, exact = 0, False
    carry = TreeCarry()  # each search leaves its trees to the next (tree_search.TreeCarry)
    while True:
        # a search gives way when it stalls while another model is left to try: the fallback, or in the
        # fallback the spheres grown less far
        stall = FALLBACK_STALL if search_end < deadline or (exact and np.any(env.blend > 0)) else 0
        path, gi, traj, chk, why = _attempt(env, q0, goals, st, deadline, search_end, Wc, Wr, rcap, vmax, amax,
                                            timings, attempt, thr, exact, stall, WALLED_NODES if exact else None,
                                            carry)
        if path is None and not exact and fallback and clock_now() < deadline:
            # the covering spheres leave no way found in time: the spheres as given, grown as far as the
            # roots allow everywhere (not only near them), checked on the meshes
            env.use("fitted", blend=lo)
            Wc = Wr = env.world
            rcap, exact, search_end, attempt = float("inf"), True, deadline, attempt + 1
            timings["fitted_after"] = (clock_now() - now) * 1e3
            continue
        if path is None and exact and why.startswith("stalled") and clock_now() < deadline:
            # a root walled in by the grown spheres (grown until a root barely kept its clearance): half as far
            b = 0.5 * env.blend
            env.use("fitted", blend=np.where(b < FALLBACK_MIN_BLEND, 0.0, b))
            Wc = Wr = env.world
            attempt += 1
            continue
        if path is None:
            return _fail(f"no collision-free path found: {why}", Failure.TIMEOUT, t0, timings)
        assert chk is not None
        if chk.kind == "timeout":
            return _fail(f"{chk.reason} (attempt {attempt + 1})", Failure.TIMEOUT, t0, timings, path, traj,
                         chk.min_clearance_m, int(goal_ids[gi]))
        # a start/goal edge that touches the real meshes: another tree may approach differently
        if chk.ok or not (hybrid or exact or env.exact_self) or chk.kind != "collision" or \
                clock_now() >= deadline:
            break
        grew = _grow(env, chk, q0, goals, thr, exact or hybrid)  # the links caught kept farther next time
        if grew:
            Wc = env.world if exact else env.world_cover
            Wr = env.world if (exact or hybrid) else Wc
        if not grew or path_valid(env, path, thr, st.resolution, Wc, Wr, rcap):
            carry.trees = None  # the refused path still valid: the next search looks for another way afresh
        attempt += 1
    goal_index = int(goal_ids[gi])
    assert traj is not None and chk is not None
    traj.meta.update({"min_clearance_m": chk.min_clearance_m, "goal_index": goal_index,
                      "collision_model": env.model})
    if not chk.ok:
        fail = Failure.COLLISION if chk.kind == "collision" else Failure.LIMIT
        return _fail(f"dense check failed: {chk.reason}", fail, t0, timings, path, traj, chk.min_clearance_m,
                     goal_index)
    return MotionPlan(True, "", Failure.NONE, traj, path, (time.perf_counter() - t0) * 1e3, dict(timings),
                      chk.min_clearance_m, goal_index, dict(timings.cpu))


def _attempt(env: Environment, q0: np.ndarray, goals: np.ndarray, st: MotionSettings, deadline: float,
             search_end: float, Wc: tuple, Wr: tuple, rcap: float, vmax: np.ndarray, amax: np.ndarray,
             timings: StageTimes, attempt: int, thr: float, exact: bool = False, stall: int = 0,
             walled: int | None = None, carry: TreeCarry | None = None
             ) -> tuple[np.ndarray | None, int, Trajectory | None, DenseCheck | None, str]:
    """One search, shortcut, timing and dense check: (path, goal, trajectory, check, why not).

    The search and the shortcut keep sphere clearance ``thr`` (<= d_min); the dense check d_min - 1 mm.
    Root edges are relaxed (``Wr``) for ``rcap`` rad (inf: not hybrid, ``Wr`` is ``Wc``). Past
    ``deadline`` the check is a failed one of kind ``"timeout"`` (the stages look at the clock
    between steps); the search itself ends at ``search_end``, or sooner when it stalls (no node added
    in ``stall`` > 0 iterations, with ``walled`` only while a tree holds at most that many nodes
    besides its roots: the caller has another model to try; its reason then starts ``"stalled"``).
    ``exact``: every sample the covering spheres leave in doubt is checked on the collision meshes
    (:func:`exact_check`). ``carry``: the trees of the last search
    (:class:`~robointel.planning.tree_search.TreeCarry`), gone on from where they are still valid.
    """
    # global stage ----------------------------------------------------------------------------
    t1, c1 = time.perf_counter(), cpu_clock()
    path, gi, why = None, -1, ""
    res = float(st.search_resolution)
    while path is None:
        path, gi, why = search(env, q0, goals, st, res, search_end, Wc, Wr, attempt, thr, rcap,
                               stall, walled, carry)
        if path is None:
            timings.add("search", t1, c1)
            return None, -1, None, None, why
        if path_valid(env, path, thr, st.resolution, Wc, Wr, rcap):
            break
        if clock_now() >= deadline:
            timings.add("search", t1, c1)
            return None, -1, None, None, f"the time budget of {st.time_budget_s:g} s ran out re-checking a path"
        path, res = None, res / 4  # an edge failed the fine check: search again, finer
        if res < st.resolution:
            res = float(st.resolution)
    timings.add("search", t1, c1)
    path, traj, chk = _finish(env, path, st, deadline, Wc, Wr, rcap, vmax, amax, timings, attempt, thr, exact)
    return path, gi, traj, chk, ""


def _finish(env: Environment, path: np.ndarray, st: MotionSettings, deadline: float, Wc: tuple, Wr: tuple,
            rcap: float, vmax: np.ndarray, amax: np.ndarray, timings: StageTimes, attempt: int, thr: float,
            exact: bool) -> tuple[np.ndarray, Trajectory | None, DenseCheck | None]:
    """The stages after the search: shortcut, timing and the dense (and mesh) checks of one attempt.

    Args and clock as :func:`_attempt`; ``path`` (k, n) is the search's path, every edge valid at
    ``st.resolution`` in ``Wc`` (``Wr`` within ``rcap`` of a root). Returns (shortened path,
    trajectory, check).
    """
    robot = env.robot
    hybrid = rcap != float("inf")
    t2, c2 = time.perf_counter(), cpu_clock()
    s = env.scratch
    P = np.empty((max(len(path) * 2 + 64, 256), robot.nq))
    P[:len(path)] = path
    R.seed(int(st.seed) + 1 + 7 * attempt)
    m = TS.shortcut_time(P, len(path), int(st.shortcut_iters), Wc, Wr, rcap, batch_state(env), s.out, float(thr),
                         env.lever, float(st.resolution), 1.0 / vmax, 1.0 / amax)
    path = P[:m].copy()
    keep = np.concatenate([[True], np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-9])
    keep[-1] = True
    path = path[keep]
    timings.add("shortcut", t2, c2)
    traj, chk = smooth_and_check(env, path, st, deadline, Wc, hybrid, vmax, amax, timings, exact)
    return path, traj, chk


_WARM: set[int] = set()


def _warmup(env: Environment) -> None:
    """Compile (or load from the disk cache) the kernels once per process.

    Runs, outside the time budget and plan_ms.
    """
    key = id(env.robot)
    if key in _WARM:
        return
    W, s = env.world, env.scratch
    q = np.clip(np.zeros(env.robot.nq), env.robot.lower, env.robot.upper)
    warm_search(env)
    P = np.array([q, q + 1e-3 * (env.robot.upper - q)])
    one = np.ones(env.robot.nq)
    BS = batch_state(env)
    TS.shortcut_time(P, 2, 0, W, W, 0.2, BS, s.out, 0.0, env.lever, 0.01, one, one)
    BE.root_edge_batch(P[0], P[1], W, W, True, True, 0.2, BS, 0.0, 0.01, s.out)
    K.samples_clearance(P, W, s.T, s.C, s.G, s.out, env.lever, 0.0, 0.1)
    K.samples_env_below(P, W, s.T, s.C, s.G, s.out, env.lever, 0.0)
    V = np.empty(P.shape)  # the dense check's kernels (called directly: tests count check_dense's calls)
    D.limits_travel(P, P, P, np.asarray(env.robot.lower, float), np.asarray(env.robot.upper, float),
                    np.ones(env.robot.nq), np.ones(env.robot.nq), V)
    D.span_clearance(P, V, 0, 2, W, s.T, s.C, s.G, s.out, env.lever, 0.0, 0.1, 0.1)
    D.variation(P, V)
    D.env_below(P, V, W, s.T, s.C, s.G, s.out, env.lever, 0.0)
    if env.cover_meshes:  # the collision meshes and their hulls, loaded once per robot; the broad phase
        MeshGeometry(env.robot, [])
        warm_broad_phase()
    lim = np.ones(env.robot.nq)
    e = 0.1 * np.eye(env.robot.nq)
    topp_spline(np.array([q, q + e[0], q + e[0] + e[-1]]), lim, lim)  # a path with a corner
    _WARM.add(key)


__all__ = ["MotionSettings", "MotionPlan", "plan_motion"]
