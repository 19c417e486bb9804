"""F/T sensor identification (3.14)-(3.20) on synthetic readings."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robointel.errors import InvalidInput
from robointel.teach.ft_identification import FTCalibration, identify_ft


def _readings(rng, n=40, noise=(0.0, 0.0)):
    R = Rotation.random(n, random_state=rng.integers(1 << 31)).as_matrix()
    truth = FTCalibration(mass=1.3, com=np.array([0.01, -0.02, 0.07]), force_bias=np.array([2.0, -1.0, 4.0]),
                          torque_bias=np.array([0.1, 0.05, -0.2]), force_rms=0, torque_rms=0)
    W = truth.payload_wrench(R)
    W[:, :3] += rng.normal(0, noise[0], (n, 3))
    W[:, 3:] += rng.normal(0, noise[1], (n, 3))
    return W, R, truth


def test_exact_recovery_noise_free():
    W, R, truth = _readings(np.random.default_rng(1))
    cal = identify_ft(W, R)
    assert cal.mass == pytest.approx(truth.mass, rel=1e-12)
    np.testing.assert_allclose(cal.com, truth.com, atol=1e-12)
    np.testing.assert_allclose(cal.force_bias, truth.force_bias, atol=1e-10)
    np.testing.assert_allclose(cal.torque_bias, truth.torque_bias, atol=1e-10)
    assert cal.force_rms < 1e-10 and cal.torque_rms < 1e-10
    np.testing.assert_allclose(cal.compensate(W, R), 0, atol=1e-10)


def test_noisy_recovery_and_residual_at_noise_level():
    rng = np.random.default_rng(2)
    W, R, truth = _readings(rng, n=200, noise=(0.05, 0.002))
    cal = identify_ft(W, R)
    assert abs(cal.mass - truth.mass) / truth.mass < 0.01
    assert np.linalg.norm(cal.com - truth.com) / np.linalg.norm(truth.com) < 0.01
    assert cal.force_rms == pytest.approx(0.05, rel=0.2)
    assert cal.torque_rms == pytest.approx(0.002, rel=0.2)
    # an external push is recovered after compensation
    push = np.array([5.0, 0, -3.0, 0.1, 0.0, 0.0])
    compensated = cal.compensate(W[0] - rng.normal(0, 0, 6) + push, R[0])
    np.testing.assert_allclose(compensated - (W[0] - truth.payload_wrench(R[0])), push, atol=0.2)


def test_unexciting_poses_rejected():
    R = np.repeat(np.eye(3)[None], 10, 0)
    with pytest.raises(InvalidInput, match="excite"):
        identify_ft(np.zeros((10, 6)), R)
    with pytest.raises(InvalidInput):
        identify_ft(np.zeros((2, 6)), R[:2])


def test_identification_in_mujoco_with_bias_and_noise():
    """Fig. 3.10: a 0.8 kg tool with an offset CoM on the simulated sensor, with bias and noise:
    mass and CoM within 1%, and compensated readings in new poses at the noise level."""
    from robointel.sim import FTSensor, Payload, Workcell
    from robointel.teach.ft_identification import calibrate_in_workcell

    noise = np.array([0.2, 0.2, 0.2, 0.01, 0.01, 0.01])
    bias = np.array([3.0, -2.0, 5.0, 0.2, -0.1, 0.05])
    com = np.array([0.05, 0.01, -0.02])
    wc = Workcell(ft_sensor=FTSensor(bias=bias, noise_std=noise, seed=1), payload=Payload(mass=0.8, com=com))
    q0 = np.array([0.0, 0.1, -0.1, 0.0, -1.2, 0.0])
    cal = calibrate_in_workcell(wc, q0, poses=12, settle=0.2, average=20)
    assert abs(cal.mass - 0.8) / 0.8 < 0.01
    assert np.linalg.norm(cal.com - com) / np.linalg.norm(com) < 0.01
    np.testing.assert_allclose(cal.force_bias, bias[:3], atol=0.05)
    np.testing.assert_allclose(cal.torque_bias, bias[3:], atol=0.005)
    # live compensation in new poses: residuals are the sensor noise
    rng = np.random.default_rng(7)
    res = []
    for _ in range(4):
        q = q0.copy()
        q[3:] += rng.uniform(-1.0, 1.0, 3)
        wc.reset(q)
        wc.hold(0.2)
        for _ in range(50):
            wc.hold(0.001)
            res.append(cal.compensate(wc.ft_reading(), wc.sensor_pose()[:3, :3]))
    res = np.array(res)
    assert np.all(np.abs(res.mean(0)) < 3 * noise)
    np.testing.assert_allclose(res.std(0), noise, rtol=0.35)
