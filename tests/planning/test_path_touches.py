"""A timing's collision-mesh failure traced back to the polyline it follows (no futile re-timing of a touching path)."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.geometry.obstacles import Sphere
from robointel.planning import Environment
from robointel.planning.exact_self import self_geometry
from robointel.planning.hybrid_check import path_touches
from robointel.planning.motion_check import DenseCheck
from robointel.robot import Robot


@pytest.fixture(scope="module")
def ur5_env(shared_data):
    root = shared_data("mbm", "ur5")
    robot = Robot.load(root / "ur5.urdf")
    return Environment(robot, [], srdf=root / "ur5.srdf")


def _contact_and_free(env):
    """A configuration whose meshes self-collide, a free one, and the pair in contact."""
    sg = self_geometry(env.robot, env.disabled)
    rng = np.random.default_rng(11)
    hit = free = None
    for q in env.robot.random_configuration(rng, 400):
        d, la, lb = sg.clearance(q, cap=0.1, thresh=0.05)
        if d < -0.002 and hit is None:
            hit = (q, la, lb)
        elif d > 0.01 and free is None:
            free = q
        if hit is not None and free is not None:
            return hit, free
    raise AssertionError("no self-collision and free pair found in 400 samples")


def test_a_polyline_through_the_contact_touches_one_beside_it_does_not(ur5_env):
    env = ur5_env
    (qc, la, lb), qf = _contact_and_free(env)
    failed = DenseCheck(False, "self-collision check", "collision", -0.002, 1, (la, lb), qc + 1e-4)
    # the polyline passes through the contact: its point nearest the failed sample is in contact too
    through = np.array([qc - 0.05, qc + 0.05, qc + 0.3])
    assert path_touches(env, through, failed, d_min=0.001)
    # a polyline that stays at a free configuration far from the failed sample
    away = np.array([qf, qf + 1e-3])
    assert not path_touches(env, away, failed, d_min=0.001)
    # only a collision-mesh failure that names its sample is traced back
    assert not path_touches(env, through, DenseCheck(False, "limit", "limit", 0.0, 1), d_min=0.001)
    no_q = DenseCheck(False, "self-collision check", "collision", -0.005, 1, (la, lb))
    assert not path_touches(env, through, no_q, d_min=0.001)


def test_an_obstacle_contact_on_the_polyline_is_traced_back(shared_data):
    root = shared_data("mbm", "ur5")
    robot = Robot.load(root / "ur5.urdf")
    rng = np.random.default_rng(3)
    q_in, q_out = robot.random_configuration(rng, 2)
    wrist = robot.link_poses(q_in)["wrist_3_link"][:3, 3]
    env = Environment(robot, [Sphere(wrist, 0.03)], srdf=root / "ur5.srdf")
    far = np.linalg.norm(robot.link_poses(q_out)["wrist_3_link"][:3, 3] - wrist)
    assert far > 0.3  # the other configuration keeps the wrist away from the ball
    failed = DenseCheck(False, "collision-mesh check", "collision", -0.01, 1, ("wrist_3_link",), q_in)
    assert path_touches(env, np.array([q_out, q_in]), failed, d_min=0.001)  # ends in the ball
    assert not path_touches(env, np.array([q_out, q_out + 1e-3]), failed, d_min=0.001)


def test_a_polyline_grazing_the_meshes_within_the_margin_touches(shared_data):
    """A polyline whose nearest point clears the meshes by less than ``TOUCH_MARGIN`` is not timed again."""
    from robointel.planning.hybrid_check import TOUCH_MARGIN, mesh_geometry

    root = shared_data("mbm", "ur5")
    robot = Robot.load(root / "ur5.urdf")
    q = np.array([0.3, -1.2, 1.4, -1.7, -1.5, 0.2])
    centre = robot.link_poses(q)["wrist_3_link"][:3, 3] + np.array([0.0, 0.0, 0.25])
    probe = Environment(robot, [Sphere(centre, 0.01)], srdf=root / "ur5.srdf")
    d0 = mesh_geometry(probe).clearance(q, cap=1.0, thresh=1.0)[0]  # exact: the meshes to a 10 mm ball
    assert 0.02 < d0 < 0.9
    failed = DenseCheck(False, "collision-mesh check", "collision", -0.001, 1, ("wrist_3_link",), q + 1e-4)
    for gap, touches in ((0.5 * TOUCH_MARGIN, True), (2.0 * TOUCH_MARGIN + 1e-3, False)):
        env = Environment(robot, [Sphere(centre, 0.01 + d0 - gap)], srdf=root / "ur5.srdf")
        assert abs(mesh_geometry(env).clearance(q, cap=1.0, thresh=1.0)[0] - gap) < 1e-6
        assert path_touches(env, np.array([q - 0.01, q + 0.01]), failed, d_min=0.001) is touches
