"""CFS keeps the arm clear of itself: self-collision pairs are constraints of the segment QP (planning/segment.py)."""
import numpy as np
import pytest

from robointel.errors import CollisionAtStart
from robointel.planning.segment import PlannerSettings, self_clearances
from robointel.planning.waypoints import TrajectoryPlanner
from robointel.robot import Robot

# two configurations of the MotionBenchMaker UR5 clear of itself, the straight line between them through itself
A = np.radians([-76.6032, -138.3858, 37.5092, -160.0803, -11.6969, 43.1939])
B = np.radians([-5.8232, -179.9427, 75.2857, -179.9427, -57.8208, -10.4591])


@pytest.fixture(scope="module")
def ur5(shared_data):
    return Robot.load(shared_data("mbm", "ur5", "ur5.urdf"))


def test_pair_clearances_and_gradients_match_the_sphere_model(lrmate):
    Q = np.random.default_rng(0).uniform(0.5 * lrmate.lower, 0.5 * lrmate.upper, (5, 6))
    d, g = self_clearances(lrmate, Q)
    sm = lrmate.spheres
    np.testing.assert_allclose(d[2], sm.self_distances(Q[2]), atol=1e-12)
    e = 1e-6
    fd = np.array([(sm.self_distances(Q[3] + e * u) - sm.self_distances(Q[3] - e * u)) / (2 * e) for u in np.eye(6)]).T
    np.testing.assert_allclose(g[3], fd, atol=1e-7)


def test_cfs_bends_a_self_colliding_line_clear(ur5):
    s = np.linspace(0.0, 1.0, 200)[:, None]
    assert self_clearances(ur5, A + s * (B - A))[0].min() < -0.002  # the reference goes through the arm
    pl = TrajectoryPlanner(ur5, (), N=40, dt=0.15, settings=PlannerSettings(d_min=0.02))
    plan = pl.plan_segment(A, B)
    assert plan.feasible and plan.blocked
    X = plan.path
    dense = np.concatenate([X[k] + s[:20] * (X[k + 1] - X[k]) for k in range(len(X) - 1)])
    assert self_clearances(ur5, dense)[0].min() > -1e-3  # clear between the knots too (1 mm: linearisation)
    off = PlannerSettings(d_min=0.02, self_collision=False)
    assert TrajectoryPlanner(ur5, (), N=40, dt=0.15, settings=off).plan_segment(A, B).path[20].tolist() != \
        X[20].tolist()  # without the pairs CFS keeps the straight line


def test_a_waypoint_in_self_collision_is_refused_naming_the_links(ur5):
    s = np.linspace(0.0, 1.0, 200)[:, None]
    line = A + s * (B - A)
    inside = line[int(np.argmin(self_clearances(ur5, line)[0].min(axis=1)))]
    pl = TrajectoryPlanner(ur5, (), N=10, dt=0.1)
    with pytest.raises(CollisionAtStart, match="self-collision: link '.*' is .* mm from link"):
        pl.check_waypoints(np.array([A, inside]), ["a", "inside"])
