"""The shortcut's one-pass edge checks keep the walk's guarantee; the root split's fractions."""
from __future__ import annotations

import numpy as np

from robointel.planning import _collision_kernels as K
from robointel.planning import _edge_kernels as E
from robointel.planning import _shortcut_kernels as S


def test_edge_fine_keeps_the_walks_guarantee(thin70, dense_min):
    p, env = thin70
    env.use("fitted")  # edges leaving the goal among the shelves, in the spheres it is free in
    W, s, robot = env.world, env.scratch, env.robot
    thr, res, gap = 0.0, 0.002, 0.004
    rng = np.random.default_rng(11)
    q0 = np.asarray(p.goals[0], float)
    assert K.config_valid(q0, W, s.T, s.C, s.G, s.out, thr)
    accepted = refused = 0
    for _ in range(80):
        d = rng.normal(0.0, 1.0, 6)
        q1 = np.clip(q0 + d * rng.uniform(0.2, 1.5) / np.abs(d).max(), robot.lower, robot.upper)
        ok = S.edge_fine(q0, q1, W, s.T, s.C, s.G, s.out, thr, env.lever, res)
        dmin = dense_min(env, W, q0, q1, gap)
        if ok:  # accepted: the guarantee on dense samples
            accepted += 1
            assert dmin >= thr - res / 2 - 1e-9
        else:  # refused: a point below thr exists (dense samples come within the gap of it)
            refused += 1
            assert dmin < thr + gap
    env.use("cover")
    assert accepted >= 5 and refused >= 5


def test_root_edge_fine_relaxed_only_near_the_root(thin70, dense_min):
    p, env = thin70
    env.use("fitted")
    Wr, W, s, robot = env.world, env.world_cover, env.scratch, env.robot
    thr, res, cap = 0.0, 0.002, 0.2
    q0 = np.asarray(p.goals[0], float)
    rng = np.random.default_rng(3)
    left = 0
    for _ in range(90):
        d = rng.normal(0.0, 1.0, 6)
        d *= rng.uniform(0.3, 1.2) / np.abs(d).max()
        q1 = np.clip(q0 + d, robot.lower, robot.upper)
        if not K.config_valid(q1, W, s.T, s.C, s.G, s.out, thr):
            continue
        if S.root_edge_fine(q0, q1, Wr, W, True, False, cap, s.T, s.C, s.G, s.out, thr, env.lever, res):
            left += 1
            f = cap / np.abs(q1 - q0).max()
            qa = q0 + min(f, 1.0) * (q1 - q0)
            assert dense_min(env, Wr, q0, qa) >= thr - res / 2 - 1e-9  # relaxed within the cap
            assert f >= 1.0 or dense_min(env, W, qa, q1) >= thr - res / 2 - 1e-9  # covering beyond
    env.use("cover")
    assert left >= 3


def test_root_split_fractions():
    q0, q1 = np.zeros(3), np.array([0.0, 1.0, -0.5])
    L, a, b, qa, qb = E.root_split(q0, q1, True, True, 0.25)
    assert (L, a, b) == (1.0, 0.25, 0.75)
    np.testing.assert_allclose(qa, [0.0, 0.25, -0.125])
    np.testing.assert_allclose(qb, [0.0, 0.75, -0.375])
    assert E.root_split(q0, q1, False, True, 0.25)[1:3] == (0.0, 0.75)
    assert E.root_split(q0, q1, True, True, 0.6)[1:3] == (0.6, 0.4)  # a >= b: within the cap everywhere
    assert E.root_split(q0, q0, True, False, 0.2)[0] == 0.0
