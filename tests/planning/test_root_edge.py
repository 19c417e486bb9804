"""The root-edge cap: an edge leaving a start/goal that is free only in the relaxed spheres is checked in
them for its first ``root_relaxed_rad`` (max |dq|) and in the mesh-covering spheres beyond; and the time
budget of a plan holds for an impossible problem and inside an attempt's collision-mesh check."""
from __future__ import annotations

import time

import numpy as np
import pytest

from robointel.geometry.obstacles import Box
from robointel.outcome import Failure
from robointel.planning import Environment, MotionSettings, plan_motion
from robointel.planning import _collision_kernels as K
from robointel.planning import _edge_kernels as E
from robointel.planning.hybrid_check import interior_check, interior_window
from robointel.planning.motion_check import check_dense
from robointel.robot import Robot
from robointel.trajectory import Trajectory


def test_root_edge_relaxed_only_near_the_root(thin70):
    p, env = thin70
    env.use("fitted")
    Wr, W, s, robot = env.world, env.world_cover, env.scratch, env.robot

    def clear(q: np.ndarray, world: tuple) -> float:
        return float(K.config_clearance(q, world, s.T, s.C, s.G, s.out, 1.0))

    thr, res, cap, gap = 0.0, 0.02, 0.2, 0.004
    q0 = np.asarray(p.goals[0], float)
    assert clear(q0, Wr) >= thr > clear(q0, W)  # a root inside the relaxed margin
    rng = np.random.default_rng(3)
    left = refused = 0
    for _ in range(300):
        d = rng.normal(0.0, 1.0, 6)
        d *= rng.uniform(0.3, 1.2) / np.abs(d).max()
        q1 = np.clip(q0 + d, robot.lower, robot.upper)
        if not K.config_valid(q1, W, s.T, s.C, s.G, s.out, thr):
            continue
        ok = E.root_edge(q0, q1, Wr, W, True, False, cap, s.T, s.C, s.G, s.out, thr, env.lever, res, 0.0)
        k = int(np.ceil(K.travel(q0, q1, env.lever) / gap)) + 1
        f = np.linspace(0.0, 1.0, k)
        far = f * np.abs(q1 - q0).max() > cap + 1e-9  # beyond the cap: the covering spheres decide
        d_far = min((clear(q0 + t * (q1 - q0), W) for t in f[far]), default=np.inf)
        d_near = min(clear(q0 + t * (q1 - q0), Wr) for t in f[~far])
        if ok:  # the start still leaves, and the guarantee holds in each stretch's world
            left += 1
            assert not E.edge_valid(q0, q1, W, s.T, s.C, s.G, s.out, thr, env.lever, res)
            assert d_near >= thr - res / 2 - 1e-9 and d_far >= thr - res / 2 - 1e-9
        elif E.edge_valid(q0, q1, Wr, s.T, s.C, s.G, s.out, thr, env.lever, res):
            # refused although the relaxed spheres clear it all: its far part crosses what only the
            # covering spheres see
            refused += 1
            assert d_far < thr + gap
    assert left >= 5 and refused >= 1


def test_root_edge_without_roots_and_with_both(thin70):
    p, env = thin70
    env.use("fitted")
    Wr, W, s = env.world, env.world_cover, env.scratch
    q0, q1 = np.asarray(p.start, float), np.asarray(p.goals[0], float)
    args = (s.T, s.C, s.G, s.out, 0.0, env.lever, 0.02, 0.0)
    # no root: the plain walk in W; an edge within the cap of its roots everywhere: Wr alone
    assert E.root_edge(q0, q1, Wr, W, False, False, 0.2, *args) == E.edge_valid(q0, q1, W, *args[:-1])
    q2 = q1 + 0.1 * np.sign(q0 - q1)
    assert E.root_edge(q2, q1, Wr, W, True, True, 0.2, *args) == E.edge_valid(q2, q1, Wr, *args[:-1])


def test_hybrid_problem_planned_with_the_cap(thin70):
    p, env = thin70
    plan = plan_motion(env.robot, env, p.start, p.goals, settings=MotionSettings(d_min=0.001, seed=7919 + 70,
                                                                                  time_budget_s=30.0))
    assert plan.success, plan.reason  # passed the collision-mesh check of its start and goal edges
    first = np.abs(plan.path[1] - plan.path[0]).max()
    assert first > 0.0


def test_impossible_problem_fails_within_the_budget():
    """scara2 turning from 0 to 2.5 rad must sweep link 1 through +90 deg, where a post stands."""
    robot = Robot.load("scara2")
    env = Environment(robot, [Box(center=[0.0, 0.3, 0.3], size=[0.1, 0.1, 1.0], name="post")])
    budget = 1.0
    t0 = time.perf_counter()
    plan = plan_motion(robot, env, [0.0, 0.0], [2.5, 0.0], settings=MotionSettings(time_budget_s=budget))
    wall = time.perf_counter() - t0
    assert not plan.success and plan.failure is Failure.TIMEOUT and "time budget" in plan.reason
    assert wall < budget + 10.0  # the budget plus the last chunk of RRT iterations, generous under load


def test_mesh_check_stops_at_the_deadline(thin70):
    p, env = thin70
    plan = plan_motion(env.robot, env, p.start, p.goals, settings=MotionSettings(d_min=0.001, seed=7919 + 70,
                                                                                  time_budget_s=30.0))
    assert plan.success, plan.reason
    env.use("fitted")
    tr = plan.trajectory
    vmax, amax = env.robot.velocity_limit, env.robot.acceleration_limit
    chk = check_dense(env, tr, d_min=0.001, vmax=vmax, amax=amax)
    done = interior_check(env, tr, plan.path, env.world_cover, chk, d_min=0.001, dt=1e-3)
    late = interior_check(env, tr, plan.path, env.world_cover, chk, d_min=0.001, dt=1e-3,
                          deadline=time.perf_counter() - 1.0)
    assert done.ok
    assert not late.ok and late.kind == "timeout" and "time budget" in late.reason


@pytest.mark.parametrize("late", [False, True])
def test_limit_failed_smoothing_honours_the_budget(monkeypatch, late):
    """A smoothing check that failed on a limit (not a collision) falls back to rest-to-rest timing
    before the deadline; past it the plan ends with ``Failure.TIMEOUT`` and the fallback never runs.

    The smoothing's check is made to fail on a limit, and (``late``) the planner's clock is moved
    past the deadline right after it, so the test does not depend on the machine's speed.
    """
    import robointel.planning.motion as M
    import robointel.planning.smoothing as S

    robot = Robot.load("lrmate200id7l")
    env = Environment(robot, [Box(center=[0.35, 0.0, 0.35], size=[0.1, 0.2, 0.7], name="post")], floor=0.0)
    q0 = np.array([0.9, 0.3, 0.0, 0.0, -0.5, 0.0])
    q1 = np.array([-0.9, 0.3, 0.0, 0.0, -0.5, 0.0])
    calls = {"check": 0, "polyline": 0}
    skew = [0.0]
    real_check, real_polyline = S.check_dense, S.polyline_timing

    def check(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls["check"] += 1
        chk = real_check(*args, **kwargs)
        if calls["check"] > 1:
            return chk
        skew[0] = 1e6 if late else 0.0
        return M.DenseCheck(False, "velocity limit (made to fail)", "limit", chk.min_clearance_m, chk.samples)

    def polyline(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls["polyline"] += 1
        return real_polyline(*args, **kwargs)

    monkeypatch.setattr(S, "check_dense", check)
    monkeypatch.setattr(S, "polyline_timing", polyline)
    real_now = M.clock_now  # the budget's clock (wall or CPU time), read by the planner and its smoothing
    monkeypatch.setattr(M, "clock_now", lambda: real_now() + skew[0])
    monkeypatch.setattr(S, "clock_now", lambda: real_now() + skew[0])
    plan = plan_motion(robot, env, q0, q1, settings=MotionSettings(d_min=0.01, time_budget_s=30.0))
    assert plan.path is not None and len(plan.path) > 2  # the post makes corners: the path was smoothed
    if late:
        assert not plan.success and plan.failure is Failure.TIMEOUT and "time budget" in plan.reason
        assert calls == {"check": 1, "polyline": 0}
    else:
        assert plan.success, plan.reason  # the rest-to-rest fallback along the checked polyline
        assert calls == {"check": 2, "polyline": 1}


def test_covering_spheres_are_never_clearer_than_the_relaxed(thin70):
    """The window of the dense check relies on it: passing in the covering spheres passes in any blend."""
    p, env = thin70
    s, robot = env.scratch, env.robot
    rng = np.random.default_rng(17)
    qs = [np.asarray(p.goals[0], float)] + [robot.random_configuration(rng) for _ in range(60)]
    try:
        for blend in (0.0, 0.5, 0.93):
            env.use("fitted", blend=blend)
            for q in qs:
                dc = float(K.config_clearance(q, env.world_cover, s.T, s.C, s.G, s.out, 1.0))
                assert dc <= float(K.config_clearance(q, env.world, s.T, s.C, s.G, s.out, 1.0)) + 1e-12
    finally:
        env.use("cover")


def test_dense_check_window_in_the_covering_spheres(thin70):
    p, env = thin70
    robot = env.robot
    vmax, amax = robot.velocity_limit, robot.acceleration_limit
    plan = plan_motion(robot, env, p.start, p.goals, settings=MotionSettings(d_min=0.001, seed=7919 + 70,
                                                                            time_budget_s=30.0))
    assert plan.success, plan.reason
    env.use("fitted")
    try:
        tr = plan.trajectory
        win = (*interior_window(tr, plan.path), env.world_cover)
        old = interior_check(env, tr, plan.path, env.world_cover, check_dense(env, tr, d_min=0.001, vmax=vmax,
                             amax=amax), d_min=0.001, dt=1e-3)
        new = check_dense(env, tr, d_min=0.001, vmax=vmax, amax=amax, window=win)
        # the same verdict (the clearances either reports above d_min are proven bounds, not minima: the
        # samples they skip differ, so their values do not compare)
        assert old.ok and new.ok
        # resting at the goal (free in the fitted spheres, not in the covering ones), all of it interior
        g = np.asarray(p.goals[0], float)
        z = np.zeros((11, robot.nq))
        rest = Trajectory(np.linspace(0.0, 0.01, 11), np.tile(g, (11, 1)), z, z, list(robot.joint_names))
        path = np.array([p.start, g, p.start])
        assert check_dense(env, rest, d_min=0.001, vmax=vmax, amax=amax).ok
        bad = check_dense(env, rest, d_min=0.001, vmax=vmax, amax=amax, window=(*interior_window(rest, path),
                                                                                 env.world_cover))
        assert not bad.ok and bad.kind == "collision" and "covering spheres" in bad.reason
        plain = check_dense(env, rest, d_min=0.001, vmax=vmax, amax=amax)
        assert not interior_check(env, rest, path, env.world_cover, plain, d_min=0.001, dt=1e-3).ok  # as before
    finally:
        env.use("cover")
