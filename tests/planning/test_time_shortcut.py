"""The time-metric shortcut: its estimate, its partial shortcut, and a result that keeps every edge valid."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.planning import _collision_kernels as K
from robointel.planning import _edge_kernels as E
from robointel.planning import _rrt_kernels as R
from robointel.planning import _time_shortcut as TS
from robointel.planning.tree_search import batch_state


def test_time_length_and_chain_time():
    w, ia = np.array([2.0, 1.0]), np.array([1.0, 0.5])
    A = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 3.0]])
    L = np.empty(3)
    assert TS.time_length(A, 3, w, L) == pytest.approx(5.0)  # max(2 * 1, 0) + max(0, 1 * 3)
    np.testing.assert_allclose(L, [0.0, 2.0, 5.0])
    assert TS.chain_time(A, 3, w, ia, 0.0) == pytest.approx(5.0)
    # the corner: velocity (0.5, 0) -> (0, 1) per s of time length; largest change / amax: joint 1, 1 * 0.5
    assert TS.chain_time(A, 3, w, ia, 0.5) == pytest.approx(5.0 + 0.5 * 0.5)
    straight = np.array([[0.0, 0.0], [0.5, 1.5], [1.0, 3.0]])
    assert TS.chain_time(straight, 3, w, ia, 0.5) == pytest.approx(3.0)  # no corner, max(2, 3)


def test_partial_moves_only_the_joint_that_saves_time():
    # joint 0 swings out and back (and sets each segment's time), joint 1 moves steadily: only joint 0
    # should become straight; a joint that does not set any segment's time saves nothing
    P = np.array([[0.0, 0.0], [2.0, 1.0], [0.0, 2.0], [2.0, 3.0], [0.0, 4.0]])
    w = np.ones(2)
    L = np.empty(5)
    TS.time_length(P, 5, w, L)
    qa, qb = P[0] + 0.5 * (P[1] - P[0]), P[3] + 0.5 * (P[4] - P[3])
    u1, u2 = 0.5 * L[1], L[3] + 0.5 * (L[4] - L[3])
    V = np.empty((8, 2))
    saved = TS._partial(P, L, 0, 3, u1, u2, qa, qb, w, V)
    assert saved > 0.0
    np.testing.assert_array_equal(V[0], qa)
    np.testing.assert_array_equal(V[4], qb)
    np.testing.assert_allclose(V[1:4, 1], P[1:4, 1])  # joint 1 kept
    np.testing.assert_allclose(V[1:4, 0], 1.0)  # joint 0 on the line qa_0 = 1 -> qb_0 = 1
    new = sum(max(np.abs(b - a)) for a, b in zip(V[:4], V[1:5]))
    old = sum(max(np.abs(b - a)) for a, b in zip(np.vstack([qa, P[1:4]]), np.vstack([P[1:4], qb])))
    assert saved == pytest.approx(old - new) and saved == pytest.approx(3.0)  # 1 + 2 + 2 + 1 -> 0.5 + 1 + 1 + 0.5
    flat = np.array([[0.0, 0.0], [1.0, 1.0], [0.0, 2.0], [1.0, 3.0], [0.0, 4.0]])  # joint 1 sets every time
    TS.time_length(flat, 5, w, L)
    qa, qb = 0.5 * (flat[0] + flat[1]), 0.5 * (flat[3] + flat[4])
    assert TS._partial(flat, L, 0, 3, 0.5 * L[1], 0.5 * (L[3] + L[4]), qa, qb, w, V) == 0.0


def _zigzag(env, start, seed, k, step):
    """k configurations from ``start``, random steps, each edge valid in the covering spheres."""
    W, s, robot = env.world_cover, env.scratch, env.robot
    rng = np.random.default_rng(seed)
    pts = [np.asarray(start, float)]
    while len(pts) < k:  # a zig-zag through free configurations, each edge valid
        q = np.clip(pts[-1] + rng.normal(0.0, step, 6), robot.lower, robot.upper)
        if E.edge_valid(pts[-1], q, W, s.T, s.C, s.G, s.out, 0.0, env.lever, 0.002) and \
                K.config_valid(q, W, s.T, s.C, s.G, s.out, 0.0):
            pts.append(q)
    return np.array(pts)


def test_shortcut_time_shortens_keeps_edges_valid_and_is_deterministic(thin70, dense_min):
    p, env = thin70
    W, s, robot = env.world_cover, env.scratch, env.robot
    thr, res = 0.0, 0.002
    path = _zigzag(env, p.start, 5, 10, 0.2)
    w = 1.0 / np.asarray(robot.velocity_limit, float)
    ia = 1.0 / np.asarray(robot.acceleration_limit, float)

    def run(seed):
        P = np.empty((256, 6))
        P[:len(path)] = path
        R.seed(seed)
        m = TS.shortcut_time(P, len(path), 40, W, W, np.inf, batch_state(env), s.out, thr, env.lever, res, w, ia)
        return P[:m].copy()

    out = run(3)
    np.testing.assert_array_equal(out[0], path[0])
    np.testing.assert_array_equal(out[-1], path[-1])
    L = np.empty(256)
    assert TS.time_length(out, len(out), w, L) < TS.time_length(path, len(path), w, L)
    assert TS.chain_time(out, len(out), w, ia, TS.CORNER_WEIGHT) < TS.chain_time(path, len(path), w, ia,
                                                                                    TS.CORNER_WEIGHT)
    for a, b in zip(out[:-1], out[1:]):
        assert dense_min(env, W, a, b) >= thr - res / 2 - 1e-9
    np.testing.assert_array_equal(run(3), out)  # the same seed, the same path
