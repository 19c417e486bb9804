"""Robot core: FK against the ROS-Industrial description, Jacobians, IK, dynamics, errors."""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest

from robointel.errors import DescriptionError, IKFailure, LimitViolation, NotFinite, ShapeError, UnknownRobot
from robointel.robot import Robot


def _xacro_eval(expr: str) -> float:
    """Evaluate a xacro ``${...}`` expression with radians() and pi."""
    expr = expr.strip()
    m = re.fullmatch(r"\$\{(.*)\}", expr)
    if not m:
        return float(expr)
    return float(eval(m.group(1), {"__builtins__": {}}, {"radians": np.radians, "pi": np.pi}))


def _axis_angle(axis, angle):
    axis = np.asarray(axis, float)
    return pin.exp3(axis / np.linalg.norm(axis) * angle)


def _xacro_chain(path):
    text = path.read_text()
    root = ET.fromstring(text)
    joints = {}
    for j in root.iter("joint"):
        o = j.find("origin")
        xyz = [_xacro_eval(v) for v in o.get("xyz").split()]
        rpy = [_xacro_eval(v) for v in o.get("rpy").split()]
        ax = j.find("axis")
        lim = j.find("limit")
        joints[j.get("name").replace("${prefix}", "")] = {
            "type": j.get("type"), "xyz": np.array(xyz), "rpy": np.array(rpy),
            "axis": np.array([float(v) for v in ax.get("xyz").split()]) if ax is not None else None,
            "lower": _xacro_eval(lim.get("lower")) if lim is not None else None,
            "upper": _xacro_eval(lim.get("upper")) if lim is not None else None,
            "velocity": _xacro_eval(lim.get("velocity")) if lim is not None else None,
        }
    return joints


def _reference_fk(chain, q):
    """Flange pose from the xacro's joint origins and axes (independent of Pinocchio)."""
    T = np.eye(4)
    for i in range(6):
        j = chain[f"joint_{i + 1}"]
        A = np.eye(4)
        A[:3, :3] = pin.rpy.rpyToMatrix(*j["rpy"])
        A[:3, 3] = j["xyz"]
        B = np.eye(4)
        B[:3, :3] = _axis_angle(j["axis"], q[i])
        T = T @ A @ B
    j = chain["link_6-flange"]
    A = np.eye(4)
    A[:3, :3] = pin.rpy.rpyToMatrix(*j["rpy"])
    A[:3, 3] = j["xyz"]
    return T @ A


def test_fk_matches_ros_industrial_description(shared_data, lrmate):
    chain = _xacro_chain(shared_data("robots", "fanuc_lrmate200id7l", "lrmate200id7l_macro.xacro"))
    for i in range(6):
        j = chain[f"joint_{i + 1}"]
        assert lrmate.lower[i] == pytest.approx(j["lower"], abs=1e-12)
        assert lrmate.upper[i] == pytest.approx(j["upper"], abs=1e-12)
        assert lrmate.velocity_limit[i] == pytest.approx(j["velocity"], abs=1e-12)
    rng = np.random.default_rng(0)
    Q = lrmate.random_configuration(rng, 1000)
    err = max(np.abs(lrmate.fk(q) - _reference_fk(chain, q)).max() for q in Q)
    assert err < 1e-9
    # the FANUC world frame 'base' is 0.330 m above the mounting plane
    assert np.allclose(lrmate.frame_pose(Q[0], "base")[:3, 3], [0, 0, 0.330])


def test_builtin_dimensions(lrmate):
    T = lrmate.fk(np.zeros(6))
    # zero pose: flange at x = 0.05 + 0.42 + 0.08, z = 0.33 + 0.44 + 0.035
    assert np.allclose(T[:3, 3], [0.55, 0.0, 0.805], atol=1e-12)
    assert np.allclose(T[:3, :3], np.eye(3))
    mass = sum(float(i.mass) for i in lrmate.model.inertias)
    assert mass == pytest.approx(27.0, abs=1e-6)


def test_point_jacobian_matches_finite_differences(lrmate):
    rng = np.random.default_rng(1)
    eps = 1e-6
    for _ in range(20):
        q = lrmate.random_configuration(rng)
        link = rng.choice(["link_2", "link_3", "link_4", "link_6"])
        p_local = rng.normal(scale=0.1, size=3)
        J = lrmate.point_jacobian(q, link, p_local)

        def point(qq):
            T = lrmate.frame_pose(qq, link)
            return T[:3, :3] @ p_local + T[:3, 3], T[:3, :3]

        Jfd = np.zeros((6, 6))
        for k in range(6):
            dq = np.zeros(6)
            dq[k] = eps
            (pp, Rp), (pm, Rm) = point(q + dq), point(q - dq)
            Jfd[:3, k] = (pp - pm) / (2 * eps)
            Jfd[3:, k] = pin.log3(Rp @ Rm.T) / (2 * eps)
        assert np.abs(J - Jfd).max() < 1e-7


def test_tcp_jacobian_with_tool(lrmate):
    robot = Robot.load("lrmate200id7l")
    tool = np.eye(4)
    tool[:3, 3] = [0.12, 0.01, -0.02]
    tool[:3, :3] = pin.rpy.rpyToMatrix(0.1, -0.2, 0.3)
    robot.tool = tool
    q = robot.random_configuration(3)
    J = robot.jacobian(q)
    eps = 1e-6
    for k in range(6):
        dq = np.zeros(6)
        dq[k] = eps
        fd = (robot.fk(q + dq)[:3, 3] - robot.fk(q - dq)[:3, 3]) / (2 * eps)
        assert np.allclose(J[:3, k], fd, atol=1e-7)
    assert np.allclose(robot.fk(q), robot.frame_pose(q) @ tool)


def test_sphere_kinematics_agree_with_point_jacobians(lrmate):
    q = lrmate.random_configuration(4)
    P, J = lrmate.spheres.kinematics(q)
    for i in (0, 5, 12, len(lrmate.spheres) - 1):
        link, c = lrmate.spheres.links[i], lrmate.spheres.centers[i]
        T = lrmate.frame_pose(q, link)
        assert np.allclose(P[i], T[:3, :3] @ c + T[:3, 3], atol=1e-12)
        assert np.allclose(J[i], lrmate.point_jacobian(q, link, c)[:3], atol=1e-12)


def test_closed_form_ik_round_trip_10000_poses(lrmate):
    rng = np.random.default_rng(2)
    Q = lrmate.random_configuration(rng, 10_000)
    worst, counts, found = 0.0, [], 0
    for q in Q:
        T = lrmate.fk(q)
        sols = lrmate.ik(T)
        counts.append(len(sols))
        for s in sols:
            assert np.all(s >= lrmate.lower) and np.all(s <= lrmate.upper)
            worst = max(worst, float(np.abs(lrmate.fk(s) - T).max()))
        # the generating configuration is among the solutions (up to 2*pi turns of J4/J6)
        found += min(np.abs(s - q).max() for s in lrmate.ik(T, all_turns=True)) < 1e-6
    assert worst < 1e-9
    assert found == len(Q)
    assert max(counts) == 8 and min(counts) >= 1


def test_ik_q_ref_sorts_and_unreachable_fails(lrmate):
    q = np.array([0.3, 0.2, -0.1, 0.5, -0.6, 1.0])
    sols = lrmate.ik(lrmate.fk(q), q_ref=q)
    assert np.allclose(sols[0], q, atol=1e-9)
    T = np.eye(4)
    T[:3, 3] = [2.0, 0.0, 0.5]
    with pytest.raises(IKFailure, match="workspace"):
        lrmate.ik(T)


def test_wrist_singular_pose(lrmate):
    q = np.array([0.2, 0.1, 0.3, 0.4, 0.0, -0.5])
    T = lrmate.fk(q)
    sols = lrmate.ik(T)
    assert sols and all(np.abs(lrmate.fk(s) - T).max() < 1e-9 for s in sols)


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_example_robot_data_arms_and_numeric_ik(name):
    robot = Robot.load(name)
    assert robot.nq in (6, 7, 9)
    rng = np.random.default_rng(5)
    q = robot.random_configuration(rng)
    T = robot.fk(q)
    sol = robot.ik(T)[0]
    assert np.abs(robot.fk(sol) - T).max() < 1e-8
    assert len(robot.spheres) > 0


def test_scara_builtin():
    r = Robot.load("scara2")
    assert r.nq == 2
    T = r.fk(np.array([0.0, np.pi / 2]))
    assert np.allclose(T[:3, 3], [0.40, 0.35, 0.33], atol=1e-12)
    # planar arm: gravity does no work about vertical axes
    assert np.allclose(r.gravity(np.array([0.3, -0.7])), 0.0, atol=1e-12)


def test_dynamics_consistency(lrmate):
    rng = np.random.default_rng(6)
    for _ in range(10):
        q = lrmate.random_configuration(rng)
        qd, qdd = rng.normal(size=6), rng.normal(size=6)
        M = lrmate.mass_matrix(q)
        assert np.allclose(M, M.T) and np.all(np.linalg.eigvalsh(M) > 0)
        tau = lrmate.inverse_dynamics(q, qd, qdd)
        assert np.allclose(tau, M @ qdd + lrmate.coriolis(q, qd) + lrmate.gravity(q), atol=1e-10)
        assert np.allclose(lrmate.forward_dynamics(q, qd, tau), qdd, atol=1e-9)
        tauf = lrmate.inverse_dynamics(q, qd, qdd, friction=True)
        assert np.allclose(lrmate.forward_dynamics(q, qd, tauf, friction=True), qdd, atol=1e-9)
        # friction dissipates
        assert lrmate.friction(qd) @ qd > 0
        # energy: qd^T (M_dot - 2 C) qd = 0  <=>  qd^T C qd = 0.5 qd^T M_dot qd
        eps = 1e-7
        Mdot = (lrmate.mass_matrix(q + eps * qd) - lrmate.mass_matrix(q - eps * qd)) / (2 * eps)
        assert qd @ lrmate.coriolis(q, qd) == pytest.approx(0.5 * qd @ Mdot @ qd, rel=1e-5, abs=1e-8)


def test_gravity_matches_potential_energy_gradient(lrmate):
    q = lrmate.random_configuration(7)
    eps = 1e-6

    def potential(qq):
        pin.forwardKinematics(lrmate.model, lrmate.data, qq)
        pin.computePotentialEnergy(lrmate.model, lrmate.data, qq)
        return lrmate.data.potential_energy

    g = np.array([(potential(q + eps * e) - potential(q - eps * e)) / (2 * eps) for e in np.eye(6)])
    assert np.allclose(lrmate.gravity(q), g, atol=1e-6)


def test_bad_input_errors(lrmate, tmp_path):
    with pytest.raises(UnknownRobot, match="not a built-in name"):
        Robot.load("kuka_nonexistent")
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot")
    with pytest.raises(DescriptionError, match="valid URDF"):
        Robot.load(bad)
    with pytest.raises(NotFinite):
        lrmate.fk(np.array([0, 0, np.nan, 0, 0, 0.0]))
    with pytest.raises(ShapeError, match=r"shape \(6,\)"):
        lrmate.fk(np.zeros(5))
    with pytest.raises(LimitViolation, match="joint_2"):
        lrmate.check_q(np.array([0, 3.0, 0, 0, 0, 0]), limits=True)
    with pytest.raises(NotFinite):
        lrmate.ik(np.full((4, 4), np.inf))


def test_sphere_kinematics_batch_equals_loop(lrmate):
    Q = lrmate.random_configuration(8, 5)
    P, J = lrmate.spheres.kinematics_batch(Q, angular=True)
    for b, q in enumerate(Q):  # (the batch is compiled over the joint chain, the single call is Pinocchio's)
        p1, j1 = lrmate.spheres.kinematics(q, angular=True)
        np.testing.assert_allclose(P[b], p1, rtol=0, atol=1e-13)
        np.testing.assert_allclose(J[b], j1, rtol=0, atol=1e-13)
    assert lrmate.spheres.kinematics_batch(Q)[1].shape == (5, len(lrmate.spheres), 3, 6)
