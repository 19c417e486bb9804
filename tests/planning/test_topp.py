"""topp_spline: limits at every sample and between them, rest to rest, the path kept, and a duration
no longer than TOPP-RA's (toppra, the peers extra; limits held between its grid points too, as ours) on the
same polyline and limits."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from robointel.errors import InvalidInput
from robointel.planning.topp import densify, natural_spline, topp_spline

VMAX = np.array([0.5, 0.5, 0.5, 0.8, 0.8, 1.0])
AMAX = np.array([1.5, 1.5, 1.5, 3.0, 3.0, 4.0])


def _path(seed: int) -> np.ndarray:
    return np.cumsum(np.random.default_rng(seed).uniform(-1.0, 1.0, (5, 6)), axis=0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_limits_hold_on_the_samples_and_between_them(seed):
    P = _path(seed)
    tr = topp_spline(P, VMAX, AMAX, dt=1e-3)
    assert np.max(np.diff(tr.t)) <= 1e-3 * (1 + 1e-9)
    np.testing.assert_allclose(tr.q[0], P[0], atol=1e-12)
    np.testing.assert_allclose(tr.q[-1], P[-1], atol=1e-12)
    assert np.abs(tr.qd[[0, -1]]).max() < 1e-9
    assert np.max(np.abs(tr.qd) / VMAX) <= 1 + 1e-9
    assert np.max(np.abs(tr.qdd) / AMAX) <= 1 + 1e-9
    # a cubic Hermite through (t, q, qd), evaluated on another 0.25 ms grid, keeps the limits too
    sp = CubicHermiteSpline(tr.t, tr.q, tr.qd, axis=0)
    ts = np.linspace(0.0, tr.t[-1], 4 * len(tr.t))
    assert np.max(np.abs(sp(ts, 1)) / VMAX) <= 1 + 1e-4
    assert np.max(np.abs(sp(ts, 2)) / AMAX) <= 1 + 1e-3
    # qd is the derivative of q (central differences away from the acceleration switches)
    mid = (tr.q[2:] - tr.q[:-2]) / (tr.t[2:] - tr.t[:-2])[:, None]
    assert np.median(np.abs(mid - tr.qd[1:-1])) < 1e-4


def test_the_spline_stays_near_the_polyline():
    P = _path(3)
    tr = topp_spline(P, VMAX, AMAX, step=0.05)
    D = densify(P, 0.005)  # the polyline, finely sampled
    far = max(float(np.min(np.linalg.norm(D - q, axis=1))) for q in tr.q[::50])
    assert far < 0.05  # rad, at the corners only


@pytest.mark.parametrize("seed", [4, 5])
def test_no_slower_than_toppra_on_the_same_polyline(seed):
    toppra = pytest.importorskip("toppra")
    import toppra.algorithm as algo
    import toppra.constraint as constraint

    P = densify(_path(seed), 0.1)
    ss = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    spline = toppra.SplineInterpolator(ss / ss[-1], P, bc_type="natural")
    inst = algo.TOPPRA([constraint.JointVelocityConstraint(np.stack([-VMAX, VMAX], 1)),
                        constraint.JointAccelerationConstraint(
                            np.stack([-AMAX, AMAX], 1),
                            discretization_scheme=constraint.DiscretizationType.Interpolation)], spline,
                       parametrizer="ParametrizeConstAccel", gridpoints=np.linspace(0, 1, 1000))
    peer = inst.compute_trajectory(0, 0).duration
    ours = topp_spline(P, VMAX, AMAX, step=0.1).duration
    assert ours <= peer * 1.005, (ours, peer)


def test_bad_input():
    with pytest.raises(InvalidInput):
        topp_spline(np.zeros((1, 6)), VMAX, AMAX)
    with pytest.raises(InvalidInput):
        topp_spline(_path(0), -VMAX, AMAX)
    with pytest.raises(InvalidInput):
        topp_spline(np.zeros((3, 6)), VMAX, AMAX)  # no length
    with pytest.raises(InvalidInput):
        topp_spline(_path(0), VMAX, AMAX[:3])


@pytest.mark.parametrize("k", [2, 3, 40])
def test_natural_spline_matches_scipy(k):
    rng = np.random.default_rng(k)
    x = np.concatenate([[0.0], np.cumsum(rng.uniform(0.01, 0.2, k - 1))])
    y = rng.normal(0.0, 1.0, (k, 6))
    c = natural_spline(x, y)
    np.testing.assert_allclose(c, CubicSpline(x, y, bc_type="natural").c, rtol=1e-9, atol=1e-9)
