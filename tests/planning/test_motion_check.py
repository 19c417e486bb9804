"""The dense check's compiled passes: the limits as the plain numpy expressions, the two-sided skip exact."""
from __future__ import annotations

import numpy as np

from robointel.planning import _collision_kernels as K
from robointel.planning import _dense_kernels as D


def test_limit_pass_matches_numpy():
    rng = np.random.default_rng(4)
    vmax, amax = rng.uniform(0.5, 2.0, 6), rng.uniform(1.0, 4.0, 6)
    Q, QD, QDD = (rng.normal(0.0, 1.0, (500, 6)) for _ in range(3))
    lo, hi = np.full(6, -2.5), np.full(6, 2.5)
    Q = np.clip(Q, -2.4, 2.4)
    Q[[37, 300], 2] = 2.6  # out of limits from sample 37 on
    V = np.empty(Q.shape)
    first, rv, ra = D.limits_travel(Q, QD, QDD, lo, hi, vmax, amax, V)
    assert first == int(np.flatnonzero(np.any(Q < lo - 1e-9, 1) | np.any(Q > hi + 1e-9, 1))[0]) == 37
    np.testing.assert_array_equal(rv, np.max(np.abs(QD) / vmax, axis=0))
    np.testing.assert_array_equal(ra, np.max(np.abs(QDD) / amax, axis=0))
    np.testing.assert_allclose(V, np.concatenate([np.zeros((1, 6)), np.cumsum(np.abs(np.diff(Q, axis=0)), axis=0)]),
                               rtol=1e-12, atol=1e-12)
    assert D.limits_travel(np.clip(Q, -2.0, 2.0), QD, QDD, lo, hi, vmax, amax, V)[0] == -1


def test_two_sided_skip_is_exact_below_the_floor(thin70):
    """On a motion grazing the shelves, the skipped samples are proven: verdicts and minima below the floor exact."""
    p, env = thin70
    W, s = env.world_cover, env.scratch
    rng = np.random.default_rng(5)
    g = np.asarray(p.goals[0], float)
    for _ in range(4):  # smooth motions through and around the goal, 1 ms apart at ~0.5 rad/s
        a, b = g + rng.normal(0.0, 0.3, 6), g + rng.normal(0.0, 0.3, 6)
        u = np.linspace(0.0, 1.0, 3000)[:, None]
        Q = np.ascontiguousarray((1 - u) ** 2 * a + 2 * u * (1 - u) * g + u ** 2 * b)
        full = np.array([K.config_clearance(q, W, s.T, s.C, s.G, s.out, 0.2) for q in Q])
        V = np.empty(Q.shape)
        z = np.zeros_like(Q)
        D.limits_travel(Q, z, z, env.robot.lower, env.robot.upper, np.ones(6), np.ones(6), V)
        for floor in (full.min() - 0.002, full.min() + 0.002, 0.01, float(np.median(full))):
            d, w, n = D.span_clearance(Q, V, 0, len(Q), W, s.T, s.C, s.G, s.out, env.lever, floor, 0.2, 0.2)
            assert d >= full.min() - 1e-12 and (w < 0 or abs(full[w] - d) < 1e-12)
            assert (d < floor) == (full.min() < floor)
            if d < floor:
                assert abs(d - full.min()) < 1e-12  # the minimum itself, when the check fails
            assert n < len(Q)
        # a stretch: the result over [lo, hi) only, starting from a given best
        d, w, _ = D.span_clearance(Q, V, 1000, 2000, W, s.T, s.C, s.G, s.out, env.lever, 1.0, 0.2, 0.2)
        assert abs(d - full[1000:2000].min()) < 1e-12 and 1000 <= w < 2000


def test_env_below_is_the_exact_mask(thin70):
    """The two-sided doubt mask of the mesh check equals the one-sided kernel's (the exact one)."""
    p, env = thin70
    W, s = env.world_cover, env.scratch
    rng = np.random.default_rng(6)
    g = np.asarray(p.goals[0], float)
    for _ in range(4):
        a, b = g + rng.normal(0.0, 0.3, 6), g + rng.normal(0.0, 0.3, 6)
        u = np.linspace(0.0, 1.0, 2000)[:, None]
        Q = np.ascontiguousarray((1 - u) ** 2 * a + 2 * u * (1 - u) * g + u ** 2 * b)
        V = np.empty(Q.shape)
        z = np.zeros_like(Q)
        D.limits_travel(Q, z, z, env.robot.lower, env.robot.upper, np.ones(6), np.ones(6), V)
        W2 = np.empty(Q.shape)
        D.variation(Q, W2)
        np.testing.assert_array_equal(W2, V)
        for thr in (0.0, 0.01, 0.05):
            old = K.samples_env_below(Q, W, s.T, s.C, s.G, s.out, env.lever, thr)
            np.testing.assert_array_equal(D.env_below(Q, V, W, s.T, s.C, s.G, s.out, env.lever, thr), old)
