"""The batched collision checks agree with the scalar kernels lane by lane; batched edges keep the walk's guarantee."""
from __future__ import annotations

import numpy as np

from robointel.planning import _batch_edges as BE
from robointel.planning import _batch_kernels as BK
from robointel.planning import _collision_kernels as K
from robointel.planning.tree_search import batch_state


def _load(BS, Q):
    Qt = BS[1][0]
    Qt[:, :len(Q)] = Q.T
    return len(Q)


def test_batch_clearance_and_verdicts_match_the_scalar_kernels(thin70):
    p, env = thin70
    W, s, robot = env.world, env.scratch, env.robot
    BS = batch_state(env)
    rng = np.random.default_rng(5)
    g = np.asarray(p.goals[0], float)  # near the shelves: many lanes close to contact
    Q = np.vstack([robot.random_configuration(rng, 48),
                   np.clip(g + rng.normal(0.0, 0.15, (48, robot.nq)), robot.lower, robot.upper)])
    free = np.array([K.config_valid(q, W, s.T, s.C, s.G, s.out, 0.01) for q in Q])
    Q = np.vstack([Q, Q[free]])  # batches of free configurations too
    best = np.empty(BK.LANES)
    free_lanes = hit_lanes = 0
    for r0 in range(0, len(Q), 13):  # batches of 13: lanes past B repeat lane B - 1
        chunk = Q[r0:r0 + 13]
        B = _load(BS, chunk)
        BK.batch_clearance(B, W, BS[0], BS[1], 0.3, best)
        ref = np.array([K.config_clearance(q, W, s.T, s.C, s.G, s.out, 0.3) for q in chunk])
        np.testing.assert_allclose(best[:B], ref, rtol=0, atol=1e-12)
        for thr in (0.0, 0.01):
            valid = np.array([K.config_valid(q, W, s.T, s.C, s.G, s.out, thr) for q in chunk])
            B = _load(BS, chunk)
            lane = BK.batch_free(B, W, BS[0], BS[1], thr, s.out)
            if valid.all():
                assert lane == -1
                free_lanes += B
            else:  # the lane named is one the scalar check refuses
                assert 0 <= lane < B and not valid[lane]
                hit_lanes += 1
    assert free_lanes > 0 and hit_lanes > 0


def test_batch_clearance_follows_the_self_collision_offset(thin70):
    """The clusters' radii come from the world's current self-collision radii (the planner shifts them per plan)."""
    p, env = thin70
    s, robot = env.scratch, env.robot
    BS = batch_state(env)
    Q = robot.random_configuration(np.random.default_rng(2), 16)
    best = np.empty(BK.LANES)
    try:
        for d_min in (0.0, 0.02, -0.03):
            env.set_self_offset(d_min)
            W = env.world
            B = _load(BS, Q)
            BK.batch_clearance(B, W, BS[0], BS[1], 0.5, best)
            ref = [K.config_clearance(q, W, s.T, s.C, s.G, s.out, 0.5) for q in Q]
            np.testing.assert_allclose(best[:B], ref, rtol=0, atol=1e-12)
    finally:
        env.set_self_offset(0.0)


def test_edge_batch_keeps_the_walks_guarantee(thin70, dense_min):
    p, env = thin70
    env.use("fitted")  # edges leaving the goal among the shelves, in the spheres it is free in
    W, s, robot = env.world, env.scratch, env.robot
    BS = batch_state(env)
    thr, res, gap = 0.0, 0.002, 0.004
    rng = np.random.default_rng(11)
    q0 = np.asarray(p.goals[0], float)
    accepted = refused = 0
    try:
        for _ in range(60):
            d = rng.normal(0.0, 1.0, robot.nq)
            q1 = np.clip(q0 + d * rng.uniform(0.2, 1.5) / np.abs(d).max(), robot.lower, robot.upper)
            ok = BE.edge_batch(q0, q1, W, BS, thr, res, s.out)
            dmin = dense_min(env, W, q0, q1, gap)
            if ok:  # accepted: the guarantee on dense samples, and the end itself keeps thr
                accepted += 1
                assert dmin >= thr - res / 2 - 1e-9
                assert K.config_clearance(q1, W, s.T, s.C, s.G, s.out, 1.0) >= thr - BK.TOL
            else:  # refused: a point below thr exists (dense samples come within the gap of it)
                refused += 1
                assert dmin < thr + gap
    finally:
        env.use("cover")
    assert accepted >= 5 and refused >= 5
