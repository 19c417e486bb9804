"""The MuJoCo model is the robot core's model: FK, M(q) and bias forces agree with Pinocchio."""
from __future__ import annotations

import mujoco
import numpy as np
import pytest

from robointel.robot import Robot
from robointel.sim import Workcell, build_model


@pytest.fixture(scope="module", params=["lrmate200id7l", "scara2", "ur5", "panda"])
def robot_and_model(request):
    robot = Robot.load(request.param)
    model, _ = build_model(robot, table=False)
    return robot, model


def _state(model, robot, q, qd):
    d = mujoco.MjData(model)
    d.qpos[: robot.nq] = q
    d.qvel[: robot.nq] = qd
    mujoco.mj_forward(model, d)
    return d


def test_fk_every_link_frame(robot_and_model):
    robot, model = robot_and_model
    rng = np.random.default_rng(1)
    worst = 0.0
    for q in robot.random_configuration(rng, 50):
        d = _state(model, robot, q, np.zeros(robot.nq))
        poses = robot.link_poses(q)
        for name, T in poses.items():
            b = model.body(name).id
            worst = max(worst, np.abs(d.xpos[b] - T[:3, 3]).max(), np.abs(d.xmat[b].reshape(3, 3) - T[:3, :3]).max())
    assert worst < 1e-12


def test_mass_matrix_and_bias_forces(robot_and_model):
    robot, model = robot_and_model
    rng = np.random.default_rng(2)
    n = robot.nq
    M = np.zeros((model.nv, model.nv))
    for q in robot.random_configuration(rng, 50):
        qd = rng.uniform(-2, 2, n)
        d = _state(model, robot, q, qd)
        mujoco.mj_fullM(model, d, M)
        np.testing.assert_allclose(M[:n, :n], robot.mass_matrix(q), atol=1e-8, rtol=0)
        # qfrc_bias = C(q, qd) qd + G(q); damping and frictionloss are elsewhere (passive/constraint)
        np.testing.assert_allclose(d.qfrc_bias[:n], robot.nonlinear_effects(q, qd), atol=1e-8, rtol=0)


def test_urdf_parameters_carried_over():
    robot = Robot.load("lrmate200id7l")
    wc = Workcell(robot)
    m = wc.model
    np.testing.assert_allclose(m.opt.gravity, [0, 0, -9.81])
    np.testing.assert_allclose(m.jnt_range[:6], np.c_[robot.lower, robot.upper])
    np.testing.assert_allclose(m.dof_damping[:6], robot.viscous)
    np.testing.assert_allclose(m.dof_frictionloss[:6], robot.coulomb)
    np.testing.assert_allclose(m.actuator_ctrlrange[:6], np.c_[-robot.effort_limit, robot.effort_limit])
    np.testing.assert_allclose(m.dof_armature[:6], 0.0)
    import xml.etree.ElementTree as ET

    for link in ET.fromstring(robot.urdf).iter("link"):
        mass = link.find("inertial/mass")
        expect = float(mass.get("value")) if mass is not None else 0.0
        assert m.body_mass[m.body(link.get("name")).id] == pytest.approx(expect, rel=1e-15)
    assert sum(m.body_mass) == pytest.approx(27.0, rel=1e-9)
    # robot root frame = MuJoCo world frame; table top at z = 0
    np.testing.assert_allclose(wc.body_pose("base_link"), np.eye(4), atol=1e-15)
    top = m.geom_pos[m.geom("table").id][2] + m.geom_size[m.geom("table").id][2]
    assert abs(top) < 1e-15


def test_payload_model_matches_mujoco():
    """model_with_payload (the controller's feed-forward model) = MuJoCo's arm + tool body."""
    import pinocchio as pin

    from robointel.sim import Payload, model_with_payload

    robot = Robot.load("lrmate200id7l")
    inertia = np.array([[0.004, 0.0005, 0.0], [0.0005, 0.006, 0.0002], [0.0, 0.0002, 0.005]])
    payload = Payload(2.5, (0.07, -0.01, 0.03), inertia=inertia)
    model, _ = build_model(robot, table=False, payload=payload)
    pm = model_with_payload(robot, payload)
    pd = pm.createData()
    rng = np.random.default_rng(5)
    M = np.zeros((6, 6))
    for q in robot.random_configuration(rng, 20):
        qd = rng.uniform(-2, 2, 6)
        d = _state(model, robot, q, qd)
        mujoco.mj_fullM(model, d, M)
        Mp = pin.crba(pm, pd, q)
        np.testing.assert_allclose(M, np.triu(Mp) + np.triu(Mp, 1).T, atol=1e-10)
        np.testing.assert_allclose(d.qfrc_bias[:6], pin.nonLinearEffects(pm, pd, q, qd), atol=1e-10)
