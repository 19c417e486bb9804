"""Culling groups: a joint whose spheres spread wide is split into several groups; verdicts unchanged."""
from __future__ import annotations

import warnings

import numpy as np

from robointel.planning import Environment
from robointel.planning import _sphere_pack as SP
from robointel.robot import Robot


def test_a_wide_joint_is_split_into_contiguous_runs():
    rng = np.random.default_rng(0)
    joints = np.array([2] * 40 + [1] * 6)
    centres = np.concatenate([np.c_[np.linspace(0.0, 1.0, 40), np.zeros((40, 2))],  # a 1 m column of spheres
                              rng.normal(0.0, 0.02, (6, 3))])
    radii = np.full(46, 0.05)
    order, gj, starts = SP.culling_groups(joints, centres, radii)
    assert sorted(order.tolist()) == list(range(46))  # a permutation
    assert np.all(np.diff(joints[order]) >= 0)  # sorted by joint
    assert gj.tolist()[0] == 1 and gj.tolist().count(1) == 1  # the compact joint: one group
    assert gj.tolist().count(2) == 3  # 0.55 m wide: ceil(0.55 / 0.25) groups
    for k in range(len(gj)):
        run = order[starts[k]:starts[k + 1]]
        assert np.all(joints[run] == gj[k])
        P = centres[run]
        assert np.max(np.linalg.norm(P - P.mean(0), axis=1) + 0.05) < 0.55  # each narrower than the whole


def test_split_groups_give_the_same_clearances(shared_data, monkeypatch):
    """The Fetch's torso and base split (three groups each): the clearance of every configuration is the one
    the unsplit groups give, obstacles and self-collision alike."""
    root = shared_data("mbm", "fetch")
    from robointel.geometry.obstacles import Box

    obstacles = [Box(center=[0.8, 0.0, 0.6], size=[0.3, 0.8, 0.04]), Box(center=[0.5, -0.4, 0.9], size=[0.2, 0.2, 0.5])]
    joints = ["torso_lift_joint", "shoulder_pan_joint", "shoulder_lift_joint", "upperarm_roll_joint",
              "elbow_flex_joint", "forearm_roll_joint", "wrist_flex_joint", "wrist_roll_joint"]

    def env():
        with warnings.catch_warnings():  # the SRDF names links the URDF lacks (skipped, as MoveIt does)
            warnings.simplefilter("ignore")
            robot = Robot.load(root / "fetch.urdf", srdf=root / "fetch.srdf", joints=joints)
            return Environment(robot, obstacles, srdf=root / "fetch.srdf", spheres=root / "fetch_spherized.urdf")

    split = env()
    monkeypatch.setattr(SP, "SPLIT_RADIUS", np.inf)
    whole = env()
    assert len(split.world[8]) > len(whole.world[8])  # more groups
    rng = np.random.default_rng(4)
    robot = split.robot
    Q = rng.uniform(robot.lower, robot.upper, (1500, robot.nq))
    a = np.array([split.clearance(q, cap=1.0) for q in Q])
    b = np.array([whole.clearance(q, cap=1.0) for q in Q])
    assert np.array_equal(a, b)
    assert np.any(a < 0.0) and np.any(a > 0.05)  # collisions and clear configurations both met
