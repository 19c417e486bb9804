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


def test_follower_position_interface_brake_and_per_period_limits():
    v, a, j = np.array([1.0, 2.0]), np.array([5.0, 5.0]), np.array([100.0, 100.0])
    f = JerkLimitedFollower(v, a, j, dt=0.001, lower=[-1.0, -1.0], upper=[1.0, 1.0])
    f.reset([0.0, 0.0])
    # position interface: reaches the target state and rests there
    for _ in range(2000):
        q, qd, qdd = f.step_position([0.4, -0.6])
    np.testing.assert_allclose(q, [0.4, -0.6], atol=1e-9)
    assert f.at_rest
    # a brake from full speed stops within the (changed, asymmetric) limits
    f.reset([0.0, 0.0], [0.9, -1.5])
    f.set_limits(min_acceleration=[-2.0, -4.0], max_acceleration=[3.0, 1.0], max_jerk=[50.0, 50.0])
    qdds = []
    for _ in range(3000):
        q, qd, qdd = f.brake()
        qdds.append(qdd)
        assert np.all(q >= -1.0) and np.all(q <= 1.0)
    qdds = np.array(qdds)
    assert f.at_rest
    assert np.all(qdds >= [-2.0 - 1e-9, -4.0 - 1e-9]) and np.all(qdds <= [3.0 + 1e-9, 1.0 + 1e-9])
    assert np.all(np.abs(np.diff(qdds, axis=0)) / 0.001 <= 50.0 + 1e-6)
    with pytest.raises(InvalidInput):
        f.set_limits(min_acceleration=[1.0, -1.0])
    with pytest.raises(InvalidInput):
        JerkLimitedFollower(v, a, j, brake_share=0.0)


def test_jerk_limited_reference_goes_through_the_one_follower(monkeypatch):
    import robointel.teach.imitation as imitation

    made = []

    class Spy(JerkLimitedFollower):
        def __init__(self, *args, **kw):
            super().__init__(*args, **kw)
            made.append(self)

    monkeypatch.setattr(imitation, "JerkLimitedFollower", Spy)
    t = np.linspace(0.0, 1.0, 11)
    ref = imitation.jerk_limited(t, np.c_[np.sin(t), t], [2.0, 2.0], [8.0, 8.0], [80.0, 80.0])
    assert len(made) == 1 and ref.q.shape == (1001, 2)
    assert np.all(np.abs(ref.qdd) <= 8.0 + 1e-9)


def test_payload_compensation_removes_weight_at_any_orientation():
    p = PayloadCompensation(1.3, np.array([0.0, 0.01, 0.05]), np.array([0.2, -0.1, 0.3]), np.array([0.01, 0, 0]))
    R = Rotation.random(20, random_state=1).as_matrix()
    ext = np.array([1.0, 2.0, 3.0, 0.1, 0.2, 0.3])
    readings = p.payload_wrench(R) + ext
    np.testing.assert_allclose(p.compensate(readings, R), np.tile(ext, (20, 1)), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(p.payload_wrench(R)[:, :3] - p.force_bias, axis=1), 1.3 * 9.81)
    from robointel.teach.ft_identification import FTCalibration

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
