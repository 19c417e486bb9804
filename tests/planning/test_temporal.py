"""Temporal optimization (7.7)-(7.9) by CFS: limits on a dense resample, shorter than fixed dt,
compared with TOPP-RA."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput, LimitViolation, NotFinite
from robointel.io.trajectory import Trajectory
from robointel.planning.temporal import concatenate_segments, temporal_optimize


def make_path(n_pts=20):
    a = np.array([0.2, -0.3, 0.1, 0.5, -0.4, 0.3])
    b = np.array([1.5, 0.4, -0.5, -0.5, 0.6, 1.8])
    s = np.linspace(0, 1, n_pts)[:, None]
    return a + (b - a) * (3 * s ** 2 - 2 * s ** 3) + 0.1 * np.sin(np.pi * s)


VMAX = np.array([3.2, 2.7, 3.6, 4.8, 4.8, 8.7])
AMAX = 3 * VMAX


def test_retimed_segment_meets_limits_densely_and_is_faster():
    path = make_path()
    res = temporal_optimize(path, VMAX, AMAX, dt=15 / 95)
    assert res.cfs.feasible
    tr = Trajectory(res.t, res.q, res.qd, res.qdd)
    dense = tr.resample(0.001)
    assert np.all(np.abs(dense.qd) <= VMAX * (1 + 1e-6))
    assert np.all(np.abs(dense.qdd) <= AMAX * (1 + 1e-6))
    np.testing.assert_allclose(dense.qd[[0, -1]], 0.0, atol=1e-9)  # stops at the waypoints
    assert res.duration < 19 * 15 / 95
    # passes through the input points (they are kept when up-sampling)
    q_at = tr.sample(res.t)[0]
    np.testing.assert_allclose(q_at, path, atol=1e-9)


def test_close_to_toppra():
    toppra = pytest.importorskip("toppra")
    import toppra.algorithm as algo
    import toppra.constraint as constraint

    path = make_path()
    res = temporal_optimize(path, VMAX, AMAX)
    p = toppra.SplineInterpolator(np.linspace(0, 1, len(path)), path)
    inst = algo.TOPPRA([constraint.JointVelocityConstraint(np.stack([-VMAX, VMAX], 1)),
                        constraint.JointAccelerationConstraint(np.stack([-AMAX, AMAX], 1))], p,
                       parametrizer="ParametrizeConstAccel", gridpoints=np.linspace(0, 1, 400))
    ref = inst.compute_trajectory(0, 0).duration
    assert ref <= res.duration <= 1.08 * ref  # time-optimal TOPP-RA is a lower bound up to discretisation


def test_concatenate_segments_stops_at_waypoints():
    p1, p2 = make_path(8), make_path(8)[::-1]
    r1, r2 = temporal_optimize(p1, VMAX, AMAX), temporal_optimize(p2, VMAX, AMAX)
    tr = concatenate_segments([(r.t, r.q, r.qd, r.qdd) for r in (r1, r2)], [f"j{i}" for i in range(6)])
    assert tr.duration == pytest.approx(r1.duration + r2.duration)
    k = len(r1.t) - 1
    np.testing.assert_allclose(tr.qd[k], 0.0, atol=1e-9)


def test_bad_input():
    path = make_path()
    with pytest.raises(LimitViolation):
        temporal_optimize(path, VMAX * 0, AMAX)
    bad = path.copy()
    bad[3, 2] = np.nan
    with pytest.raises(NotFinite):
        temporal_optimize(bad, VMAX, AMAX)
    with pytest.raises(InvalidInput):
        temporal_optimize(path[:1], VMAX, AMAX)


@pytest.mark.parametrize("kw", [{"upsample": 2}, {"trust": 0.3}, {"refine": 0}])
def test_variants_meet_limits(kw):
    path = make_path()
    res = temporal_optimize(path, VMAX, AMAX, **kw)
    dense = Trajectory(res.t, res.q, res.qd, res.qdd).resample(0.001)
    assert np.all(np.abs(dense.qd) <= VMAX * (1 + 1e-6)) and np.all(np.abs(dense.qdd) <= AMAX * (1 + 1e-6))
    assert res.cfs.feasible
