"""Dynamic imitation on the 2-link SCARA: DARE gain, computed torque, latency and compensation."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.robot import Robot
from robointel.teach.scara import (
    ARPredictor,
    ComputedTorqueLQ,
    KalmanPredictor,
    arm_angles,
    double_integrator,
    fit_predictor,
    lq_gain,
    simulate_scara,
)
from robointel.teach.skeleton import read_bvh, read_kinect_csv, synthetic_wave, synthetic_wave_bvh


@pytest.fixture(scope="module")
def scara():
    return Robot.load("scara2")


def test_dare_gain_is_optimal_and_stable():
    A, B = double_integrator(2, 0.001)
    Q, R = np.diag([1, 1, 1e-3, 1e-3]), 1e-8 * np.eye(2)
    K, P = lq_gain(A, B, Q, R)
    # P solves (3.7) and the closed loop is stable
    res = A.T @ P @ A - A.T @ P @ B @ np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A) + Q - P
    assert np.abs(res).max() < 1e-6 * np.abs(P).max()
    assert np.abs(np.linalg.eigvals(A - B @ K)).max() < 1.0


def test_arm_angles_recover_bvh_joint_angles():
    sk = read_bvh(synthetic_wave_bvh(3.0))
    q = arm_angles(sk, "right")
    # the forearm-upper arm angle is the BVH elbow flexion in the arm's plane (|angle| 25..95 deg)
    assert np.degrees(np.abs(q[:, 1])).min() > 15 and np.degrees(np.abs(q[:, 1])).max() < 100


def test_computed_torque_tracks_in_mujoco(scara):
    from robointel.sim import Workcell

    wc = Workcell(scara, table=False, ft_sensor=False)
    ctrl = ComputedTorqueLQ(scara)
    wc.reset(np.zeros(2), np.array([1.0, 1.2]))
    err = []
    for k in range(2000):
        t = k * 1e-3
        qr = np.array([0.5 * np.sin(2 * t), 0.4 * np.sin(3 * t)])
        qdr = np.array([1.0 * np.cos(2 * t), 1.2 * np.cos(3 * t)])
        qddr = np.array([-2.0 * np.sin(2 * t), -3.6 * np.sin(3 * t)])
        wc.step(ctrl.torque(wc.q, wc.qd, qr, qdr, qddr))
        err.append(wc.q - np.array([0.5 * np.sin(2 * (t + 1e-3)), 0.4 * np.sin(3 * (t + 1e-3))]))
    assert np.abs(err).max() < 2e-3  # model-exact computed torque: the plant is a double integrator


def test_kalman_predictor_extrapolates_ramp():
    kf = KalmanPredictor(1, accel_psd=10.0, meas_std=0.01)
    for k in range(60):
        kf.update(k / 30, np.array([0.5 * k / 30]))
    q, qd = kf.predict(59 / 30 + 0.1)
    assert abs(qd[0] - 0.5) < 0.02 and abs(q[0] - 0.5 * (59 / 30 + 0.1)) < 0.005


def test_latency_shows_and_tracking_is_tight(scara):
    sk = synthetic_wave(4.0, dropout_at=2.0, speed=0.5)
    r0 = simulate_scara(sk, robot=scara, latency=0.0)
    r1 = simulate_scara(sk, robot=scara, latency=0.1)
    assert r1.rms.mean() > r0.rms.mean()             # the latency costs imitation accuracy
    assert r1.tracking_rms.max() < 0.01              # the controller follows what it receives
    rc = simulate_scara(sk, robot=scara, latency=0.1, compensate=True)
    assert rc.rms.mean() < r1.rms.mean()             # prediction recovers part of the delay
    ro = simulate_scara(sk, robot=scara, offline=True)
    assert ro.offline and ro.rms.max() < 0.02        # a stored recording, no latency: tight imitation
    assert ro.rms.mean() < rc.rms.mean()


def test_recording_runs(scara, shared_data):
    sk = read_kinect_csv(shared_data("kinect", "Ges01_wavehand.csv"))
    r = simulate_scara(sk, robot=scara)
    assert np.all(np.isfinite(r.q)) and r.rms.shape == (2,)
    assert np.all(np.abs(r.q) <= scara.upper + 0.05)


def test_bad_latency(scara):
    with pytest.raises(InvalidInput):
        simulate_scara(synthetic_wave(1.0), robot=scara, latency=-0.1)
    with pytest.raises(InvalidInput):
        simulate_scara(synthetic_wave(1.0), robot=scara, smooth_hz=200.0)  # unstable at 1 kHz
    with pytest.raises(InvalidInput):
        simulate_scara(synthetic_wave(1.0), robot=scara, shaping="spline")
    with pytest.raises(InvalidInput):
        simulate_scara(synthetic_wave(1.0), robot=scara, blend_time=0.0)
    with pytest.raises(InvalidInput):
        ComputedTorqueLQ(scara, r_weight=0.0)


def test_ar_predictor_learns_a_ramp_and_resets():
    # frames of ramps with different slopes: q(t_k + h) - q_k = slope * h = (q_k - q_{k-1}) h / T
    T, runs = 1 / 30, []
    for slope in (-1.0, 0.5, 2.0):
        t = np.arange(60) * T
        q = np.stack([slope * t, -0.5 * slope * t], 1)
        runs.append((t, q, q))
    ar = ARPredictor.fit(runs, latency=0.1, order=3, alphas=(1e-8,))  # (near) unregularised: exact on ramps
    for k in range(10):
        ar.update(k * T, np.array([1.5 * k * T, 0.3 * k * T]))
    q, qd = ar.predict(9 * T + 0.12)
    assert np.allclose(q, [1.5 * (9 * T + 0.12), 0.3 * (9 * T + 0.12)], atol=2e-3)
    assert np.allclose(qd, [1.5, 0.3], atol=0.02)
    ar.reset()
    assert ar.t is None and ar.hist == []


def test_learned_prediction_compensates_the_latency(scara):
    # predictor fitted on other synthetic takes (different seeds), evaluated on an unseen one
    ar = fit_predictor([synthetic_wave(6.0, seed=s, dropout_at=None) for s in (1, 2, 3)], robot=scara)
    sk = synthetic_wave(6.0, seed=0, dropout_at=3.0)
    r0 = simulate_scara(sk, robot=scara, latency=0.1)
    r1 = simulate_scara(sk, robot=scara, latency=0.1, compensate=True, predictor=ar)
    assert r1.compensated and not r0.compensated
    # the prediction is much closer to the true human angles than the delayed frames are ...
    assert r1.prediction_rms.sum() < 0.6 * r0.prediction_rms.sum()
    assert np.allclose(r0.prediction_rms, np.sqrt(np.mean((r0.q_delayed - r0.q_human) ** 2, 0)))
    # ... and the robot driven by it imitates better (same shaping, same controller)
    assert r1.rms.sum() < 0.9 * r0.rms.sum()
    r2 = simulate_scara(sk, robot=scara, latency=0.1, compensate=True, predictor=ar)
    assert np.array_equal(r1.q, r2.q)                               # the predictor is reset: deterministic


def test_crossfade_is_smooth_and_lands_on_the_frames(scara):
    sk = synthetic_wave(3.0, dropout_at=None, speed=0.5)
    r = simulate_scara(sk, robot=scara, latency=0.1, blend_time=0.05)
    step_ref = np.abs(np.diff(r.q_ref, axis=0)).max()
    step_frames = np.abs(np.diff(r.q_delayed, axis=0)).max()
    assert step_ref < 0.1 * step_frames                             # no jumps at frame arrivals
    # 50 ms after an arrival the crossfade is over: the reference is the received frame itself
    t_h = sk.t[0] + np.arange(len(sk.t)) / sk.rate
    settled = np.zeros(len(r.t), bool)
    for a in t_h[1:] + 0.1:
        settled |= (r.t >= a + 0.05 + 1e-9) & (r.t < a + 1 / sk.rate - 2e-3)
    assert settled.sum() == 0 or np.abs(r.q_ref[settled] - r.q_delayed[settled]).max() < 1e-9


def test_torque_limit_scales_the_acceleration(scara):
    ctrl = ComputedTorqueLQ(scara)
    q, qd = np.array([0.3, 1.0]), np.array([0.5, -0.2])
    tau = ctrl.torque(q, qd, q + np.array([2.0, -1.0]), qd, np.zeros(2))  # far off: far beyond the limits
    assert np.all(np.abs(tau) <= scara.effort_limit + 1e-9) and np.any(np.isclose(np.abs(tau), scara.effort_limit))
    b = scara.nonlinear_effects(q, qd) + scara.viscous * qd
    u_applied = np.linalg.solve(scara.mass_matrix(q), tau - b)
    u_wanted = -ctrl.K @ np.concatenate([-np.array([2.0, -1.0]), np.zeros(2)])
    cos = u_applied @ u_wanted / (np.linalg.norm(u_applied) * np.linalg.norm(u_wanted))
    assert cos > 0.999 and np.linalg.norm(u_applied) < np.linalg.norm(u_wanted)  # same direction, scaled down


def test_ar_predictor_rejects_bad_weights():
    with pytest.raises(InvalidInput):
        ARPredictor(np.ones(7), order=3, poly=1)
    with pytest.raises(InvalidInput):
        ARPredictor(np.full(12, np.nan), order=3, poly=1)
    ar = ARPredictor(np.zeros(12), order=3, poly=1)
    with pytest.raises(InvalidInput):
        ar.update(0.0, np.zeros(3))


def test_plot_has_the_predicted_signal(scara, tmp_path):
    from robointel.teach.scara import plot_scara

    sk = synthetic_wave(2.0, dropout_at=None)
    r0 = simulate_scara(sk, robot=scara)
    r1 = simulate_scara(sk, robot=scara, compensate=True)
    assert r1.q_pred.shape == r1.q.shape and not np.allclose(r1.q_pred, r1.q_delayed)
    plot_scara([r0, r1], tmp_path / "fig.png")
    assert (tmp_path / "fig.png").stat().st_size > 10_000


def test_offline_exact_reference_is_tracked(scara):
    ro = simulate_scara(synthetic_wave(4.0, speed=0.5), robot=scara, offline=True, follower=False)
    assert ro.rms.max() < 2e-3 and ro.saturated < 0.01


def test_training_predictor_leaves_the_recording_out(monkeypatch, shared_data):
    from robointel.io import reference
    from robointel.teach.scara import training_predictor

    ar, what = training_predictor("Ges01_wavehand.csv")
    assert what == "6 other Kinect recordings" and isinstance(ar, ARPredictor)
    monkeypatch.setattr(reference, "data_root", lambda: None)  # no reference data on this machine
    ar, what = training_predictor("Ges01_wavehand.csv")
    assert what == "3 synthetic arm waves" and np.all(np.isfinite(ar.w))


def test_flexion_elbow_never_wraps(shared_data):
    from robointel.teach.scara import human_reference

    sk = read_kinect_csv(shared_data("kinect", "Ges05_demopoint.csv"))
    _, planar, _ = human_reference(sk, elbow="planar")
    _, flex, live = human_reference(sk, elbow="flexion")
    assert planar[:, 1].min() < -np.pi                  # the projected forearm swings past the folded pose
    assert np.all((flex[:, 1] <= 0) & (flex[:, 1] > -np.pi)) and np.all(live[:, 1] <= 0)
    assert np.allclose(flex[:, 0], planar[:, 0])        # the shoulder angle is the same
    with pytest.raises(InvalidInput):
        human_reference(sk, elbow="wrist")


def test_accel_limits_keep_the_torques_within_the_effort_limits(scara):
    from robointel.teach.scara import accel_limits

    rng = np.random.default_rng(0)
    for _ in range(20):
        q, qd = rng.uniform(-2.5, 2.5, 2), rng.uniform(-3, 3, 2)
        b = scara.nonlinear_effects(q, qd) + scara.viscous * qd
        M = scara.mass_matrix(q)
        lo, hi = accel_limits(scara, q, qd, margin=0.9)  # the box: every corner is within the limits
        for corner in ([lo[0], lo[1]], [lo[0], hi[1]], [hi[0], lo[1]], [hi[0], hi[1]]):
            assert np.all(np.abs(M @ corner + b) <= 0.9 * scara.effort_limit + 1e-9)
        qdd = rng.uniform(-20, 20, 2)  # with the other joint's acceleration as it is: each bound is exact
        lo, hi = accel_limits(scara, q, qd, margin=0.9, qdd=qdd)
        for i in range(2):
            for bound, sign in ((lo[i], -1), (hi[i], 1)):
                a = qdd.copy()
                a[i] = bound
                if abs(bound) > 0.1 * 0.9 * scara.effort_limit[i] / M[i, i] + 1e-9:  # not the braking floor
                    assert np.isclose((M @ a + b)[i], sign * 0.9 * scara.effort_limit[i])


def test_feasible_reference_is_followed_within_the_torque_limits(scara):
    from robointel.sim import Workcell
    from robointel.teach.scara import FeasibleReference

    target = np.array([1.2, -1.0])  # a 1.2 / 1.0 rad step: far beyond what the torques allow at once
    errs = {}
    for shaped in (False, True):
        wc = Workcell(scara, table=False, ft_sensor=False)
        wc.reset(np.zeros(2), np.zeros(2))
        ctrl, fr = ComputedTorqueLQ(scara), FeasibleReference(scara)
        fr.reset(np.zeros(2))
        e, need = [], []
        for _ in range(1500):
            q_r, qd_r, qdd_r = fr.step(target, np.zeros(2)) if shaped else (target, np.zeros(2), np.zeros(2))
            if shaped:  # the torque the reference itself needs stays within the effort limits
                need.append(np.abs(scara.mass_matrix(q_r) @ qdd_r + scara.nonlinear_effects(q_r, qd_r)
                                   + scara.viscous * qd_r) / scara.effort_limit)
            wc.step(ctrl.torque(wc.q, wc.qd, q_r, qd_r, qdd_r))
            e.append(np.abs(wc.q - q_r))
        errs[shaped] = np.max(e[100:], axis=0)
        if shaped:
            assert np.max(need) <= 0.9 * 1.02                    # margin 0.9 (+ what one jerk step can add)
            assert np.allclose(q_r, target, atol=1e-3)            # it gets there within 1.5 s
    assert errs[True].max() < 0.02 and errs[False].max() > 0.3    # the robot follows the shaped reference


def test_feasible_reference_rejects_bad_settings(scara):
    from robointel.teach.scara import FeasibleReference

    for kw in ({"margin": 0.0}, {"margin": 1.5}, {"jerk_time": 0.0}, {"mode": "torque"}, {"coupling": "none"}):
        with pytest.raises(InvalidInput):
            FeasibleReference(scara, **kw)


def test_settings_and_keyword_overrides_are_the_same_run(scara):
    from robointel.teach.scara import ScaraSettings

    sk = synthetic_wave(1.0, dropout_at=None)
    a = simulate_scara(sk, ScaraSettings(latency=0.05, blend_time=0.05), robot=scara)
    b = simulate_scara(sk, robot=scara, latency=0.05, blend_time=0.05)
    assert np.array_equal(a.q, b.q) and a.latency == 0.05
    with pytest.raises(InvalidInput):
        simulate_scara(sk, robot=scara, latncy=0.1)                 # a misspelt setting is refused
    with pytest.raises(InvalidInput):
        ScaraSettings(latency=2.5)


def test_recorded_angles_are_bridged_but_not_smoothed():
    from robointel.teach.scara import human_reference, recorded_angles
    from robointel.teach.skeleton import clean

    sk = synthetic_wave(3.0, dropout_at=1.5)
    raw = clean(sk, smooth=False)
    idx = np.searchsorted(sk.t, raw.t - 1e-9).clip(0, sk.n - 1)
    good = ~raw.bridged.any(axis=1) & (np.abs(sk.t[idx] - raw.t) < 1e-9)
    assert good.sum() > 0.8 * len(raw.t)
    assert np.allclose(raw.positions[good], sk.positions[idx[good]])  # the recording's own samples where it is good
    assert raw.bridged.any() and np.all(np.isfinite(raw.positions))  # the dropout is bridged
    t, q_rec = recorded_angles(sk)
    t2, q_true, _ = human_reference(sk)
    assert np.array_equal(t, t2)
    assert 0 < np.sqrt(np.mean((q_rec - q_true) ** 2)) < 0.1          # same convention, differs by the smoothing


def test_delay_aligned_rms_takes_the_known_delay_out(scara):
    from dataclasses import replace

    from robointel.teach.scara import delay_aligned_rms, recorded_angles

    sk = synthetic_wave(3.0, dropout_at=None)
    r0 = simulate_scara(sk, robot=scara, latency=0.1)
    # a robot that were exactly the recorded motion 0.1 s late scores zero
    t_h, q_rec = recorded_angles(sk)
    late = np.stack([np.interp(r0.t - 0.1, t_h, q_rec[:, j]) for j in range(2)], axis=1)
    assert np.allclose(delay_aligned_rms(replace(r0, q=late), sk, delay=0.1, robot=scara), 0.0, atol=1e-12)
    # the live uncompensated robot lags by at least the latency: taking 0.1 s out brings it closer
    aligned = delay_aligned_rms(r0, sk, delay=0.1, robot=scara)
    assert np.all(aligned < r0.rms)
    with pytest.raises(InvalidInput):
        delay_aligned_rms(r0, sk, delay=-0.1, robot=scara)
