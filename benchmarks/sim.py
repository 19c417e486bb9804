"""Simulation: speed of the 1 kHz control loop in the MuJoCo workcell, tracking accuracy, and the
agreement of the MuJoCo model with the Pinocchio robot core.

Ours: ``Workcell.track`` (inertia-scheduled PID + RNEA feed-forward + friction compensation, one
physics step) and ``Workcell.run_trajectory`` (the same plus logging and the F/T sensor). Peer, in
the same run: the loop one writes with MuJoCo alone (fixed-gain PD + MuJoCo's own bias forces
``qfrc_bias`` as feed-forward, ``mj_step``), and bare ``mj_step``.

    python benchmarks/sim.py [--json]
"""
from __future__ import annotations

import argparse
import json
import time

import mujoco
import numpy as np

from _timing import median_us


def test_trajectory(q0, q1, T=2.0, n=201):
    t = np.linspace(0.0, T, n)
    s = 0.5 - 0.5 * np.cos(np.pi * t / T)
    sd = 0.5 * np.pi / T * np.sin(np.pi * t / T)
    sdd = 0.5 * (np.pi / T) ** 2 * np.cos(np.pi * t / T)
    dq = q1 - q0
    return t, q0 + np.outer(s, dq), np.outer(sd, dq), np.outer(sdd, dq)


def model_agreement(robot, samples: int = 200) -> dict:
    from robointel.sim import build_model

    model, _ = build_model(robot, table=False)
    d = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    n = robot.nq
    M = np.zeros((model.nv, model.nv))
    fk = mm = bias = 0.0
    for q in robot.random_configuration(rng, samples):
        qd = rng.uniform(-2, 2, n)
        d.qpos[:n], d.qvel[:n] = q, qd
        mujoco.mj_forward(model, d)
        mujoco.mj_fullM(model, d, M)
        for name, T in robot.link_poses(q).items():
            b = model.body(name).id
            fk = max(fk, np.abs(d.xpos[b] - T[:3, 3]).max(), np.abs(d.xmat[b].reshape(3, 3) - T[:3, :3]).max())
        mm = max(mm, np.abs(M[:n, :n] - robot.mass_matrix(q)).max())
        bias = max(bias, np.abs(d.qfrc_bias[:n] - robot.nonlinear_effects(q, qd)).max())
    return {"fk_max_diff": fk, "mass_matrix_max_diff": mm, "bias_forces_max_diff": bias, "samples": samples}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()

    from robointel.robot import Robot
    from robointel.sim import FlexibleJointModel, Workcell

    robot = Robot.load("lrmate200id7l")
    q0 = np.array([0.0, 0.3, -0.2, 0.0, -0.5, 0.0])
    q1 = np.array([1.0, 0.8, 0.3, 1.0, 0.8, 2.0])
    t, q, qd, qdd = test_trajectory(q0, q1)

    wc = Workcell(robot)
    wc.run_trajectory(t[:3], q[:3], qd[:3], qdd[:3])  # JIT warm-up
    walls, log = [], None
    for _ in range(5):
        w = time.perf_counter()
        log = wc.run_trajectory(t, q, qd, qdd)
        walls.append(time.perf_counter() - w)
    rtf = log.duration / float(np.median(walls))
    # the same trajectory without the model feed-forward (PID only) and with an unmodelled payload
    pid_only = Workcell(robot)
    pid_only.controller.feedforward = False
    log_pid = pid_only.run_trajectory(t, q, qd, qdd, record_ft=False)
    from robointel.sim import Payload

    loaded = Workcell(robot, payload=Payload(2.0, (0.08, 0.0, 0.0)), compensate_payload=False)
    log_pl = loaded.run_trajectory(t, q, qd, qdd, record_ft=False)
    wc.reset(q0)
    ours_track = median_us(lambda: wc.track(q0))

    # peer: plain MuJoCo loop, fixed PD + qfrc_bias feed-forward
    m, d = wc.model, wc.data
    kp = np.array([2000.0, 2000.0, 1000.0, 100.0, 50.0, 10.0])
    kd = 2 * np.sqrt(kp * np.array([1.0, 1.0, 0.3, 0.005, 0.001, 3e-5]))
    eff = robot.effort_limit

    def peer():
        e = q0 - d.qpos[:6]
        d.ctrl[:6] = np.clip(kp * e - kd * d.qvel[:6] + d.qfrc_bias[:6], -eff, eff)
        mujoco.mj_step(m, d)

    wc.reset(q0)
    peer_track = median_us(peer)
    wc.reset(q0)
    bare = median_us(lambda: mujoco.mj_step(m, d))

    flex = FlexibleJointModel(robot)
    flex.reset(q0)
    hold = flex.holding_torque(q0)
    flex_us = median_us(lambda: flex.step(hold), reps=2000)

    out = {
        "sim_track_step_us": ours_track,
        "peer_mujoco_pd_loop_step_us": peer_track,
        "ratio_track_vs_peer": ours_track / peer_track,
        "mj_step_us": bare,
        "sim_real_time_factor_run_trajectory": rtf,
        "sim_real_time_factor_track": 1e3 / ours_track,
        "tracking_rms_rad": log.rms_error.tolist(),
        "tracking_max_rad": log.max_error.tolist(),
        "tracking_tcp_max_m": float(log.tcp_error(robot).max()),
        "tracking_rms_pid_only_rad": log_pid.rms_error.tolist(),
        "tracking_tcp_max_pid_only_m": float(log_pid.tcp_error(robot).max()),
        "tracking_rms_unmodelled_2kg_payload_rad": log_pl.rms_error.tolist(),
        "tracking_tcp_max_unmodelled_2kg_payload_m": float(log_pl.tcp_error(robot).max()),
        "flexible_step_us": flex_us,
        "flexible_resonance_hz_at_q0": flex.resonance_frequencies(q0).tolist(),
        "flexible_gravity_sag_rad_at_q0": (-robot.gravity(q0) / flex.params.stiffness).tolist(),
        "pinocchio_vs_mujoco": model_agreement(robot),
    }
    if args.json:
        print(json.dumps(out))
        return
    print(f"Workcell.track (PID + RNEA ff + mj_step): {ours_track:8.2f} us   "
          f"plain MuJoCo PD loop: {peer_track:8.2f} us   ratio {ours_track / peer_track:.2f}")
    print(f"bare mj_step: {bare:.2f} us; real-time factor run_trajectory {rtf:.1f}x, track {1e3 / ours_track:.1f}x")
    print(f"tracking RMS (rad) {np.array2string(log.rms_error, precision=2)}; max TCP error "
          f"{out['tracking_tcp_max_m'] * 1e6:.2f} um")
    print(f"PID only: max TCP error {out['tracking_tcp_max_pid_only_m'] * 1e3:.2f} mm; unmodelled 2 kg payload: "
          f"{out['tracking_tcp_max_unmodelled_2kg_payload_m'] * 1e3:.2f} mm")
    print(f"flexible-joint step {flex_us:.1f} us; Pinocchio vs MuJoCo {out['pinocchio_vs_mujoco']}")


if __name__ == "__main__":
    main()
