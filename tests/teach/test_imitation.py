"""Kinematic imitation (3.1) on the LR Mate: IK continuity, limits, MuJoCo tracking."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.teach.imitation import (
    TOOL_DOWN,
    WORKSPACE_HI,
    WORKSPACE_LO,
    fit_workspace,
    jerk_limited,
    kinematic_imitation,
    simulate_imitation,
    solve_ik_path,
)
from robointel.teach.skeleton import read_kinect_csv, synthetic_wave


def test_workspace_map_fits_box():
    rng = np.random.default_rng(0)
    d = rng.normal(0, 0.3, (200, 3))
    m = fit_workspace(d)
    p = m(d)
    assert np.all(p >= WORKSPACE_LO - 1e-9) and np.all(p <= WORKSPACE_HI + 1e-9)
    # uniform scale: shape preserved (distances scale by one factor)
    r = np.linalg.norm(p[1:] - p[:-1], axis=1) / np.linalg.norm(d[1:] - d[:-1], axis=1)
    np.testing.assert_allclose(r, m.scale)
    with pytest.raises(InvalidInput):
        fit_workspace(d, lo=[0, 0, 0], hi=[0, 1, 1])


def test_ik_path_continuous_and_exact(lrmate):
    t = np.linspace(0, 2 * np.pi, 120)
    p = np.stack([0.45 + 0.1 * np.cos(t), 0.25 * np.sin(t), 0.35 + 0.1 * np.sin(2 * t)], 1)
    q, ok = solve_ik_path(lrmate, p, TOOL_DOWN)
    assert ok.all()
    assert np.abs(np.diff(q, axis=0)).max() < 0.1  # no branch flips between frames
    for qi, pi in zip(q[::10], p[::10]):
        T = lrmate.fk(qi)
        np.testing.assert_allclose(T[:3, 3], pi, atol=1e-8)
        np.testing.assert_allclose(T[:3, :3], TOOL_DOWN, atol=1e-8)


def test_unreachable_frames_hold(lrmate):
    p = np.array([[0.45, 0.0, 0.35], [3.0, 0.0, 0.35], [0.45, 0.05, 0.35]])
    q, ok = solve_ik_path(lrmate, p, TOOL_DOWN)
    assert ok.tolist() == [True, False, True]
    np.testing.assert_array_equal(q[1], q[0])


def test_jerk_limited_reference_respects_limits():
    t = np.linspace(0, 2, 61)
    q = np.stack([0.5 + 0.5 * np.tanh(20 * (t - 0.8)), np.sin(4 * t)], 1)  # a quick move and a fast sine
    vmax, amax, jmax = np.array([3.0, 2.0]), np.array([6.0, 8.0]), np.array([80.0, 160.0])
    ref = jerk_limited(t, q, vmax, amax, jmax)
    assert ref.t[0] == t[0] and ref.t[-1] == pytest.approx(t[-1]) and ref.n_joints == 2
    Q, QD, QDD = ref.q, ref.qd, ref.qdd
    assert np.all(np.abs(QD) <= vmax + 1e-9) and np.all(np.abs(QDD) <= amax + 1e-9)
    jerk = np.abs(np.diff(QDD, axis=0)) / 1e-3
    assert np.all(jerk <= jmax * (1 + 1e-6) + 1e-6)
    assert abs(Q[-1, 0] - 1.0) < 1e-3  # reaches the end of the move without overshooting it
    assert Q[:, 0].max() < 1.0 + 0.02  # catching up never overshoots by more than 2 %


def test_imitation_synthetic_in_mujoco(lrmate):
    plan = kinematic_imitation(synthetic_wave(3.0, dropout_at=1.5), lrmate)
    assert plan.reachable.all()
    assert np.all(np.abs(plan.trajectory.qd) <= lrmate.velocity_limit + 1e-9)
    assert np.all(np.abs(plan.trajectory.qdd) <= lrmate.acceleration_limit + 1e-9)
    run = simulate_imitation(plan, lrmate)
    assert run.tracking_rms.max() < 0.005       # the 1 kHz controller follows the reference
    assert run.tcp_rms < 0.15 and not run.log.collided
    assert run.outcome.success and run.outcome.figures["unreachable_fraction"] == 0.0
    assert run.outcome.figures["max_tracking_rms_rad"] == float(run.tracking_rms.max())


def test_imitation_recording_in_mujoco(lrmate, shared_data):
    sk = read_kinect_csv(shared_data("kinect", "Ges01_wavehand.csv"))
    run = simulate_imitation(kinematic_imitation(sk, lrmate), lrmate)
    assert run.plan.reachable.all()
    assert run.rms.max() < 0.02           # joints follow the per-frame IK targets
    assert run.tcp_rms < 0.01             # the TCP follows the scaled hand within 1 cm


def test_cli_imitate_writes_plots(tmp_path):
    from typer.testing import CliRunner

    from robointel.cli import app

    res = CliRunner().invoke(app, ["imitate", "synthetic", "--scara", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "lrmate_imitation.png").stat().st_size > 10_000
    assert (tmp_path / "scara_imitation.png").stat().st_size > 10_000
    assert "0.153" in res.output  # the dissertation's figure printed beside ours
    bad = CliRunner().invoke(app, ["imitate", str(tmp_path / "missing.csv")])
    assert bad.exit_code == 2 and "error" in bad.output


def test_demo_stage_runs_without_shared_data(tmp_path, monkeypatch):
    monkeypatch.setenv("ROBOINTEL_DATA", str(tmp_path / "nowhere"))
    from robointel.commands import teach
    from robointel.report.demo import run_demo

    html = run_demo([teach.demo_stage], tmp_path, quick=True).read_text()
    assert "Imitation from human motion" in html and "synthetic" in html
    assert "0.153 / 0.185" in html and html.count("data:image/png;base64") == 2
