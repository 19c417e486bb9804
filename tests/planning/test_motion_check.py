"""The dense check's compiled limit pass agrees with the plain numpy expressions."""
from __future__ import annotations

import numpy as np

from robointel.planning.motion_check import _limit_ratios


def test_limit_pass_matches_numpy():
    rng = np.random.default_rng(4)
    vmax, amax = rng.uniform(0.5, 2.0, 6), rng.uniform(1.0, 4.0, 6)
    Q, QD, QDD = (rng.normal(0.0, 1.0, (500, 6)) for _ in range(3))
    lo, hi = np.full(6, -2.5), np.full(6, 2.5)
    Q = np.clip(Q, -2.4, 2.4)
    Q[[37, 300], 2] = 2.6  # out of limits from sample 37 on
    first, rv, ra = _limit_ratios(Q, QD, QDD, lo, hi, vmax, amax)
    assert first == int(np.flatnonzero(np.any(Q < lo - 1e-9, 1) | np.any(Q > hi + 1e-9, 1))[0]) == 37
    np.testing.assert_array_equal(rv, np.max(np.abs(QD) / vmax, axis=0))
    np.testing.assert_array_equal(ra, np.max(np.abs(QDD) / amax, axis=0))
    assert _limit_ratios(np.clip(Q, -2.0, 2.0), QD, QDD, lo, hi, vmax, amax)[0] == -1
