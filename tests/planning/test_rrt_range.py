"""The RRT search kernel: exact nearest neighbours, each tree's adaptive range, determinism per seed.

A cage goal of MotionBenchMaker sits in a narrow pocket: long extensions of the goal tree almost
all fail, so its range must drop while the start tree's (in free space) stays as asked.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from robointel.geometry._kernels import point_distances
from robointel.io.mbm import load_mbm_problems
from robointel.planning import Environment, MotionSettings
from robointel.planning import _collision_kernels as K
from robointel.planning import _node_check as NC
from robointel.planning import _rrt_kernels as R
from robointel.planning._batch_view import obstacle_boxes
from robointel.planning.budget_clock import now as clock_now
from robointel.planning.motion import FALLBACK_STALL, _goal_set
from robointel.planning.tree_search import batch_state, search
from robointel.robot import Robot


def test_nearest_is_the_exact_nearest():
    rng = np.random.default_rng(3)
    walk = np.cumsum(rng.normal(0.0, 0.3, (3000, 6)), axis=0)  # clustered, as a tree's nodes
    for Q in (walk, rng.uniform(-6, 6, (3000, 6))):
        for q in rng.uniform(-6, 6, (50, 6)):
            i, d = R._nearest(Q, 2500, q)
            dist = np.linalg.norm(Q[:2500] - q, axis=1)
            assert i == int(np.argmin(dist)) and d == pytest.approx(dist.min(), rel=1e-12)
            for n in (2500, 15, 16, 17):  # joint by joint; the lanes' remainder
                j, e = R._nearest_soa(np.ascontiguousarray(Q.T), n, q, np.empty(3000))
                k = int(np.argmin(dist[:n]))
                assert j == k and e == pytest.approx(dist[k], rel=1e-12)
    for nj in (3, 9):  # joints one by one only; two passes of four and one more. A tie: the first
        Q = rng.uniform(-1, 1, (40, nj))
        Q[30] = Q[7]
        j, e = R._nearest_soa(np.ascontiguousarray(Q.T), 40, Q[7] + 1e-3, np.empty(40))
        assert j == 7 and e == pytest.approx(np.sqrt(nj) * 1e-3, rel=1e-9)


def test_adapt_halves_and_doubles_within_bounds():
    rng, win = np.array([1.0, 1.0, 1.0]), np.zeros((2, 2), np.int64)
    for _ in range(R.WINDOW * 10):  # tree 1 never succeeds: halves each window down to the floor
        R._adapt(rng, win, 1, False)
    assert rng[1] == R.MIN_RANGE and rng[0] == 1.0
    few = R.WINDOW // 8
    for k in range(R.WINDOW):  # fewer than 1/8 succeed: halves for tree 0
        R._adapt(rng, win, 0, k < few - 1)
    assert rng[0] == max(0.5, R.MIN_RANGE)
    for k in range(R.WINDOW):  # 1/8 exactly (not < 1/8, not > 1/2): unchanged
        R._adapt(rng, win, 0, k < few)
    assert rng[0] == max(0.5, R.MIN_RANGE)
    for _ in range(R.WINDOW * 10):  # all succeed: doubles up to the range asked for, never beyond
        R._adapt(rng, win, 1, True)
    assert rng[1] == 1.0 and rng[2] == 1.0


@pytest.fixture(scope="module")
def cage(shared_data, tmp_path_factory):
    root = shared_data("mbm", "ur5")
    robot = Robot.load(root / "ur5.urdf")
    data = json.loads((root / "problems.json").read_text())
    one = tmp_path_factory.mktemp("cage") / "one.json"  # the reader on this problem alone (all 689 is slow)
    one.write_text(json.dumps({**data, "problems": {"cage": [r for r in data["problems"]["cage"] if r["index"] == 4]}}))
    p = load_mbm_problems(one).select(index=4)[0]
    env = Environment(robot, p.obstacles, srdf=root / "ur5.srdf", spheres=root / "ur5_spherized.urdf")
    env.use("cover")
    goals = _goal_set(robot, p.goals, 0)
    return env, np.asarray(p.start, float), goals


def _grow(env, q0, goals, seed, iters=1536, dom=None, rdom=4.0):
    W, s, n, cap = env.world_cover, env.scratch, len(q0), 4000
    X, parent = np.zeros((2, n, cap)), np.full((2, cap), -1, np.int64)  # the nodes joint by joint
    count = np.array([1, len(goals)], np.int64)
    nroot = count.copy()
    X[0, :, 0], X[1, :, :len(goals)] = q0, goals.T
    rng, win, link = np.ones(3), np.zeros((2, 2), np.int64), np.zeros(2, np.int64)
    dom = np.full((2, cap), np.inf) if dom is None else dom
    R.seed(seed)
    status = 0
    for _ in range(iters // 32):
        status = R.rrt_connect(X, parent, count, env.robot.lower, env.robot.upper, 32, rng, win, W, W, nroot,
                               np.inf, s.T, s.C, s.G, s.out, 0.001, env.lever, 0.02, link, batch_state(env), dom,
                               rdom)
        if status != 0:
            break
    return X.transpose(0, 2, 1), parent, count, rng, status


def test_goal_tree_steps_shorter_in_a_pocket_and_search_is_deterministic(cage):
    env, q0, goals = cage
    nodes, parent, count, rng, status = _grow(env, q0, goals, seed=11)
    assert rng[2] == 1.0 and rng[0] == 1.0  # the start tree in free space keeps the range asked for
    assert rng[1] < 1.0  # the goal tree's long extensions failed: it steps shorter
    for t in range(2):  # no edge is longer than the range asked for; every node is valid
        for i in range(int(count[t])):
            if parent[t, i] >= 0:
                assert np.linalg.norm(nodes[t, i] - nodes[t, parent[t, i]]) <= 1.0 + 1e-9
                assert env.clearance(nodes[t, i], cap=0.1) >= 0.001 - 1e-9
    again = _grow(env, q0, goals, seed=11)
    assert again[4] == status and np.array_equal(again[2], count) and np.array_equal(again[3], rng)
    assert all(np.array_equal(again[0][t, :count[t]], nodes[t, :count[t]]) for t in range(2))
    assert all(np.array_equal(again[1][t, :count[t]], parent[t, :count[t]]) for t in range(2))


def test_a_node_is_extended_only_toward_samples_within_its_dynamic_domain(cage):
    """Every node's domain empty: no sample is tried, no node added. Grown with domains of 0.3 rad: a node whose
    extension failed holds 0.3, every other node inf, and the goal tree in the cage pocket has such nodes."""
    env, q0, goals = cage
    shut = np.zeros((2, 4000))
    nodes, parent, count, rng, status = _grow(env, q0, goals, seed=11, iters=512, dom=shut)
    assert status == 0 and list(count) == [1, len(goals)] and np.all(shut == 0.0)
    dom = np.full((2, 4000), np.inf)
    nodes, parent, count, rng, status = _grow(env, q0, goals, seed=11, dom=dom, rdom=0.3)
    for t in range(2):
        d = dom[t, :count[t]]
        assert np.all((d == 0.3) | (d == np.inf))
    assert np.any(dom[1, :count[1]] == 0.3)


def test_node_check_gives_config_valids_verdict(cage):
    """The search's node check (groups from the tool back, tests against the threshold alone) refuses and
    accepts exactly the configurations ``config_valid`` does: uniform ones and ones near the cage goal."""
    env, q0, goals = cage
    W, s = env.world_cover, env.scratch
    obox = obstacle_boxes(W[12], W[13])
    rs = np.random.default_rng(5)
    U = rs.uniform(env.robot.lower, env.robot.upper, (3000, len(q0)))
    D = U - goals[0]
    near = goals[0] + rs.uniform(0.0, 0.5, (3000, 1)) * D / np.linalg.norm(D, axis=1)[:, None]
    seen = set()
    for thr in (0.0, 0.001, 0.03):
        for q in np.concatenate([U, near]):
            v = K.config_valid(q, W, s.T, s.C, s.G, s.out, thr)
            kind = int(s.out[0])
            assert NC.config_free(q, W, s.T, s.C, s.G, s.out, thr, obox) == v
            seen.add((v, kind))
    assert {(True, -1), (False, K.ENV), (False, K.SELF)} <= seen  # free, an obstacle and a self-collision met


def test_clearance_is_the_brute_force_minimum(cage):
    """The compiled clearance (obstacles, and self-collision pairs culled by group and then by each sphere
    against the other group's bounding sphere) equals the minimum over every obstacle and every checked sphere
    pair, measured one by one: near the cage goal, where the links crowd the bars and each other."""
    env, q0, goals = cage
    W, s = env.world_cover, env.scratch
    rs = np.random.default_rng(9)
    U = rs.uniform(env.robot.lower, env.robot.upper, (400, len(q0)))
    D = U - goals[0]
    near = goals[0] + rs.uniform(0.0, 0.5, (400, 1)) * D / np.linalg.norm(D, axis=1)[:, None]
    sr, gj, gs, smask, ssr = W[7], W[8], W[11], W[15], W[21]
    moving = np.repeat(gj != 0, np.diff(gs))  # spheres fixed to the base are not checked against obstacles
    I, J = np.nonzero(smask)
    below = 0
    for q in np.concatenate([U, near]):
        K.sphere_centres(q, W, s.T, s.C, s.G)
        C = s.C.copy()
        env_min = min((float(np.min(point_distances(int(t), p, C[moving])[0] - sr[moving]))
                       for t, p in zip(W[12], W[13])), default=np.inf)
        self_min = float(np.min(np.linalg.norm(C[I] - C[J], axis=1) - ssr[I] - ssr[J])) if len(I) else np.inf
        want = min(0.5, env_min, self_min)
        got = K.config_clearance(q, W, s.T, s.C, s.G, s.out, 0.5)
        assert got == pytest.approx(want, abs=1e-9)
        below += self_min < min(0.5, env_min)
    assert below > 0  # some configurations are decided by a self-collision pair


def test_a_search_with_no_way_out_stalls_and_says_so(cage):
    """With ``stall``, a search whose trees gain no node gives up after that many iterations (the planner then
    tries its other sphere model); without it, only the deadline ends the search."""
    env, q0, goals = cage
    st = MotionSettings(d_min=0.001, seed=3)
    far = clock_now() + 600.0  # never reached: the stall ends the search
    # a threshold no configuration keeps: every sample and every edge leaving a root is refused
    path, gi, why = search(env, q0, goals, st, 0.02, far, env.world_cover, env.world_cover, thr=10.0, stall=2048)
    assert path is None and gi == -1 and why.startswith("stalled") and "2048 iterations" in why
    path, gi, why = search(env, q0, goals, st, 0.02, clock_now() + 0.05, env.world_cover, env.world_cover, thr=10.0)
    assert path is None and "time budget" in why
    # a search that finds its way is not stopped by the planner's stall rule
    path, gi, why = search(env, q0, goals, st, 0.02, clock_now() + 60.0, env.world_cover, env.world_cover,
                           stall=FALLBACK_STALL)
    assert path is not None and why == ""
