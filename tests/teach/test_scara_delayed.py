"""The SCARA run as the dissertation's system: frames on their own clock, the whole loop a known delay late."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.robot import Robot
from robointel.teach.scara import (
    LinePredictor,
    ScaraSettings,
    delay_aligned_rms,
    received_frames,
    recorded_angles,
    required_torques,
    simulate_scara,
)
from robointel.teach.skeleton import NOT_TRACKED, read_kinect_csv, synthetic_wave


@pytest.fixture(scope="module")
def scara():
    return Robot.load("scara2")


@pytest.fixture(scope="module")
def wave():
    return synthetic_wave(3.0, dropout_at=1.5)


def _best_lag(run, sk, robot):
    lags = np.round(np.arange(0.06, 0.26, 0.01), 2)
    rms = [delay_aligned_rms(run, sk, delay=d, robot=robot).sum() for d in lags]
    return float(lags[int(np.argmin(rms))])


def test_received_frames_keep_their_capture_times_and_drop_the_untrusted(wave):
    t, q = received_frames(wave)
    hand = wave.index("HandRight")
    lost = wave.state[:, hand] <= NOT_TRACKED
    assert lost.any() and len(t) == wave.n - lost.sum()            # the dropout is a gap, not held frames
    assert np.array_equal(t, wave.t[~lost])                        # each frame at its own capture time
    # where the recording is good, the received angles are the recorded ones (no low-pass, same convention)
    t_r, q_r = recorded_angles(wave)
    near = np.abs(t_r[:, None] - t[None, :])
    same = near.min(axis=1) < 1e-6                                  # a grid sample at a frame's time
    far = np.abs(t_r[:, None] - wave.t[lost][None, :]).min(axis=1) > 0.1
    common = same & far
    assert common.sum() > 0.8 * len(t_r)
    assert np.allclose(q[near.argmin(axis=1)[common]], q_r[common], atol=1e-6)


def test_line_predictor_interpolates_and_extrapolates():
    p = LinePredictor()
    p.update(0.0, [1.0, -1.0])
    assert np.allclose(p.predict(0.5)[0], [1.0, -1.0])             # one frame: held
    p.update(0.1, [1.2, -1.3])
    q, v = p.predict(0.05)
    assert np.allclose(q, [1.1, -1.15]) and np.allclose(v, [2.0, -3.0])
    assert np.allclose(p.predict(0.15)[0], [1.3, -1.45])
    p.reset()
    assert p.t is None


def test_delayed_tracking_is_late_by_the_delay_only(scara, wave):
    r0 = simulate_scara(wave, robot=scara, latency=0.1)              # the received frames, resampled and filtered
    rd = simulate_scara(wave, ScaraSettings.delayed_tracking(0.1), robot=scara)
    assert rd.latency == 0.1 and not rd.compensated
    assert rd.tracking_rms.max() < 0.01                              # the robot follows its reference
    lag0, lagd = _best_lag(r0, wave, scara), _best_lag(rd, wave, scara)
    assert lagd < lag0 and 0.09 <= lagd <= 0.12                      # the resampling/low-pass/hold lag is gone
    assert np.all(delay_aligned_rms(rd, wave, delay=0.1, robot=scara) <
                  delay_aligned_rms(r0, wave, delay=0.1, robot=scara))
    # a faster sensor with the rest of the 0.1 s spent interpolating between frames: closer still
    rb = simulate_scara(wave, ScaraSettings.delayed_tracking(0.1, latency=0.1 - 1 / 30), robot=scara,
                        predictor=LinePredictor())
    assert (delay_aligned_rms(rb, wave, delay=0.1, robot=scara).sum()
            < delay_aligned_rms(rd, wave, delay=0.1, robot=scara).sum())


def test_delay_settings_are_checked():
    with pytest.raises(InvalidInput):
        ScaraSettings(delay=0.1, compensate=True)                    # aim at t - delay, or predict t: not both
    with pytest.raises(InvalidInput):
        ScaraSettings(delay=-0.1)
    with pytest.raises(InvalidInput):
        ScaraSettings(clock="resampled")
    s = ScaraSettings.delayed_tracking(0.1)
    assert (s.latency, s.delay, s.clock) == (0.1, 0.1, "frames")


def test_required_torques_are_the_inverse_dynamics(scara):
    t = np.linspace(0.0, 2.0, 61)
    q = np.stack([0.5 * np.sin(2 * t), 0.4 * np.sin(3 * t)], axis=1)
    tg, tau, qd = required_torques(t, q, scara)
    k = len(tg) // 2
    qk = np.array([0.5 * np.sin(2 * tg[k]), 0.4 * np.sin(3 * tg[k])])
    qdk = np.array([np.cos(2 * tg[k]), 1.2 * np.cos(3 * tg[k])])
    qddk = np.array([-2.0 * np.sin(2 * tg[k]), -3.6 * np.sin(3 * tg[k])])
    expect = scara.inverse_dynamics(qk, qdk, qddk) + scara.viscous * qdk   # Pinocchio RNEA + viscous friction
    assert np.allclose(qd[k], qdk, atol=1e-3) and np.allclose(tau[k], expect, rtol=1e-2, atol=1e-2)
    with pytest.raises(InvalidInput):
        required_torques(t, q[:, :1], scara)


def test_recorded_kinect_angles_ask_more_than_the_scara_has(scara, shared_data):
    # following the recorded angles (Kinect noise and all) exactly needs torques beyond the effort limits
    sk = read_kinect_csv(shared_data("kinect", "Ges01_wavehand.csv"))
    t, q = recorded_angles(sk)
    _, tau, _ = required_torques(t, q, scara)
    assert np.mean(np.any(np.abs(tau) > scara.effort_limit, axis=1)) > 0.02
