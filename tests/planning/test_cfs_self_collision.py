"""CFS keeps the arm clear of itself: self-collision pairs are constraints of the segment QP (planning/segment.py)."""
import numpy as np
import pytest

from robointel.errors import CollisionAtStart
from robointel.planning.segment import PlannerSettings, self_clearances
from robointel.planning.waypoints import TrajectoryPlanner
from robointel.robot import Robot

# two configurations of the MotionBenchMaker UR5 clear of itself, the straight line between them through itself
A = np.radians([-149.1188, -94.7181, 108.4243, 29.5689, -146.0672, -24.0666])
B = np.radians([-45.2578, -147.2461, 57.7616, 155.2775, -105.3776, 46.8176])


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


def test_cfs_sees_self_collision_and_its_verdict_matches_a_dense_check(ur5):
    s = np.linspace(0.0, 1.0, 20)[:, None]
    line = A + np.linspace(0.0, 1.0, 200)[:, None] * (B - A)
    assert self_clearances(ur5, line)[0].min() < -0.002  # the straight reference goes through the arm

    def dense_min(X):
        return self_clearances(ur5, np.concatenate([X[k] + s * (X[k + 1] - X[k]) for k in range(len(X) - 1)]))[0].min()

    blind = TrajectoryPlanner(ur5, (), N=40, dt=0.3, settings=PlannerSettings(d_min=0.02, self_collision=False))
    old = blind.plan_segment(A, B)
    assert old.feasible and dense_min(old.path) < -0.002  # without the pairs: "feasible" through itself
    pl = TrajectoryPlanner(ur5, (), N=40, dt=0.3, settings=PlannerSettings(d_min=0.02))
    plan = pl.plan_segment(A, B)
    assert plan.blocked
    assert plan.feasible == (dense_min(plan.path) > -1e-3)  # the planner's verdict is the dense check's
    assert dense_min(plan.path) > dense_min(old.path)  # and it moved away from the collision


def test_a_waypoint_in_self_collision_is_refused_naming_the_links(ur5):
    s = np.linspace(0.0, 1.0, 200)[:, None]
    line = A + s * (B - A)
    inside = line[int(np.argmin(self_clearances(ur5, line)[0].min(axis=1)))]
    pl = TrajectoryPlanner(ur5, (), N=10, dt=0.1)
    with pytest.raises(CollisionAtStart, match="self-collision: link '.*' is .* mm from link"):
        pl.check_waypoints(np.array([A, inside]), ["a", "inside"])


def test_far_self_pairs_are_left_out_without_changing_a_row_or_a_minimum(ur5):
    from robointel.geometry import Box
    from robointel.planning.segment import all_clearances, sphere_clearances

    st = PlannerSettings(d_min=0.02, margin=0.05)
    box = [Box(center=np.array([0.45, 0.1, 0.3]), size=np.array([0.1, 0.4, 0.3]))]
    Q = A + np.linspace(0.0, 1.0, 30)[:, None] * (B - A)
    got = all_clearances(ur5, Q, box, st)
    full_d, full_g = self_clearances(ur5, Q)
    full_d = full_d + st.d_min - st.self_d_min
    obs = sphere_clearances(ur5, Q, box)
    k = obs.d.reshape(len(Q), -1).shape[1]
    assert got.n_obstacle == k
    np.testing.assert_array_equal(got.d[:, :k], obs.d.reshape(len(Q), -1))
    far = st.d_min + st.safety + st.margin
    near = full_d.min(axis=0) < far
    assert 0 < near.sum() < len(near)  # some pairs come within the margin somewhere, most never do
    # every pair that can enter the QP is there with its gradient; the rest is one column of their minimum
    assert got.d.shape[1] == k + near.sum() + 1
    np.testing.assert_array_equal(got.d[:, k:-1], full_d[:, near])
    np.testing.assert_array_equal(got.grad[:, k:-1], full_g[:, near])
    np.testing.assert_array_equal(got.d[:, -1], full_d[:, ~near].min(axis=1))
    assert (got.d[:, -1] >= far).all() and not got.grad[:, -1].any()
    np.testing.assert_array_equal(got.d.min(axis=1), np.minimum(obs.d.reshape(len(Q), -1).min(axis=1),
                                                                full_d.min(axis=1)))
    every = all_clearances(ur5, Q, box, st, cull=False)  # SLSQP's fixed set of constraints: every pair
    np.testing.assert_array_equal(every.d[:, k:], full_d)
    np.testing.assert_array_equal(every.grad[:, k:], full_g)
