"""CFS trajectory planning (7.1)-(7.3) on the LR Mate, against SLSQP; collision and limit checks."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import CollisionAtStart, LimitViolation, NotFinite
from robointel.geometry import Box, Sphere, sphere_distances_batch
from robointel.planning.sqp import slsqp_segment
from robointel.planning.waypoints import PlannerSettings, TrajectoryPlanner

START = np.radians([40, 20, -10, 0, -60, 0.0])
GOAL = np.radians([-40, 20, -10, 0, -60, 0.0])


@pytest.fixture(scope="module")
def box():
    return [Box([0.55, 0.0, 0.35], [0.15, 0.3, 0.3], name="box")]


def dense_clearance(robot, X, obstacles, per=25):
    """Min distance on the joint-space polyline through the knots, `per` samples per interval."""
    s = np.linspace(0, 1, per, endpoint=False)[:, None]
    Q = np.concatenate([(1 - s) * X[i] + s * X[i + 1] for i in range(len(X) - 1)] + [X[-1:]])
    return float(sphere_distances_batch(robot, Q, obstacles, movable_only=True).d.min())


def test_free_segment_is_the_straight_line(lrmate):
    pl = TrajectoryPlanner(lrmate, [], N=10, dt=0.1)
    res = pl.plan_segment(START, GOAL)
    assert res.status == "converged" and res.iterations <= 2 and not res.blocked
    np.testing.assert_allclose(res.path, np.linspace(START, GOAL, 11), atol=1e-4)


def test_blocked_segment_clears_obstacle_and_limits(lrmate, box):
    pl = TrajectoryPlanner(lrmate, box, N=19, dt=15 / 95)
    res = pl.plan_segment(START, GOAL, keep_iterates=True)
    assert res.blocked and res.feasible and res.status == "converged"
    st = pl.settings
    assert res.min_distance >= st.d_min - 1e-9
    assert dense_clearance(lrmate, res.path, box) >= st.d_min - 1e-3
    X = res.path
    assert np.all(X >= lrmate.lower - 1e-6) and np.all(X <= lrmate.upper + 1e-6)
    assert np.all(np.abs(np.diff(X, axis=0)) <= pl.vmax * pl.dt + 1e-5)
    assert np.all(np.abs(np.diff(X, 2, axis=0)) <= pl.amax * pl.dt ** 2 + 1e-5)
    np.testing.assert_allclose(X[0], START)
    np.testing.assert_allclose(X[-1], GOAL)
    # once an iterate is feasible, every later iterate is feasible (CFS keeps the feasible set)
    feas = [pl.distances(Xk).d.min() >= st.d_min - 1e-9 for Xk in res.iterates]
    first = feas.index(True)
    assert all(feas[first:])


def test_cfs_matches_slsqp_optimum(lrmate):
    obs = [Sphere([0.6, 0.0, 0.45], 0.12, name="ball")]
    pl = TrajectoryPlanner(lrmate, obs, N=8, dt=0.3, settings=PlannerSettings(eps=1e-5, max_iter=60))
    res = pl.plan_segment(START, GOAL)
    X, sq = slsqp_segment(pl, START, GOAL, tol=1e-10)
    Xr = np.linspace(START, GOAL, 9)
    assert res.blocked and res.feasible
    assert sq.success
    c_cfs, c_sqp = pl._cost(res.path, Xr), pl._cost(X, Xr)
    assert c_cfs == pytest.approx(c_sqp, rel=0.02)
    np.testing.assert_allclose(res.path, X, atol=0.03)


def test_waypoint_in_collision_names_link_and_obstacle(lrmate, box):
    pl = TrajectoryPlanner(lrmate, box, N=10, dt=0.1)
    inside = np.radians([0, 20, -10, 0, -60, 0.0])
    with pytest.raises(CollisionAtStart) as e:
        pl.check_waypoints(np.array([START, inside]))
    assert "box" in str(e.value) and "link" in str(e.value) and "waypoint 1" in str(e.value)


def test_bad_waypoints_and_nan(lrmate, box):
    pl = TrajectoryPlanner(lrmate, box, N=10, dt=0.1)
    bad = START.copy()
    bad[1] = 3.0
    with pytest.raises(LimitViolation):
        pl.check_waypoints(np.array([START, bad]))
    with pytest.raises(NotFinite):
        pl.plan_segment(np.full(6, np.nan), GOAL)


def test_capped_cfs_returns_best_feasible_with_status(lrmate, box):
    pl = TrajectoryPlanner(lrmate, box, N=19, dt=15 / 95, settings=PlannerSettings(max_iter=4))
    res = pl.plan_segment(START, GOAL, keep_iterates=True)
    assert res.status == "max_iter"
    feas = [(pl._cost(X, np.linspace(START, GOAL, 20)), X) for X in res.iterates
            if pl.distances(X).d.min() >= pl.settings.d_min - 1e-9]
    assert res.feasible and feas
    best = min(feas, key=lambda c: c[0])
    np.testing.assert_allclose(res.path, best[1])


def test_impossible_limits_raise_with_reason(lrmate):
    from robointel.errors import InfeasibleProblem

    pl = TrajectoryPlanner(lrmate, [], N=5, dt=0.01)
    with pytest.raises(InfeasibleProblem, match="impossible limits: joint_1"):
        pl.plan_segment(START, GOAL)
