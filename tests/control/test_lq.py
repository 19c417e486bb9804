"""Computed torque (3.9) around discrete LQ tracking (3.7)-(3.8): robointel.control.lq."""
import numpy as np
import pinocchio as pin
import pytest

from robointel.control import ComputedTorqueLQ, double_integrator, lq_gain
from robointel.errors import InvalidInput
from robointel.robot import Robot


def test_gain_solves_the_riccati_equation_and_stabilises():
    A, B = double_integrator(3, 0.008)
    Q, R = np.diag([1.0] * 3 + [1e-3] * 3), 1e-6 * np.eye(3)
    K, P = lq_gain(A, B, Q, R)
    residual = A.T @ P @ A - A.T @ P @ B @ np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A) + Q - P
    assert np.max(np.abs(residual)) < 1e-6 * np.max(np.abs(P))
    assert np.max(np.abs(np.linalg.eigvals(A - B @ K))) < 1.0


def test_lrmate_tracks_a_reference_through_its_real_dynamics():
    """The 6-DoF arm, integrated with Pinocchio's forward dynamics (ABA) at 1 kHz, follows the reference."""
    robot = Robot.load("lrmate200id7l")
    ctl = ComputedTorqueLQ(robot, dt=0.001)
    data = robot.model.createData()
    q0 = np.array([0.0, 0.3, -0.2, 0.0, -0.6, 0.0])
    amp, w = np.array([0.3, 0.2, 0.2, 0.4, 0.3, 0.5]), 2 * np.pi * 0.5

    def ref(t):
        return q0 + amp * np.sin(w * t), amp * w * np.cos(w * t), -amp * w * w * np.sin(w * t)

    q, qd = q0 + 0.02, np.zeros(6)  # start off the reference
    err = []
    for k in range(2000):
        t = k * 0.001
        q_r, qd_r, qdd_r = ref(t)
        tau = ctl.torque(q, qd, q_r, qd_r, qdd_r)
        qdd = pin.aba(robot.model, data, q, qd, tau - robot.viscous * qd)
        qd = qd + qdd * 0.001  # semi-implicit Euler
        q = q + qd * 0.001
        err.append(np.abs(q - ref(t + 0.001)[0]))
    err = np.array(err)
    assert err[0].max() > 0.01  # it started off
    assert err[-500:].max() < 2e-3, err[-500:].max(axis=0)  # and converged onto the moving reference


def test_bad_weights_are_refused():
    with pytest.raises(InvalidInput):
        ComputedTorqueLQ(Robot.load("scara2"), r_weight=0.0)
