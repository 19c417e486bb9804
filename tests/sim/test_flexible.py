"""The flexible-joint model (2.1)-(2.2): rigid limit, gravity wind-up, resonance."""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from robointel.errors import InvalidInput, NotFinite, ShapeError
from robointel.robot import Robot
from robointel.sim.flexible import FlexibleJointModel, FlexibleJointParams

Q0 = np.array([0.2, 0.4, -0.3, 0.5, -0.6, 0.3])


def test_very_stiff_joints_converge_to_the_rigid_model(lrmate):
    p = FlexibleJointParams.lrmate(stiffness=1e9, damping=1e3)
    flex = FlexibleJointModel(lrmate, p, dt=1e-3, substeps=10)
    rigid = flex.rigid_model()
    data = rigid.createData()
    B, N = flex.params.reflected_friction, flex.params.gear_ratio
    g0 = lrmate.gravity(Q0)

    def tau_m(t):  # open loop: gravity at Q0 plus a wobble, motor side, held over each 1 ms period
        t = np.floor(t / 1e-3 + 1e-9) * 1e-3
        return (g0 + np.array([20.0, 15.0, 8.0, 2.0, 2.0, 0.5]) * np.sin(2 * np.pi * 2.0 * t)) / N

    def rhs(x, u):
        q, qd = x[:6], x[6:]
        return np.concatenate([qd, pin.aba(rigid, data, q, qd, N * u - B * qd)])

    T = 0.3
    flex.reset(Q0)
    out = flex.simulate(lambda m: tau_m(m.time), T)
    # reference: the rigid limit by classical RK4 at 0.1 ms with the same zero-order-hold torques
    x, h, qref = np.concatenate([Q0, np.zeros(6)]), 1e-4, []
    for k in range(len(out["t"])):
        qref.append(x[:6].copy())
        u = tau_m(k * 1e-3)
        for _ in range(10):
            k1 = rhs(x, u)
            k2 = rhs(x + 0.5 * h * k1, u)
            k3 = rhs(x + 0.5 * h * k2, u)
            k4 = rhs(x + h * k3, u)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    qref = np.array(qref)
    err = np.abs(out["q"] - qref).max()
    travel = np.abs(qref - Q0).max()
    assert travel > 0.05  # the arm really moved
    assert err < 5e-4 * travel, (err, travel)  # measured 2.5e-4: O(h) of the implicit Euler, h = 0.1 ms
    assert np.abs(out["theta"] - out["q"]).max() < 1e-6  # no visible spring deflection


def test_gravity_winds_up_the_springs(lrmate):
    flex = FlexibleJointModel(lrmate, FlexibleJointParams.lrmate(), dt=1e-3)
    K = flex.params.stiffness
    N = flex.params.gear_ratio
    G = lrmate.gravity(Q0)
    theta_star = flex.equilibrium_motor_position(Q0)
    np.testing.assert_allclose(K * (theta_star - Q0), G, rtol=1e-9, atol=1e-12)
    w = 2 * np.pi * 20.0  # motor position loop at 20 Hz
    kp, kd = flex.params.reflected_inertia * w**2, 2.0 * flex.params.reflected_inertia * w

    def motor_pd(theta_ref):
        return lambda m: (G + kp * (theta_ref - m.theta) - kd * m.thetad) / N

    # start undeflected (theta = q): the links sag until K (theta - q) = G(q)
    flex.reset(Q0, theta=Q0.copy())
    flex.simulate(motor_pd(theta_star), 3.0)
    assert np.abs(flex.qd).max() < 1e-6
    np.testing.assert_allclose(flex.joint_torque, lrmate.gravity(flex.q), atol=1e-6 * np.abs(G).max())
    np.testing.assert_allclose(flex.q, Q0, atol=1e-6)
    # a motor that ignores the wind-up (theta = q_ref) leaves the links sagging by ~K^-1 G
    flex.reset(Q0)
    flex.simulate(motor_pd(Q0.copy()), 3.0)
    sag = flex.q - Q0
    np.testing.assert_allclose(K * flex.deflection, lrmate.gravity(flex.q), atol=1e-6 * np.abs(G).max())
    np.testing.assert_allclose(sag, -G / K, rtol=0.05, atol=1e-6)
    assert np.abs(sag).max() > 1e-4


@pytest.mark.parametrize("mode", [0, 1])
def test_resonance_matches_the_linearised_model(mode):
    robot = Robot.load("scara2")  # horizontal: G = 0, pure elastic modes
    p = FlexibleJointParams(stiffness=[800.0, 300.0], damping=0.0, rotor_inertia=[1e-4, 5e-5],
                            motor_friction=0.0, gear_ratio=[50.0, 40.0])
    flex = FlexibleJointModel(robot, p, dt=1e-3, substeps=10)
    q0 = np.array([0.3, 0.8])
    f = flex.resonance_frequencies(q0)
    assert f.shape == (2,) and 5 < f[0] < f[1] < 200
    # excite one elastic mode from its shape
    from scipy.linalg import eigh

    M = robot.mass_matrix(q0)
    K = np.diag(p.stiffness)
    J = np.diag(flex.params.reflected_inertia)
    Kf = np.block([[K, -K], [-K, K]])
    Mf = np.block([[M, np.zeros((2, 2))], [np.zeros((2, 2)), J]])
    w2, V = eigh(Kf, Mf)
    v = V[:, 2 + mode]
    v = 1e-4 * v / np.abs(v).max()
    flex.reset(q0 + v[:2], theta=q0 + v[2:])
    out = flex.simulate(lambda m: np.zeros(2), 0.6)
    x = out["q"][:, int(np.argmax(np.abs(v[:2])))] - q0[int(np.argmax(np.abs(v[:2])))]
    s = np.signbit(x)
    crossings = np.flatnonzero(s[1:] != s[:-1])
    # linear interpolation of the crossing times
    tc = out["t"][crossings] - x[crossings] * (out["t"][crossings + 1] - out["t"][crossings]) / (
        x[crossings + 1] - x[crossings])
    measured = 0.5 / np.mean(np.diff(tc))
    assert measured == pytest.approx(f[mode], rel=2e-3)  # measured within 5e-4


def test_bad_input(lrmate):
    flex = FlexibleJointModel(lrmate)
    with pytest.raises(NotFinite):
        flex.step([np.nan] * 6)
    with pytest.raises(ShapeError):
        flex.step(np.zeros(3))
    with pytest.raises(InvalidInput):
        FlexibleJointParams.lrmate(stiffness=-1.0).checked(6)


def test_joint_controller_on_the_flexible_arm(lrmate):
    """Fig. 2.3 controller on motor encoders: stiff joints track like the rigid arm; soft joints
    leave the links sagging by K^-1 G(q) (the motor cannot see the spring wind-up)."""
    T = 1.5
    t = np.arange(0.0, T, 1e-3)
    s, sd = 0.5 - 0.5 * np.cos(np.pi * t / T), 0.5 * np.pi / T * np.sin(np.pi * t / T)
    sdd = 0.5 * (np.pi / T) ** 2 * np.cos(np.pi * t / T)
    dq = np.array([1.0, 0.5, 0.4, 1.0, 0.8, 1.5])
    for params, bound in ((FlexibleJointParams.lrmate(stiffness=1e8, damping=1e3), 2e-5),
                          (FlexibleJointParams.lrmate(), None)):
        flex = FlexibleJointModel(lrmate, params)
        ctl = flex.controller()
        flex.reset(Q0)
        err = []
        for k in range(len(t)):
            q_ref = Q0 + s[k] * dq
            err.append(flex.q - q_ref)
            flex.track(ctl, q_ref, sd[k] * dq, sdd[k] * dq)
        err = np.array(err)
        q_end = Q0 + dq
        for _ in range(1000):
            flex.track(ctl, q_end)
        if bound is not None:
            assert np.abs(err).max() < bound  # measured 7.6e-6
        else:
            sag = -lrmate.gravity(q_end) / params.stiffness
            np.testing.assert_allclose(flex.q - q_end, sag, atol=2e-6)
            assert np.abs(sag).max() > 1e-4
            np.testing.assert_allclose(flex.theta, q_end, atol=1e-6)
    with pytest.raises(InvalidInput):
        flex.track(ctl, q_end, measure="elbow")
