"""control/: each controller written once; checked against the code it replaces and physical properties."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robointel.control import (
    AdmittanceController,
    AdmittanceGains,
    JerkLimitedFollower,
    PayloadCompensation,
    damped_pinv,
)
from robointel.errors import InvalidInput


def test_follower_respects_limits_and_reaches_a_moving_target():
    v, a, j = np.array([1.0, 2.0]), np.array([5.0, 5.0]), np.array([100.0, 100.0])
    f = JerkLimitedFollower(v, a, j, dt=0.001)
    f.reset([0.0, 0.0])
    qs, qds, qdds = [], [], []
    for k in range(3000):
        t = k * 0.001
        q, qd, qdd = f.step([0.5 + 0.1 * t, -0.3], [0.1, 0.0])
        qs.append(q), qds.append(qd), qdds.append(qdd)
    qds, qdds = np.array(qds), np.array(qdds)
    assert np.all(np.abs(qds) <= v + 1e-9) and np.all(np.abs(qdds) <= a + 1e-9)
    jerk = np.diff(qdds, axis=0) / 0.001
    assert np.all(np.abs(jerk) <= j + 1e-6)
    np.testing.assert_allclose(qs[-1], [0.5 + 0.1 * 2.999, -0.3], atol=2e-3)
    with pytest.raises(InvalidInput):
        JerkLimitedFollower([1.0], [0.0], [1.0])


def test_follower_matches_the_imitation_follower_it_replaces():
    from robointel.programming.imitation import LimitedFollower

    old = LimitedFollower(3, 2.0, 8.0, 80.0, dt=0.001)
    new = JerkLimitedFollower([2.0] * 3, 8.0, 80.0, dt=0.001)
    old.reset(np.zeros(3)), new.reset(np.zeros(3))
    rng = np.random.default_rng(0)
    for _ in range(200):
        tgt = rng.normal(size=3)
        for _ in range(5):
            np.testing.assert_allclose(new.step(tgt)[0], old.step(tgt)[0], atol=1e-12)


def test_payload_compensation_removes_weight_at_any_orientation():
    p = PayloadCompensation(1.3, np.array([0.0, 0.01, 0.05]), np.array([0.2, -0.1, 0.3]), np.array([0.01, 0, 0]))
    R = Rotation.random(20, random_state=1).as_matrix()
    ext = np.array([1.0, 2.0, 3.0, 0.1, 0.2, 0.3])
    readings = p.payload_wrench(R) + ext
    np.testing.assert_allclose(p.compensate(readings, R), np.tile(ext, (20, 1)), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(p.payload_wrench(R)[:, :3] - p.force_bias, axis=1), 1.3 * 9.81)
    from robointel.programming.ft_identification import FTCalibration

    old = FTCalibration(1.3, p.com, p.force_bias, p.torque_bias, 0.0, 0.0)
    np.testing.assert_allclose(p.compensate(readings, R), old.compensate(readings, R), atol=1e-12)
    with pytest.raises(InvalidInput):
        p.compensate(readings[0], R)


def test_admittance_moves_the_tcp_along_the_push(lrmate):
    ctl = AdmittanceController(lrmate, 0.008, AdmittanceGains(translational=0.07, force_deadband=1.0))
    q = np.array([0.0, 0.2, -0.3, 0.0, -0.8, 0.0])
    p0 = lrmate.fk(q)[:3, 3]
    push = np.array([0.0, 20.0, 0.0, 0, 0, 0])
    for _ in range(50):
        q = ctl.step(q, push)
    d = lrmate.fk(q)[:3, 3] - p0
    expected = 0.07 * 19.0 * 50 * 0.008  # (|f| - deadband) K_d t
    assert d[1] == pytest.approx(expected, rel=0.05) and abs(d[0]) < 0.02 * expected
    assert np.all(ctl.step(q, np.zeros(6)) == q)  # inside the deadband: no motion
    J = lrmate.jacobian(q)
    np.testing.assert_allclose(damped_pinv(J) @ J, np.eye(6), atol=1e-8)
