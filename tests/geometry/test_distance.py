"""Robot-obstacle distances: consistency with the shapes, exact gradients (finite differences),
the true minimum, J_rep, batching, collision checks and bad input."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robointel.errors import CollisionAtStart, InvalidInput, NotFinite, ShapeError
from robointel.geometry import (
    Box,
    Capsule,
    Cylinder,
    ObstacleSet,
    PointCloud,
    Sphere,
    check_collision_free,
    closest_pairs,
    in_collision,
    min_distance,
    self_collision_distance,
    sphere_distances,
    sphere_distances_batch,
)
from robointel.robot import Robot


@pytest.fixture(scope="module")
def ur5():
    return Robot.load("ur5")


def scene(robot, rng):
    """Obstacles of every type scattered in the robot's workspace."""
    reach = 0.8 if robot.name == "lrmate200id7l" else 0.7
    z0 = 0.4 if robot.name == "lrmate200id7l" else 0.2
    c = lambda: rng.uniform([-reach, -reach, 0.0], [reach, reach, z0 + 0.6])  # noqa: E731
    return [
        Sphere(c(), 0.08, name="ball"),
        Capsule(c(), c(), 0.05),
        Cylinder(c(), c(), 0.06, name="post"),
        Cylinder([0.45, 0.0, 0.0], [0.45, 0.0, 0.7], 0.05),
        Box(c(), [0.2, 0.1, 0.3], Rotation.random(random_state=rng).as_matrix()),
        PointCloud(c() + rng.normal(size=(60, 3)) * 0.05, radius=0.01, name="cloud"),
    ]


@pytest.fixture(params=["lrmate", "ur5"])
def robot(request, lrmate, ur5):
    return lrmate if request.param == "lrmate" else ur5


def _scene(robot, seed):
    return scene(robot, np.random.default_rng(seed))


def test_sphere_distances_match_shapes(robot):
    obs = _scene(robot, 1)
    q = robot.random_configuration(11)
    sd = sphere_distances(robot, q, obs)
    m, k = len(robot.spheres), len(obs)
    assert sd.d.shape == (m, k) and sd.grad.shape == (m, k, robot.nq)
    assert sd.normals.shape == sd.robot_points.shape == sd.obstacle_points.shape == (m, k, 3)
    C = robot.spheres.positions(q)
    r = robot.spheres.radii
    for j, o in enumerate(obs):
        d, cl, n = o.distance(C)
        np.testing.assert_allclose(sd.d[:, j], d - r, atol=1e-12)
        np.testing.assert_allclose(sd.obstacle_points[:, j], cl, atol=1e-12)
        np.testing.assert_allclose(sd.normals[:, j], n, atol=1e-12)
        np.testing.assert_allclose(sd.robot_points[:, j], C - r[:, None] * n, atol=1e-12)
    # surface-to-surface: the gap between the closest points equals d along the normal
    gap = np.einsum("mkj,mkj->mk", sd.robot_points - sd.obstacle_points, sd.normals)
    np.testing.assert_allclose(gap, sd.d, atol=1e-9)


def _fd_check(robot, obs, qs, h=1e-6):
    """Central finite differences of d vs grad at pairs away from kinks (one-sided FDs agree)."""
    checked = 0
    for q in qs:
        sd = sphere_distances(robot, q, obs)
        fd = np.empty_like(sd.grad)
        smooth = np.ones(sd.d.shape, bool)
        for a in range(robot.nq):
            e = np.zeros(robot.nq)
            e[a] = h
            dp = sphere_distances(robot, q + e, obs).d
            dm = sphere_distances(robot, q - e, obs).d
            fd[:, :, a] = (dp - dm) / (2 * h)
            smooth &= np.abs((dp - sd.d) - (sd.d - dm)) / h < 1e-4
        assert smooth.mean() > 0.95
        np.testing.assert_allclose(sd.grad[smooth], fd[smooth], atol=2e-6)
        checked += smooth.sum()
    return checked


def test_gradients_match_finite_differences(robot):
    rng = np.random.default_rng(5)
    obs = _scene(robot, 2)
    qs = robot.random_configuration(rng, 6)
    assert _fd_check(robot, obs, qs) > 500


def test_min_distance_is_the_true_minimum(robot):
    rng = np.random.default_rng(9)
    obs = _scene(robot, 3)
    for q in robot.random_configuration(rng, 15):
        sd = sphere_distances(robot, q, obs)
        md = min_distance(robot, q, obs)
        i, k = sd.argmin()
        assert md.distance == pytest.approx(sd.d.min(), abs=1e-12)
        assert (md.sphere, md.obstacle) == (i, k)
        assert md.link == robot.spheres.links[i]
        assert md.obstacle_name == obs[k].label(k)
        np.testing.assert_allclose(md.gradient, sd.grad[i, k], atol=1e-12)
        np.testing.assert_allclose(md.normal, sd.normals[i, k], atol=1e-12)
        np.testing.assert_allclose(md.robot_point, sd.robot_points[i, k], atol=1e-12)
        np.testing.assert_allclose(md.obstacle_point, sd.obstacle_points[i, k], atol=1e-12)
        np.testing.assert_allclose(md.normal @ md.jacobian, md.gradient, atol=1e-12)


def test_jrep_is_the_jacobian_of_the_closest_point_fixed_on_its_link(robot):
    rng = np.random.default_rng(13)
    obs = _scene(robot, 4)
    h = 1e-6
    for q in robot.random_configuration(rng, 5):
        md = min_distance(robot, q, obs)
        T = robot.frame_pose(q, md.link)
        p_link = T[:3, :3].T @ (md.robot_point - T[:3, 3])
        # the robot core's point Jacobian of the same link point
        np.testing.assert_allclose(md.jacobian, robot.point_jacobian(q, md.link, p_link)[:3], atol=1e-12)
        # finite difference of the point carried by the link
        fd = np.empty((3, robot.nq))
        for a in range(robot.nq):
            e = np.zeros(robot.nq)
            e[a] = h
            Tp, Tm = robot.frame_pose(q + e, md.link), robot.frame_pose(q - e, md.link)
            fd[:, a] = ((Tp[:3, :3] @ p_link + Tp[:3, 3]) - (Tm[:3, :3] @ p_link + Tm[:3, 3])) / (2 * h)
        np.testing.assert_allclose(md.jacobian, fd, atol=1e-7)


def test_batch_equals_loop(lrmate):
    obs = _scene(lrmate, 6)
    Q = lrmate.random_configuration(21, 7)
    b = sphere_distances_batch(lrmate, Q, obs, movable_only=True)
    assert b.d.shape == (7, int(lrmate.spheres.movable.sum()), len(obs))
    for t, q in enumerate(Q):
        s = sphere_distances(lrmate, q, obs, movable_only=True)
        np.testing.assert_allclose(b.d[t], s.d, atol=1e-12)
        np.testing.assert_allclose(b.grad[t], s.grad, atol=1e-12)
        np.testing.assert_allclose(b.obstacle_points[t], s.obstacle_points, atol=1e-12)
        np.testing.assert_allclose(b.robot_points[t], s.robot_points, atol=1e-12)
        np.testing.assert_array_equal(b.spheres, s.spheres)


def test_batch_all_spheres_and_empty_batch(lrmate):
    """The batched kinematics path (all spheres, not only the movable ones) equals the loop, and an
    empty batch gives empty arrays."""
    obs = _scene(lrmate, 4)
    Q = lrmate.random_configuration(5, 4)
    b = sphere_distances_batch(lrmate, Q, obs)
    assert b.d.shape == (4, len(lrmate.spheres.radii), len(obs))
    for t, q in enumerate(Q):
        s = sphere_distances(lrmate, q, obs)
        np.testing.assert_allclose(b.d[t], s.d, atol=1e-12)
        np.testing.assert_allclose(b.grad[t], s.grad, atol=1e-12)
        np.testing.assert_allclose(b.normals[t], s.normals, atol=1e-12)
    e = sphere_distances_batch(lrmate, np.zeros((0, 6)), obs, movable_only=True)
    assert e.d.shape == (0, int(lrmate.spheres.movable.sum()), len(obs))


def test_planner_clearances_are_the_batched_distances(lrmate):
    from robointel.planning.waypoints import sphere_clearances

    obs = _scene(lrmate, 3)
    Q = lrmate.random_configuration(8, 6)
    a = sphere_clearances(lrmate, Q, obs)
    b = sphere_distances_batch(lrmate, Q, obs, movable_only=True)
    np.testing.assert_array_equal(a.d, b.d)
    np.testing.assert_array_equal(a.grad, b.grad)
    np.testing.assert_array_equal(a.spheres, b.spheres)


def test_movable_only_and_custom_spheres(lrmate):
    from robointel.robot import SphereModel

    obs = [Cylinder([0.5, 0, 0], [0.5, 0, 0.6], 0.05)]
    q = np.zeros(6)
    full = sphere_distances(lrmate, q, obs)
    mov = sphere_distances(lrmate, q, obs, movable_only=True)
    mask = lrmate.spheres.movable
    np.testing.assert_array_equal(mov.spheres, np.flatnonzero(mask))
    np.testing.assert_allclose(mov.d, full.d[mask])
    np.testing.assert_allclose(full.grad[~mask], 0.0)  # base spheres never move
    md = min_distance(lrmate, q, obs, movable_only=True)
    assert mask[md.sphere]
    one = SphereModel(["link_6"], np.array([[0.0, 0.0, 0.05]]), np.array([0.03])).bind(lrmate)
    sd = sphere_distances(lrmate, q, obs, spheres=one)
    assert sd.d.shape == (1, 1)
    c = one.positions(q)
    assert sd.d[0, 0] == pytest.approx(obs[0].distance(c)[0][0] - 0.03)


def test_obstacle_set_and_cache_reuse(lrmate):
    obs = _scene(lrmate, 7)
    q = lrmate.random_configuration(2)
    a = sphere_distances(lrmate, q, obs)
    b = sphere_distances(lrmate, q, ObstacleSet(obs))
    c = sphere_distances(lrmate, q, tuple(obs))
    np.testing.assert_allclose(a.d, b.d)
    np.testing.assert_allclose(a.d, c.d)
    moved = [o.translated([0.1, 0, 0]) for o in obs]  # new objects -> new packing, new answer
    d = sphere_distances(lrmate, q, moved)
    assert not np.allclose(a.d, d.d)
    single = sphere_distances(lrmate, q, obs[0])
    np.testing.assert_allclose(single.d[:, 0], a.d[:, 0])


def test_empty_obstacles(lrmate):
    q = np.zeros(6)
    sd = sphere_distances(lrmate, q, [])
    assert sd.d.shape == (len(lrmate.spheres), 0)
    md = min_distance(lrmate, q, [])
    assert md.distance == np.inf and md.sphere == -1 and md.gradient.shape == (6,)
    assert not in_collision(lrmate, q, [])


def test_in_collision_names_link_and_obstacle(lrmate):
    q = np.zeros(6)
    tcp = lrmate.frame_pose(q, "link_6")[:3, 3]
    obs = [Sphere([2.0, 2.0, 2.0], 0.1, name="far"), Sphere(tcp, 0.02, name="cup")]
    res = in_collision(lrmate, q, obs)
    assert res and res.distance < 0 and res.obstacle == 1
    assert "cup" in res.message and res.link in res.message
    with pytest.raises(CollisionAtStart, match="cup"):
        check_collision_free(lrmate, q, obs)
    free = [obs[0]]
    assert not in_collision(lrmate, q, free)
    check_collision_free(lrmate, q, free)
    far = min_distance(lrmate, q, free).distance
    assert in_collision(lrmate, q, free, margin=far + 0.01)  # the margin counts


def test_self_collision_distance(robot):
    rng = np.random.default_rng(17)
    sm = robot.spheres
    if len(sm.self_pairs) == 0:
        pytest.skip("no self-collision pairs in this sphere model")
    h = 1e-6
    for q in robot.random_configuration(rng, 5):
        sd = self_collision_distance(robot, q)
        np.testing.assert_allclose(sd.distance, sm.self_distances(q).min(), atol=1e-12)
        assert sd.links == (sm.links[sd.spheres[0]], sm.links[sd.spheres[1]])
        fd = np.empty(robot.nq)
        for a in range(robot.nq):
            e = np.zeros(robot.nq)
            e[a] = h
            i, k = sd.spheres
            fp = sm.positions(q + e)
            fm = sm.positions(q - e)
            dp = np.linalg.norm(fp[i] - fp[k]) - sm.radii[i] - sm.radii[k]
            dm = np.linalg.norm(fm[i] - fm[k]) - sm.radii[i] - sm.radii[k]
            fd[a] = (dp - dm) / (2 * h)
        np.testing.assert_allclose(sd.gradient, fd, atol=1e-7)


@pytest.mark.parametrize("call,exc", [
    (lambda r: sphere_distances(r, np.full(6, np.nan), []), NotFinite),
    (lambda r: sphere_distances(r, np.zeros(5), []), ShapeError),
    (lambda r: min_distance(r, np.zeros((2, 6)), []), ShapeError),
    (lambda r: sphere_distances(r, np.zeros(6), [np.zeros(3)]), InvalidInput),
    (lambda r: min_distance(r, np.zeros(6), ["box"]), InvalidInput),
    (lambda r: sphere_distances_batch(r, np.zeros((3, 5)), []), ShapeError),
    (lambda r: sphere_distances_batch(r, np.array([[0, 0, 0, 0, 0, np.inf]]), []), NotFinite),
    (lambda r: in_collision(r, np.zeros(6), [], margin=np.nan), NotFinite),
    (lambda r: sphere_distances(r, np.zeros(6), [], spheres="all"), InvalidInput),
])
def test_bad_input(lrmate, call, exc):
    with pytest.raises(exc):
        call(lrmate)


def test_warmup_and_self_collision_flag(lrmate):
    from robointel.geometry import warmup

    warmup()
    sm = lrmate.spheres
    # a folded-back configuration where the wrist nears the upper arm: self-collision counts
    rng = np.random.default_rng(23)
    Q = lrmate.random_configuration(rng, 400)
    dists = np.array([sm.self_distances(q).min() for q in Q])
    q = Q[int(np.argmin(dists))]
    far = [Sphere([3.0, 3.0, 3.0], 0.1, name="far")]
    res = in_collision(lrmate, q, far, self_collision=True)
    assert res.distance == pytest.approx(min(dists.min(), min_distance(lrmate, q, far).distance))
    assert dists.min() < 0  # random configurations do fold the arm onto itself
    assert res and res.obstacle == -1 and res.obstacle_name.startswith("self")
    assert not in_collision(lrmate, q, far, self_collision=False)


@pytest.mark.parametrize("movable_only", [False, True])
def test_closest_pairs_per_obstacle(robot, movable_only):
    rng = np.random.default_rng(29)
    obs = _scene(robot, 8)
    for q in robot.random_configuration(rng, 4):
        sd = sphere_distances(robot, q, obs, movable_only=movable_only)
        cp = closest_pairs(robot, q, obs, movable_only=movable_only)
        assert len(cp) == len(obs)
        rows = sd.d.argmin(0)
        np.testing.assert_allclose(cp.distance, sd.d.min(0), atol=1e-12)
        np.testing.assert_array_equal(cp.sphere, sd.spheres[rows])
        cols = np.arange(len(obs))
        np.testing.assert_allclose(cp.gradient, sd.grad[rows, cols], atol=1e-12)
        np.testing.assert_allclose(cp.normal, sd.normals[rows, cols], atol=1e-12)
        np.testing.assert_allclose(cp.robot_point, sd.robot_points[rows, cols], atol=1e-12)
        np.testing.assert_allclose(cp.obstacle_point, sd.obstacle_points[rows, cols], atol=1e-12)
        for k in range(len(obs)):
            pair = cp[k]
            T = robot.frame_pose(q, pair.link)
            p_link = T[:3, :3].T @ (pair.robot_point - T[:3, 3])
            np.testing.assert_allclose(pair.jacobian, robot.point_jacobian(q, pair.link, p_link)[:3], atol=1e-12)
        md = min_distance(robot, q, obs, movable_only=movable_only)
        k = int(np.argmin(cp.distance))
        assert md.obstacle == k and md.sphere == cp.sphere[k]
        np.testing.assert_allclose(md.jacobian, cp.jacobian[k], atol=1e-12)


def test_closest_pairs_primitives_only_and_empty(lrmate):
    q = np.zeros(6)
    obs = [Cylinder([0.5, 0, 0], [0.5, 0, 0.6], 0.05), Box([0.3, 0.4, 0.3], [0.1, 0.1, 0.1])]
    cp = closest_pairs(lrmate, q, obs)
    sd = sphere_distances(lrmate, q, obs)
    np.testing.assert_allclose(cp.distance, sd.d.min(0), atol=1e-12)
    assert cp.obstacle_names == ["cylinder[0]", "box[1]"]
    empty = closest_pairs(lrmate, q, [])
    assert len(empty) == 0 and empty.gradient.shape == (0, 6)
