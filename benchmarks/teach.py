"""Teaching interfaces benchmark (Ch. 3.2, 3.4): imitation accuracy on the real Kinect recordings,
SCARA LQ tracking with and without delay compensation beside the dissertation's figures, and the
streaming interface's latency and sustained rate on loopback.

    python benchmarks/teach.py            # tables
    python benchmarks/teach.py --json     # one JSON object
    python benchmarks/teach.py --json --scara   # the SCARA figures only

SCARA fields (see ``scara_note`` in the output): ``scara_rms_delay_aligned_rad`` is the
dissertation's system (the whole loop 0.1 s late: frames on their own clock measured 0.1 s after
capture, the reference aimed at the angles 0.1 s ago, computed-torque LQ with feed-forward) against
the recorded human angles 0.1 s earlier (the delay taken out of the comparison, the dissertation's
reading); ``*_received`` is the same reading of the live uncompensated run (the previous figure);
``scara_rms_compensated_rad`` is the honest live predicted
figure (robot vs the true, undelayed human angles, a predictor fitted leave-one-recording-out);
``scara_rms_offline_compensated_rad`` (recording known in advance, shifted by the latency) and
``scara_controller_rms_*`` (robot vs its own reference) are separate, named as such; ``*_unshaped``
keys re-run the previous live pipeline (no torque-feasible follower) for comparison.

Needs ../shared/data/kinect (the seven recordings). Timings are wall-clock on a shared machine.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from dataclasses import replace
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table
from websockets.sync.client import connect

from robointel.errors import IKFailure
from robointel.io.reference import data_path
from robointel.robot import Robot
from robointel.teach.imitation import kinematic_imitation, simulate_imitation
from robointel.teach.scara import (
    BLEND_FRAMES,
    PAPER_RMS,
    PAPER_RMS_COMPENSATED,
    KalmanPredictor,
    LinePredictor,
    ScaraResult,
    ScaraSettings,
    delay_aligned_rms,
    delayed_copy_rms,
    fit_predictor,
    received_frames,
    recorded_angles,
    required_torques,
    simulate_scara,
)
from robointel.teach.scara import FeasibleReference as FR
from robointel.teach.skeleton import Skeleton, read_kinect_csv
from robointel.teach.stream_client import StreamClient
from robointel.teach.streaming import StreamingController, StreamingServer

RECORDINGS = ["Ges01_wavehand", "Ges02_balancinghands", "Ges03_drawlines", "Ges04_comehere",
              "Ges05_demopoint", "Ges06_chickenwing", "joints"]


def imitation(recordings: list[str]) -> dict[str, Any]:
    """LR Mate kinematic imitation figures on the Kinect recordings."""
    lr = Robot.load("lrmate200id7l")
    out: dict[str, Any] = {"imitation_rms_rad": {}, "imitation_controller_rms_rad": {}, "imitation_tcp_rms_mm": {},
                           "imitation_limit_hits": {}, "imitation_unreachable_frames": {}}
    for name in recordings:
        sk = read_kinect_csv(data_path("kinect", f"{name}.csv"))
        run = simulate_imitation(kinematic_imitation(sk, lr), lr)
        out["imitation_rms_rad"][name] = np.round(run.rms, 5).tolist()
        out["imitation_controller_rms_rad"][name] = np.round(run.tracking_rms, 6).tolist()
        out["imitation_tcp_rms_mm"][name] = round(run.tcp_rms * 1000, 2)
        out["imitation_limit_hits"][name] = run.plan.limit_hits.astype(int).tolist()
        out["imitation_unreachable_frames"][name] = int((~run.plan.reachable).sum())
    return out


def _lag(run: ScaraResult, sk: Skeleton, robot: Robot) -> tuple[float, np.ndarray, np.ndarray]:
    """(the shift of the recorded angles that fits the run best [s], the RMS there, the RMS at 0.1 s)."""
    lags = np.round(np.arange(0.08, 0.26, 0.01), 2)
    by_lag = [delay_aligned_rms(run, sk, delay=d, robot=robot) for d in lags]
    best = int(np.argmin([a.sum() for a in by_lag]))
    return float(lags[best]), by_lag[best], by_lag[int(np.argmin(np.abs(lags - 0.1)))]


def scara(recordings: list[str]) -> dict[str, Any]:
    """SCARA tracking figures on the Kinect recordings (see the module docstring and ``scara_note``)."""
    sc = Robot.load("scara2")
    skels = {name: read_kinect_csv(data_path("kinect", f"{name}.csv")) for name in RECORDINGS}
    scara_keys = ("scara_rms_rad", "scara_rms_delay_aligned_rad", "scara_rms_best_lag_rad",
                  "scara_rms_delay_aligned_received_rad", "scara_rms_best_lag_received_rad",
                  "scara_rms_delay_aligned_frames_held_rad", "scara_rms_delay_aligned_buffered_rad",
                  "scara_rms_best_lag_buffered_rad", "scara_rms_delay_aligned_offline_rad",
                  "scara_controller_rms_delayed_rad", "scara_recorded_torque_rms_nm",
                  "scara_rms_delay_aligned_smoothed_rad",
                  "scara_received_delay_aligned_rad", "scara_rms_compensated_rad",
                  "scara_rms_compensated_kalman_rad",
                  "scara_rms_delayed_copy_rad", "scara_prediction_rms_delayed_frames_rad",
                  "scara_prediction_rms_rad", "scara_prediction_rms_kalman_rad",
                  "scara_rms_offline_compensated_rad", "scara_controller_rms_rad",
                  "scara_controller_rms_compensated_rad", "scara_controller_rms_offline_rad",
                  "scara_rms_planar_elbow_rad", "scara_rms_compensated_planar_elbow_rad",
                  "scara_target_rms_rad", "scara_target_rms_compensated_rad",
                  "scara_rms_unshaped_rad", "scara_rms_compensated_unshaped_rad",
                  "scara_controller_rms_unshaped_rad", "scara_controller_rms_compensated_unshaped_rad",
                  "scara_prediction_rms_insample_rad")
    lag_keys = ("scara_lag_s", "scara_lag_received_s", "scara_lag_frames_held_s", "scara_lag_buffered_s",
                "scara_recorded_torque_over_limit", "scara_recorded_rate_over_limit")
    out: dict[str, Any] = {"scara_delayed_stages": {}, "scara_torque_saturation": {},
                           "scara_torque_saturation_unshaped": {},
                           "scara_torque_saturation_delayed": {}, "scara_predictor_ridge_alpha": {},
                           **{k: {} for k in lag_keys}, **{k: {} for k in scara_keys}}
    # optimistic bound for this predictor family: the ridge fitted on all seven recordings, INCLUDING the
    # one it is then evaluated on (in-sample; not a live figure)
    ar_all = fit_predictor(list(skels.values()), robot=sc, latency=0.1)
    for name in recordings:
        sk = skels[name]
        # leave-one-recording-out: the predictor never saw the recording it is evaluated on (its
        # ridge strength is chosen by leave-one-out over the six training recordings only)
        others = [s for n, s in skels.items() if n != name]
        ar = fit_predictor(others, robot=sc, latency=0.1)
        r0 = simulate_scara(sk, robot=sc, latency=0.1)
        r1 = simulate_scara(sk, robot=sc, latency=0.1, compensate=True, predictor=ar)
        rk = simulate_scara(sk, robot=sc, latency=0.1, compensate=True, predictor=KalmanPredictor(2, accel_psd=10.0))
        r2 = simulate_scara(sk, robot=sc, offline=True)
        # the dissertation's system: the whole loop 0.1 s late (measured 0.1 s after capture, the frames on
        # their own clock, the reference aimed at t - 0.1 s, the frame's age bridged by the Kalman filter)
        rd = simulate_scara(sk, ScaraSettings.delayed_tracking(0.1), robot=sc)
        # the same frames, newest one as received (no age bridging): the resampling and low-pass taken out only
        rf = simulate_scara(sk, robot=sc, latency=0.1, clock="frames")
        # a sensor one frame period faster, that period spent interpolating between frames: 0.1 s in all
        t_f, q_f = received_frames(sk)
        period = float(np.median(np.diff(t_f)))
        rb = simulate_scara(sk, ScaraSettings.delayed_tracking(0.1, latency=0.1 - period), robot=sc,
                            predictor=LinePredictor())
        # the previous live pipeline, for comparison in the same run: crossfade over 2 frame periods fed to the
        # LQ as it is (no torque-feasible follower)
        u0 = simulate_scara(sk, robot=sc, latency=0.1, blend_time=2 / sk.rate, feasible=False)
        u1 = simulate_scara(sk, robot=sc, latency=0.1, compensate=True, predictor=ar, blend_time=2 / sk.rate,
                            feasible=False)
        ins = simulate_scara(sk, robot=sc, latency=0.1, compensate=True, predictor=ar_all).prediction_rms
        # the 0.1 s system stage by stage against the recorded angles 0.1 s earlier: the estimate of the angles at
        # t - 0.1 s (no robot), after the crossfade, after the torque-feasible follower (the LQ's reference), robot
        for stage, q_stage in (("estimate", rd.q_pred), ("crossfade", rd.q_target), ("follower", rd.q_ref),
                               ("robot", rd.q)):
            lag_s, _, at_s = _lag(replace(rd, q=q_stage), sk, sc)
            out["scara_delayed_stages"].setdefault(stage, {})[name] = [*np.round(at_s, 4).tolist(), lag_s]
        lag_d, best_d, at_d = _lag(rd, sk, sc)
        lag_0, best_0, at_0 = _lag(r0, sk, sc)
        lag_f, _, at_f = _lag(rf, sk, sc)
        lag_b, best_b, at_b = _lag(rb, sk, sc)
        # what following the recorded angles exactly would take of the SCARA
        t_r, q_r = recorded_angles(sk)
        _, tau, qd = required_torques(t_r, q_r, sc)
        out["scara_lag_s"][name], out["scara_lag_received_s"][name] = lag_d, lag_0
        out["scara_lag_frames_held_s"][name], out["scara_lag_buffered_s"][name] = lag_f, lag_b
        out["scara_recorded_torque_over_limit"][name] = round(float(np.mean(np.any(
            np.abs(tau) > sc.effort_limit, axis=1))), 4)
        out["scara_recorded_rate_over_limit"][name] = round(float(np.mean(np.any(
            np.abs(qd) > sc.velocity_limit, axis=1))), 4)
        ok = rd.t >= 0.1
        vals = {"scara_rms_rad": r0.rms, "scara_rms_delay_aligned_rad": at_d, "scara_rms_best_lag_rad": best_d,
                "scara_rms_delay_aligned_received_rad": at_0, "scara_rms_best_lag_received_rad": best_0,
                "scara_rms_delay_aligned_frames_held_rad": at_f, "scara_rms_delay_aligned_buffered_rad": at_b,
                "scara_rms_best_lag_buffered_rad": best_b,
                "scara_rms_delay_aligned_offline_rad": delay_aligned_rms(r2, sk, delay=0.0, robot=sc),
                "scara_controller_rms_delayed_rad": rd.tracking_rms,
                "scara_rms_delay_aligned_smoothed_rad": np.sqrt(np.mean((rd.q[ok] - np.stack(
                    [np.interp(rd.t[ok] - 0.1, rd.t, rd.q_human[:, j]) for j in range(2)], axis=1)) ** 2, axis=0)),
                "scara_recorded_torque_rms_nm": np.sqrt(np.mean(tau ** 2, axis=0)),
                "scara_received_delay_aligned_rad": delay_aligned_rms(replace(r0, q=r0.q_delayed), sk, delay=0.1,
                                                                      robot=sc),
                "scara_rms_compensated_rad": r1.rms, "scara_rms_compensated_kalman_rad": rk.rms,
                "scara_rms_delayed_copy_rad": delayed_copy_rms(sk, robot=sc, latency=0.1),
                "scara_prediction_rms_delayed_frames_rad": r0.prediction_rms,
                "scara_prediction_rms_rad": r1.prediction_rms, "scara_prediction_rms_kalman_rad": rk.prediction_rms,
                "scara_rms_offline_compensated_rad": r2.rms, "scara_controller_rms_rad": r0.tracking_rms,
                "scara_controller_rms_compensated_rad": r1.tracking_rms,
                "scara_controller_rms_offline_rad": r2.tracking_rms,
                "scara_target_rms_rad": r0.target_rms, "scara_target_rms_compensated_rad": r1.target_rms,
                "scara_rms_unshaped_rad": u0.rms, "scara_rms_compensated_unshaped_rad": u1.rms,
                "scara_controller_rms_unshaped_rad": u0.tracking_rms,
                "scara_controller_rms_compensated_unshaped_rad": u1.tracking_rms,
                "scara_prediction_rms_insample_rad": ins}
        for k, v in vals.items():
            out[k][name] = np.round(v, 4).tolist()
        out["scara_predictor_ridge_alpha"][name] = ar.alpha
        out["scara_torque_saturation"][name] = [round(r0.saturated, 4), round(r1.saturated, 4)]
        out["scara_torque_saturation_unshaped"][name] = [round(u0.saturated, 4), round(u1.saturated, 4)]
        out["scara_torque_saturation_delayed"][name] = round(rd.saturated, 4)
        # the earlier mapping: the projected in-plane elbow angle (wraps past -pi on Ges05/Ges06)
        arp = fit_predictor(others, robot=sc, latency=0.1, elbow="planar")
        out["scara_rms_planar_elbow_rad"][name] = np.round(
            simulate_scara(sk, robot=sc, latency=0.1, elbow="planar").rms, 4).tolist()
        out["scara_rms_compensated_planar_elbow_rad"][name] = np.round(simulate_scara(
            sk, robot=sc, latency=0.1, compensate=True, predictor=arp, elbow="planar").rms, 4).tolist()
    for k in (*scara_keys, "scara_torque_saturation", "scara_torque_saturation_unshaped"):
        out[k]["mean"] = np.round(np.mean([v for n, v in out[k].items() if n != "mean"], axis=0), 4).tolist()
    for k in (*lag_keys, "scara_torque_saturation_delayed"):
        out[k]["mean"] = round(float(np.mean(list(out[k].values()))), 4)
    for per in out["scara_delayed_stages"].values():
        per["mean"] = np.round(np.mean(list(per.values()), axis=0), 4).tolist()
    pred = {"delayed frames (no prediction)": "scara_prediction_rms_delayed_frames_rad",
            "constant-rate Kalman": "scara_prediction_rms_kalman_rad", "ridge AR (LORO)": "scara_prediction_rms_rad"}
    out["scara_predictor_choice"] = min(pred, key=lambda p: sum(out[pred[p]]["mean"]))
    out["scara_rms_paper_rad"] = list(PAPER_RMS)
    out["scara_rms_compensated_paper_rad"] = list(PAPER_RMS_COMPENSATED)
    out["scara_latency_s"] = 0.1
    fr = FR(sc)
    out["scara_note"] = (
        "All scara_rms* = RMS over the run at 1 kHz of (robot angle in MuJoCo - TRUE human angle at the same "
        "instant: the zero-phase cleaned recording, not delayed), [q1, q2] rad; q2 = the elbow's 3-D flexion "
        "(planar_elbow keys: the projected in-plane angle). LIVE runs: the Kinect frames (causally filtered, "
        "dropouts held) reach the controller 0.1 s after capture; the reference crossfades over "
        f"{BLEND_FRAMES:g} frame period(s) at each arrival and then passes a torque-feasible online follower "
        f"(ruckig velocity interface, braking-curve feedback gain {fr.gain:g} 1/s, acceleration bounds from the URDF "
        f"effort limits x {fr.margin:g} and M(q), b(q, qd) at each step, jerk = bound / {fr.jerk_time:g} s) before "
        "the computed torque + DARE LQ (acceleration scaled down at the torque limits). The crossfade length, "
        "follower gain, margin and jerk time were chosen on these same 7 recordings (not leave-one-out). "
        "scara_rms_rad: live, no compensation (the received frames, delayed). "
        "scara_rms_delay_aligned_rad: the dissertation's 'if the delay is compensated in 0.1 second' read as "
        "RMS over time of q_robot(t) - q_human(t - 0.1 s), q_human the angles from the recording itself (dropouts "
        "bridged, not smoothed, linear between frames), over the steps with t - 0.1 s inside the recording, for "
        "the dissertation's system (ScaraSettings.delayed_tracking(0.1)): the whole loop 0.1 s late - each Kinect "
        "frame on its own capture clock (no resampling, no low-pass, untrusted frames dropped) usable 0.1 s after "
        "capture, the reference aimed at the angles at t - 0.1 s (the newest frame's age, 0-33 ms, bridged by the "
        "constant-rate Kalman filter, predictor_psd 10 as before), crossfaded over one frame, the torque-feasible "
        "follower, the computed-torque LQ with the reference's rate and acceleration as feed-forward; compared "
        "with the dissertation's 0.0103/0.0305 rad. scara_lag_s: the shift (0.08-0.25 s, 10 ms grid) of the "
        "recorded angles that fits that run best (how late the robot really is); scara_rms_best_lag_rad: the RMS "
        "there; scara_controller_rms_delayed_rad / scara_torque_saturation_delayed: that run's robot vs its own "
        "reference, and its steps with a torque at the limit. "
        "*_received: the same reading of the live uncompensated run (scara_rms_rad; the frames resampled to a "
        "uniform 30.3 Hz clock, held, causal 12 Hz low-pass, the newest frame crossfaded: the previous "
        "scara_rms_delay_aligned_rad); *_frames_held: the frames on their own clock, no low-pass, the newest "
        "frame crossfaded with no age bridging (resampling and low-pass taken out, nothing else); *_buffered: "
        "NOT a 0.1 s measurement latency - a sensor one frame period (33 ms) faster, that period spent "
        "interpolating between the two newest frames (LinePredictor), 0.1 s in all. "
        "scara_delayed_stages: that 0.1 s system stage by stage, [q1 rad, q2 rad, best shift s] against the recorded "
        "angles 0.1 s earlier: estimate (the Kalman filter's angles at t - 0.1 s from the frames received, no "
        "robot), crossfade, follower (the reference the LQ gets), robot. "
        "scara_rms_delay_aligned_smoothed_rad: the 0.1 s system against the smoothed (zero-phase 6 Hz) angles "
        "0.1 s earlier instead of the recorded ones (a second reading: what the Kinect noise costs). "
        "scara_rms_delay_aligned_offline_rad: the offline replay (the smoothed recording known in advance, no "
        "latency) vs the recorded angles at the same instant: the Kinect noise a robot following the arm's "
        "motion perfectly would still be scored for. scara_recorded_torque_*: following the recorded angles "
        "exactly (cubic spline, Pinocchio inverse dynamics): RMS torque [J1, J2] N m against the 60 / 30 N m "
        "effort limits, the share of time a torque (torque_over_limit) or rate (rate_over_limit, 2 pi rad/s) "
        "would exceed its limit. "
        "scara_received_delay_aligned_rad: the received frames themselves (held, live-filtered) vs the recorded "
        "angles 0.1 s earlier (the signal the robot is given, no robot). "
        "scara_rms_compensated_rad: live, with compensation - THE HONEST LIVE FIGURE - a ridge autoregressive "
        "predictor of the angles 0.1 s + frame age ahead, fitted leave-one-recording-out (never on the recording "
        "it runs on). scara_rms_compensated_kalman_rad: live, constant-rate Kalman prediction instead. "
        "*_unshaped: the previous live pipeline in the same run (crossfade over 2 frame periods straight into the "
        "LQ, no feasible follower). scara_controller_rms*: robot vs the reference the LQ was given (after the "
        "follower); scara_target_rms*: robot vs the crossfaded signal before the follower (what the follower "
        "smooths away counts here). "
        "scara_prediction_rms*: the predictor's output alone vs the true angles, no robot (delayed_frames: the "
        "received frames held as they come); scara_predictor_choice: the lowest of these (leave-one-out); "
        "scara_prediction_rms_insample_rad: the same ridge fitted on all 7 recordings including the evaluated one "
        "(optimistic in-sample bound of this predictor family, NOT a live figure). "
        "scara_rms_delayed_copy_rad: signal only, a perfect noise-free copy of the true motion delayed by exactly "
        "0.1 s (no frame age, no sensor noise: not reachable live without prediction). "
        "scara_rms_offline_compensated_rad: OFFLINE, the recording known in advance and shifted by the known "
        "latency (exact q/qd/qdd reference): no sensor in the loop, only the robot's own limits remain. "
        "saturation: fraction of steps with a torque at its limit [uncompensated, compensated]; with the follower "
        "the reference itself is planned up to the limits (time-optimal), so steps at the limit are by design. "
        "The dissertation's compensated 0.0103/0.0305 rad is compared with scara_rms_delay_aligned_rad (the delay "
        "taken out of the comparison) and with scara_rms_compensated_rad (live prediction 0.1 s ahead, a harder "
        "claim: no predictor tried gets the signal below ~0.17/0.19 rad, see scara_prediction_rms*).")
    return out




def ik_speed(n: int = 300) -> dict[str, Any]:
    """Closed-form IK per imitation frame (ours) vs Pinocchio damped least squares (peer path)."""
    r = Robot.load("lrmate200id7l")
    qs = r.random_configuration(1, 20)
    Ts = [r.fk(q) for q in qs]
    t0 = time.perf_counter()
    for i in range(n):
        r.ik(Ts[i % 20], q_ref=qs[i % 20])
    ours = (time.perf_counter() - t0) / n * 1e6
    rng = np.random.default_rng(2)
    starts = [q + rng.normal(0, 0.05, 6) for q in qs]  # warm start: the previous frame's solution
    t0 = time.perf_counter()
    m, fails = 60, 0
    for i in range(m):
        try:
            r.ik_numeric(Ts[i % 20], q0=np.clip(starts[i % 20], r.lower, r.upper), restarts=2)
        except IKFailure:
            fails += 1
    peer = (time.perf_counter() - t0) / m * 1e6
    return {"ik_closed_form_us": round(ours, 1), "ik_numeric_dls_us": round(peer, 1),
            "ik_speedup": round(peer / ours, 1), "ik_numeric_failures": fails,
            "ik_note": "per imitation frame: closed form (all branches, nearest to previous) vs Pinocchio "
                       "damped least squares warm-started 0.05 rad away"}


def streaming(latency_samples: int = 500, rate_seconds: float = 3.0) -> dict[str, Any]:
    """Teleoperation latency (target -> applied round trip) and the sustained streaming rate on loopback."""
    srv = StreamingServer(StreamingController(), port=0).start()
    res: dict[str, Any] = {}
    try:
        with connect(srv.url, compression=None) as ws:
            ws.recv(timeout=5)
            ws.send(json.dumps({"type": "acquire"}))  # protocol 2: one commanding client
            json.loads(ws.recv(timeout=5))
            ready = np.array([0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0])
            lat = []
            for k in range(latency_samples):
                q = ready + np.array([0.2 * np.sin(k / 50), 0.1 * np.sin(k / 70), 0, 0, 0, 0])
                t0 = time.perf_counter()
                ws.send(json.dumps({"type": "joint_target", "q": q.tolist(), "seq": k, "ack": True,
                                    "t": time.perf_counter()}))
                while True:
                    m = json.loads(ws.recv(timeout=5))
                    if m["type"] == "applied" and m["seq"] == k:
                        break
                lat.append((time.perf_counter() - t0) * 1e3)
                time.sleep(0.004)
            res["teleop_latency_ms"] = {"median": round(float(np.median(lat)), 3),
                                        "p99": round(float(np.percentile(lat, 99)), 3), "n": len(lat),
                                        "what": "WebSocket target message -> first 1 kHz control step using it "
                                                "-> 'applied' reply (round trip, loopback)"}
            # sustained rate: targets paced at 900 Hz in bursts of 9 per 10 ms (under the server's 1000
            # messages/s per-client limit; a faster client is throttled and its late targets are dropped
            # as stale), 3 s
            a0, r0 = srv.controller.accepted, srv.controller.rejected
            t0 = time.perf_counter()
            k = 0
            while time.perf_counter() - t0 < rate_seconds:
                q = ready + np.array([0.3 * np.sin(k / 2000), 0, 0, 0, 0, 0])
                ws.send(json.dumps({"type": "joint_target", "q": q.tolist(), "seq": k, "t": time.perf_counter()}))
                k += 1
                if k % 9 == 0:  # 9 targets per 10 ms, sleeping between (a busy wait would hold the GIL)
                    time.sleep(max(0.0, t0 + k / 900.0 - time.perf_counter()))
            el = time.perf_counter() - t0
            ws.send(json.dumps({"type": "get_state"}))
            while json.loads(ws.recv(timeout=10))["type"] != "state":
                pass
            acc = srv.controller.accepted - a0
            res["stream_rate_hz"] = round(acc / el, 1)
            res["stream_messages"] = {"sent": k, "accepted": acc, "rejected": srv.controller.rejected - r0,
                                      "seconds": round(el, 2), "paced_hz": 900,
                                      "note": "targets replaced in the client's one-target mailbox before their "
                                              "collision check are neither accepted nor rejected"}
            res["control_overruns"] = srv.controller.overruns
    finally:
        srv.stop()
    return res


def _flooders(url: str, modes: list[str], seconds: float, hold: float) -> list[subprocess.Popen[str]]:
    """Flooding clients, each in its own process at the lowest CPU priority (see the tests)."""
    procs = [subprocess.Popen(["nice", "-n", "19", sys.executable, "-m", "robointel.teach.stream_client", url, m,
                               str(seconds), str(hold)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
             for m in modes]
    for p in procs:
        assert p.stdout is not None and p.stdout.readline().strip() == "ready"
    return procs


def _release(procs: list[subprocess.Popen[str]]) -> None:
    """Start the flooders: each waits for a ``go`` line on its stdin."""
    for p in procs:
        assert p.stdin is not None
        p.stdin.write("go\n")
        p.stdin.flush()


def stream_safety(runs: int = 3, probe_seconds: float = 3.0) -> dict[str, Any]:
    """The streaming server's two figures: how long after the last send of a 0.4 s flood the stop begins
    (``deadman_after_flood_ms``; deadman 100 ms), and another client's get_state round trip while 5
    clients flood (``get_state_p99_ms_under_load``), beside the same client's p99 with no load."""
    srv = StreamingServer(StreamingController(), port=0).start()
    ctrl = srv.controller
    res: dict[str, Any] = {}
    try:
        delays, rest = [], []
        for _ in range(runs):
            with StreamClient(srv.url) as a:  # start at rest at J1's left end
                a.acquire()
                for _ in range(150):
                    a.joint_target([-2.5, 0.0, 0.0, 0.0, -np.pi / 2, 0.0])
                    time.sleep(0.01)
            time.sleep(0.3)
            procs = _flooders(srv.url, ["command"], 0.4, 1.5)
            _release(procs)
            assert procs[0].stdout is not None
            last = json.loads(procs[0].stdout.readline())["last_send"]
            time.sleep(1.0)
            delays.append((ctrl.stop_began - last) * 1e3)
            rest.append((ctrl.rest_at - last) * 1e3 if ctrl.rest_at else float("nan"))
            for p in procs:
                p.kill()
                p.wait()
        res["deadman_after_flood_ms"] = {
            "median": round(float(np.median(delays)), 1), "max": round(float(np.max(delays)), 1),
            "at_rest_after_last_send_ms_max": round(float(np.nanmax(rest)), 1), "runs": runs,
            "deadman_ms": 1e3 * ctrl.deadman,
            "what": "stop began - client's last send of a 0.4 s flood (one client in control, as fast as the "
                    "link takes); negative: the flood's late targets were already dropped as stale"}

        def probe(seconds: float) -> list[float]:
            lat = []
            with StreamClient(srv.url) as c:
                t_end = time.monotonic() + seconds
                while time.monotonic() < t_end:
                    t0 = time.perf_counter()
                    c.state()
                    lat.append((time.perf_counter() - t0) * 1e3)
                    time.sleep(0.01)
            return lat

        idle = probe(probe_seconds)
        procs = _flooders(srv.url, ["command_poses", "junk", "junk", "junk", "junk"], probe_seconds + 0.5, 0.5)
        _release(procs)
        time.sleep(0.3)
        loaded = probe(probe_seconds)
        for p in procs:
            p.kill()
            p.wait()
        res["get_state_p99_ms_under_load"] = round(float(np.percentile(loaded, 99)), 2)
        res["get_state_under_load"] = {
            "median_ms": round(float(np.median(loaded)), 2), "max_ms": round(float(np.max(loaded)), 2),
            "n": len(loaded), "p99_ms_no_load": round(float(np.percentile(idle, 99)), 2),
            "what": "get_state round trip of one client at 100 Hz while 5 clients flood (one in control sending "
                    "unreachable poses, four sending refused targets, state requests, bad JSON, heartbeats), "
                    "flooders in their own processes at nice 19"}
    finally:
        srv.stop()
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--quick", action="store_true", help="two recordings only")
    ap.add_argument("--scara", action="store_true", help="the SCARA figures only")
    args = ap.parse_args()
    out: dict[str, Any] = {"benchmark": "teach"}
    recordings = RECORDINGS[:2] if args.quick else RECORDINGS
    if not args.scara:
        out.update(imitation(recordings))
    out.update(scara(recordings))
    if not args.scara:
        out.update(ik_speed())
        out.update(streaming())
        out.update(stream_safety())
    out["targets"] = {"scara_rms_delay_aligned_rad <=": [0.0103, 0.0305],
                      "scara_rms_compensated_rad <=": [0.0103, 0.0305], "teleop_latency_ms.p99 <=": 20,
                      "stream_rate_hz >=": 500, "deadman_after_flood_ms.max <=": 100,
                      "get_state_p99_ms_under_load <=": 50}
    if args.json:
        print(json.dumps(out))
        return
    c = Console()
    if not args.scara:
        t = Table(title="LR Mate kinematic imitation (RMS vs per-frame IK target, rad)")
        t.add_column("recording")
        for j in range(6):
            t.add_column(f"J{j + 1}", justify="right")
        t.add_column("TCP RMS [mm]", justify="right")
        for n, v in out["imitation_rms_rad"].items():
            t.add_row(n, *[f"{x:.4f}" for x in v], f"{out['imitation_tcp_rms_mm'][n]:.1f}")
        c.print(t)
    s = Table(title="SCARA, 0.1 s latency: RMS q1 / q2 [rad] vs the true human angles (dissertation 0.153 / 0.185; "
                    "compensated 0.0103 / 0.0305)")
    cols = {"live, no comp.": "scara_rms_rad", "0.1 s system vs human(t - 0.1 s)": "scara_rms_delay_aligned_rad",
            "live, no comp., vs human(t - 0.1 s)": "scara_rms_delay_aligned_received_rad",
            "live, AR comp. (LORO)": "scara_rms_compensated_rad",
            "live, Kalman comp.": "scara_rms_compensated_kalman_rad", "AR prediction only": "scara_prediction_rms_rad",
            "delayed copy (ideal)": "scara_rms_delayed_copy_rad", "offline comp.": "scara_rms_offline_compensated_rad",
            "controller vs ref (comp.)": "scara_controller_rms_compensated_rad",
            "live, AR comp., unshaped (previous)": "scara_rms_compensated_unshaped_rad",
            "controller vs ref (comp., unshaped)": "scara_controller_rms_compensated_unshaped_rad"}
    s.add_column("recording", justify="right")
    for col in cols:
        s.add_column(col, justify="right")
    for n in out["scara_rms_rad"]:
        s.add_row(n, *(" / ".join(f"{x:.4f}" for x in out[k][n]) for k in cols.values()))
    c.print(s)
    if args.scara:
        return
    c.print(f"IK per frame: closed form {out['ik_closed_form_us']} us vs numeric DLS {out['ik_numeric_dls_us']} us "
            f"({out['ik_speedup']}x)")
    c.print(f"teleop latency: median {out['teleop_latency_ms']['median']} ms, "
            f"p99 {out['teleop_latency_ms']['p99']} ms; "
            f"sustained stream {out['stream_rate_hz']} Hz ({out['stream_messages']})")
    c.print(f"stop after a 0.4 s flood: {out['deadman_after_flood_ms']} ms after the last send; get_state p99 "
            f"under 5 flooding clients {out['get_state_p99_ms_under_load']} ms ({out['get_state_under_load']})")


if __name__ == "__main__":
    main()
