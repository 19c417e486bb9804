"""Temporal optimization (7.7)-(7.9) by CFS: limits on a dense resample, shorter than fixed dt,
compared with TOPP-RA."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput, LimitViolation, NotFinite
from robointel.planning.clamped_spline import knot_ratios, knot_ratios_scipy, limit_stretch, spline_segment
from robointel.planning.qp import DenseQP
from robointel.planning.temporal import TemporalSettings, concatenate_segments, temporal_optimize
from robointel.planning.temporal_cfs import solve_tau
from robointel.planning.temporal_start import accel_ratio, feasible_uniform_dt, pass_start, step_bounds
from robointel.trajectory import Trajectory


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
    tr = res.trajectory
    assert isinstance(tr, Trajectory)
    dense = tr.resample(0.001)
    assert np.all(np.abs(dense.qd) <= VMAX * (1 + 1e-6))
    assert np.all(np.abs(dense.qdd) <= AMAX * (1 + 1e-6))
    np.testing.assert_allclose(dense.qd[[0, -1]], 0.0, atol=1e-9)  # stops at the waypoints
    assert res.duration < 19 * 15 / 95
    # passes through the input points (they are kept when up-sampling)
    q_at = tr.sample(tr.t)[0]
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
    tr = concatenate_segments([r.trajectory for r in (r1, r2)], [f"j{i}" for i in range(6)])
    assert tr.duration == pytest.approx(r1.duration + r2.duration)
    k = len(r1.trajectory.t) - 1
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
    dense = res.trajectory.resample(0.001)
    assert np.all(np.abs(dense.qd) <= VMAX * (1 + 1e-6)) and np.all(np.abs(dense.qdd) <= AMAX * (1 + 1e-6))
    assert res.cfs.feasible


# --- speed work: the forward/backward starting pass, the dedicated CFS loop, the compiled spline ---

def _segment_problem(n_pts=20):
    path = make_path(n_pts)
    dx = np.diff(path, axis=0)
    A = np.tile(AMAX, (len(dx) + 1, 1))
    return path, dx, A


def test_pass_start_is_feasible_and_near_optimal():
    path, dx, A = _segment_problem()
    N = len(dx)
    tau0 = pass_start(dx, VMAX, A)
    lb = step_bounds(dx, VMAX, A)
    assert np.all(tau0 >= lb) and accel_ratio(dx, tau0, A) <= 1.0
    h_u = feasible_uniform_dt(path, VMAX, AMAX)
    assert tau0.sum() < 0.8 * h_u * N  # far better than the uniform schedule
    res = solve_tau(dx, VMAX, A, np.ones(N), tau0, 1.0, 1.0, 1e-6, 50, DenseQP())
    assert res.feasible and tau0.sum() <= 1.1 * res.z.sum()  # within 10 % of the CFS optimum


def test_pass_start_with_uneven_steps_stays_feasible():
    path, dx, A = _segment_problem(8)  # a tiny last step after long ones (the linear model is poor)
    tau0 = pass_start(dx, VMAX, A)
    assert np.all(np.isfinite(tau0)) and accel_ratio(dx, tau0, A) <= 1.0
    assert tau0.max() <= feasible_uniform_dt(path, VMAX, AMAX) * (1 + 1e-6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dedicated_cfs_matches_general_cfs_and_every_iterate_is_feasible(seed):
    path, dx, A = _segment_problem()
    rng = np.random.default_rng(seed)
    A = A * rng.uniform(0.6, 1.0, A.shape)  # per-knot limits as in the refinement rounds
    N = len(dx)
    tau0 = pass_start(dx, VMAX, A)
    out = {}
    for solver in ("dedicated", "general"):
        st = TemporalSettings(solver=solver, ftol=0.0)  # stop on the step length only (same rule for both)
        out[solver] = solve_tau(dx, VMAX, A, np.ones(N), tau0, 1.0, 1.0, 1e-7, 60, DenseQP(), keep_iterates=True,
                                settings=st)
    d, g = out["dedicated"], out["general"]
    assert d.status == g.status == "converged"
    np.testing.assert_allclose(d.z, g.z, rtol=1e-5, atol=1e-7)
    lb = step_bounds(dx, VMAX, A)
    for z in d.iterates:  # every iterate meets (7.8) exactly and the bounds
        assert np.all(z >= lb - 1e-12) and accel_ratio(dx, z, A) <= 1.0 + 1e-9
    assert np.all(np.diff(d.costs) <= 1e-12)  # the cost never increases


def test_compiled_spline_ratios_match_scipy():
    path, dx, A = _segment_problem()
    rng = np.random.default_rng(3)
    for N in (1, 2, 7, 19):
        t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.02, 0.2, N))])
        y = rng.normal(size=(N + 1, 6))
        ra, rv = knot_ratios(t, y, VMAX, AMAX)
        ra_s, rv_s = knot_ratios_scipy(t, y, VMAX, AMAX)
        np.testing.assert_allclose(ra, ra_s, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(rv, rv_s, rtol=1e-9, atol=1e-12)


def test_short_and_two_point_segments():
    for n_pts in (2, 3):
        path = make_path(n_pts)
        res = temporal_optimize(path, VMAX, AMAX)
        dense = res.trajectory.resample(0.001)
        assert np.all(np.abs(dense.qd) <= VMAX * (1 + 1e-6)) and np.all(np.abs(dense.qdd) <= AMAX * (1 + 1e-6))


def test_output_is_scipys_clamped_spline_and_limit_stretch():
    path = make_path()
    res = temporal_optimize(path, VMAX, AMAX)
    t0 = np.concatenate([[0.0], np.cumsum(res.tau)])
    s = limit_stretch(spline_segment(t0, path), t0[-1], VMAX, AMAX)
    assert res.stretch == pytest.approx(s, rel=1e-9)
    tr = res.trajectory
    np.testing.assert_allclose(tr.t, t0 * s, rtol=1e-12)
    sp = spline_segment(tr.t, path)
    np.testing.assert_allclose(tr.qd, sp(tr.t, 1), atol=1e-9)
    np.testing.assert_allclose(tr.qdd, sp(tr.t, 2), atol=1e-8)


def test_working_set_gives_the_full_qp_solutions():
    path, dx, A = _segment_problem()
    N = len(dx)
    tau0 = pass_start(dx, VMAX, A)
    out = []
    for ws in (0.0, 0.5):
        out.append(solve_tau(dx, VMAX, A, np.ones(N), tau0, 1.0, 1.0, 1e-7, 60, DenseQP(), keep_iterates=True,
                             settings=TemporalSettings(working_set=ws)))
    assert out[0].iterations == out[1].iterations
    for a, b in zip(out[0].iterates, out[1].iterates):
        np.testing.assert_allclose(a, b, rtol=1e-7, atol=1e-10)


@pytest.mark.parametrize("st", [TemporalSettings(start="scaled"), TemporalSettings(start="uniform"),
                                TemporalSettings(refine_mode="tighten"), TemporalSettings(refine_mode="both"),
                                TemporalSettings(solver="general"), TemporalSettings(local_ub=2.0)])
def test_settings_variants_meet_limits(st):
    path = make_path()
    res = temporal_optimize(path, VMAX, AMAX, settings=st)
    dense = res.trajectory.resample(0.001)
    assert np.all(np.abs(dense.qd) <= VMAX * (1 + 1e-6)) and np.all(np.abs(dense.qdd) <= AMAX * (1 + 1e-6))
    assert res.cfs.feasible


def test_bad_settings():
    with pytest.raises(InvalidInput):
        TemporalSettings(solver="fast")
    with pytest.raises(InvalidInput):
        TemporalSettings(ub_factor=0.5)
