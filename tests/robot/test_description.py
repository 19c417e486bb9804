"""Descriptions as their makers ship them: joint types, planning groups, SRDF entries, mesh lookup, numeric IK."""
from __future__ import annotations

import shutil
import warnings

import numpy as np
import pinocchio as pin
import pytest

from robointel.errors import DescriptionError, DescriptionWarning, IKFailure, InvalidInput
from robointel.robot import Robot
from robointel.robot.catalogue import example_robot_urdf
from robointel.robot.srdf import read_srdf


def test_continuous_joints_are_angles_and_goals_take_the_shorter_turn():
    r = Robot.load(example_robot_urdf("kinova_description/robots/kinova.urdf"))
    assert r.nq == 6 and r.continuous.tolist() == [True, False, False, True, False, True]
    assert np.allclose(r.upper[r.continuous], 2 * np.pi) and np.allclose(r.lower[r.continuous], -2 * np.pi)
    q = np.zeros(6)
    q[0] = 3.0
    g = np.zeros(6)
    g[0] = -3.0  # 6 rad the long way, 0.28 rad across +-pi
    w = r.wrap_goal(g, q)
    assert w[0] == pytest.approx(-3.0 + 2 * np.pi) and np.allclose(r.fk(w), r.fk(g))


def test_repeated_frame_names_resolve_to_the_link():
    r = Robot.load(example_robot_urdf("z1_description/urdf/z1.urdf"))
    names = [f.name for f in r.model.frames]
    shared = sorted({n for n in names if names.count(n) > 1})
    assert shared, "the Z1 description repeats frame names across frame types"
    for n in shared:
        if n in r.link_names:
            assert r.model.frames[r.frame_id(n)].type == pin.FrameType.BODY
    assert set(r.link_poses(np.zeros(r.nq))) == set(r.link_names)


def test_srdf_entries_naming_absent_links_are_skipped_with_a_warning(shared_data):
    d = shared_data("mbm", "fetch")
    with pytest.warns(DescriptionWarning, match="bellows_link2"):
        r = Robot.load(d / "fetch.urdf", srdf=d / "fetch.srdf", group="arm_with_torso")
    assert r.joint_names[0] == "torso_lift_joint" and r.nq == 8
    assert r.chain[3][1] == 1  # the torso is prismatic
    assert all(set(p) <= set(r.link_names) for p in r.srdf.disabled)


def test_malformed_srdf_names_file_and_element(tmp_path):
    bad = tmp_path / "bad.srdf"
    bad.write_text('<robot name="x"><disable_collisions link1="a" reason="Never"/></robot>')
    with pytest.raises(InvalidInput, match=r"bad\.srdf.*disable_collisions.*link2"):
        read_srdf(bad, ["a", "b"])
    bad.write_text("<robot")
    with pytest.raises(InvalidInput, match="bad.srdf"):
        read_srdf(bad)


def test_groups_chains_and_held_joints():
    panda = example_robot_urdf("panda")
    srdf = example_robot_urdf("panda_description/srdf/panda.srdf")
    chain = Robot.load(panda, base_link="panda_link0", tip_link="panda_link8")
    assert chain.joint_names == [f"panda_joint{i}" for i in range(1, 8)] and chain.flange_frame == "panda_link8"
    assert chain.held == {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}
    held = Robot.load(panda, joints=chain.joint_names, held={"panda_finger_joint1": 0.03})
    assert held.held["panda_finger_joint2"] == pytest.approx(0.03)  # the mimic joint follows its master
    a, b = chain.link_poses(np.zeros(7)), held.link_poses(np.zeros(7))
    assert not np.allclose(a["panda_leftfinger"], b["panda_leftfinger"])
    with pytest.raises(InvalidInput, match="outside its limits"):
        Robot.load(panda, joints=chain.joint_names, held={"panda_finger_joint1": 1.0})
    with pytest.raises(InvalidInput, match="no group"):
        Robot.load(panda, srdf=srdf, group="no_such_group")
    with pytest.raises(DescriptionError, match="mimic"):
        Robot.load(panda, joints=["panda_joint1", "panda_finger_joint1"])


def test_missing_mesh_names_the_path_and_where_it_was_looked_for(tmp_path):
    src = example_robot_urdf("ur_description/urdf/ur5_robot.urdf")
    copy = tmp_path / "ur5_robot.urdf"
    shutil.copy(src, copy)  # without its meshes
    with pytest.raises(DescriptionError, match=r"mesh 'package://.*not found; looked in package_dirs.*ROS_PACKAGE"):
        Robot.load(copy)
    r = Robot.load(copy, package_dirs=[src.parents[4]])  # the folder holding example-robot-data/
    assert r.nq == 6


@pytest.mark.parametrize("name", ["ur5", "panda", "fetch", "lrmate200id7l"])
def test_numeric_ik_solves_reachable_poses(name, shared_data):
    if name == "fetch":
        d = shared_data("mbm", "fetch")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DescriptionWarning)
            r = Robot.load(d / "fetch.urdf", srdf=d / "fetch.srdf", group="arm_with_torso")
    else:
        r = Robot.load(name)
    rng = np.random.default_rng(11)
    for k in range(100):
        T = r.fk(r.random_configuration(rng))
        q = r.ik_numeric(T, rng=k)
        assert np.all(q >= r.lower) and np.all(q <= r.upper)
        assert np.abs(r.fk(q) - T).max() < 1e-6
    far = np.eye(4)
    far[:3, 3] = [5.0, 0.0, 0.0]
    with pytest.raises(IKFailure, match="unreachable"):
        r.ik_numeric(far, restarts=5)


@pytest.mark.parametrize("urdf", ["kinova_description/robots/kinova.urdf", "panda_description/urdf/panda.urdf",
                                  "ur_description/urdf/ur5_robot.urdf"])
def test_compiled_batch_kinematics_are_pinocchios(urdf):
    r = Robot.load(example_robot_urdf(urdf))
    rng = np.random.default_rng(11)
    lo, hi = np.maximum(r.lower, -3.0), np.minimum(r.upper, 3.0)
    Q = rng.uniform(lo, hi, (7, r.nq))
    joints = rng.integers(1, r.model.njoints, 9)
    pts = rng.normal(scale=0.2, size=(9, 3))
    assert r._chain_batch  # each joint its own coordinate: the compiled path
    P, J = r.points_kinematics_batch(Q, joints, pts, angular=True)
    r._chain_batch = False  # Pinocchio's computeJointJacobians, sample by sample
    P0, J0 = r.points_kinematics_batch(Q, joints, pts, angular=True)
    np.testing.assert_allclose(P, P0, atol=1e-12)
    np.testing.assert_allclose(J, J0, atol=1e-12)
