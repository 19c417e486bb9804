"""Dynamic imitation of a recording on the 2-link SCARA in MuJoCo (Ch. 3.2, (3.2)-(3.9)).

The Kinect delivers frames at ~30 Hz with a latency; a live system sees them cleaned causally
(dropouts held, causal low-pass). Without compensation the reference is the newest received frame;
with compensation it is a predictor's estimate of the human angles at the current instant. The
estimate is shaped into (q_r, qd_r, qdd_r) (see :class:`ScaraSettings`), passed through the
torque-feasible follower (:class:`FeasibleReference`) and tracked by computed torque + LQ
(:class:`ComputedTorqueLQ`). Errors are measured against the true human angles (the zero-phase
cleaned recording, not delayed) at the same instant.
"""
from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline

from robointel.control import ComputedTorqueLQ, JerkLimitedFollower
from robointel.errors import InvalidInput
from robointel.robot import Robot
from robointel.sim import Workcell
from robointel.teach.scara.angles import human_reference, received_frames
from robointel.teach.scara.crossfade import Transition
from robointel.teach.scara.feasible import FeasibleReference
from robointel.teach.scara.predictors import HoldPredictor, KalmanPredictor, Predictor
from robointel.teach.scara.settings import BLEND_FRAMES, ScaraSettings
from robointel.teach.skeleton import Skeleton


@dataclass
class ScaraResult:
    """One SCARA imitation run.

    Attributes:
        t: (M,) control times [s] (1 kHz).
        q: (M, 2) simulated joint angles [rad].
        q_human: (M, 2) true human angles [rad] (zero-phase cleaned, not delayed).
        q_ref: (M, 2) reference the controller tracked [rad] (delayed, predicted, or the recording).
        tau: (M, 2) commanded torques [N m].
        rms: (2,) RMS of q - q_human [rad]: the imitation error, robot vs the true human.
        tracking_rms: (2,) RMS of q - q_ref [rad]: the controller's own error vs what it was given.
        saturated: fraction of steps with a torque at its limit.
        latency: the sensor latency of the run [s] (0 offline).
        compensated: the run predicted across the latency.
        source: the recording's name.
        offline: the run replayed the recording known in advance.
        q_delayed: (M, 2) the newest received frame at each step [rad] (the human motion as the
            controller sees it: delayed by the latency and the frame's age, live-filtered).
        q_pred: (M, 2) the predictor's output before shaping [rad] (equal to ``q_delayed``
            without compensation; the recording itself offline).
        prediction_rms: (2,) RMS of q_pred - q_human [rad]: the predictor's own error.
        q_target: (M, 2) the shaped signal before the torque-feasible follower [rad] (equal to
            ``q_ref`` without the follower).
        target_rms: (2,) RMS of q - q_target [rad]: robot vs that signal.
    """

    t: np.ndarray
    q: np.ndarray
    q_human: np.ndarray
    q_ref: np.ndarray
    tau: np.ndarray
    rms: np.ndarray
    tracking_rms: np.ndarray
    saturated: float
    latency: float
    compensated: bool
    source: str = ""
    offline: bool = False
    q_delayed: np.ndarray | None = None
    q_pred: np.ndarray | None = None
    prediction_rms: np.ndarray | None = None
    q_target: np.ndarray | None = None
    target_rms: np.ndarray | None = None


def _rms(e: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(e ** 2, axis=0))


def simulate_scara(skel: Skeleton, settings: ScaraSettings | None = None, *, robot: Robot | None = None,
                   controller: ComputedTorqueLQ | None = None, workcell: Workcell | None = None,
                   predictor: Predictor | None = None, **overrides: Any) -> ScaraResult:
    """Simulate dynamic imitation of a recording on the SCARA in MuJoCo at 1/dt Hz (3.2)-(3.9).

    Frames captured at t_k reach the controller at t_k + latency (live-filtered on the recording's
    uniform clock, see :func:`human_reference`, or as received on their own clock, see
    :func:`received_frames`); each control period the shaped reference is tracked by computed
    torque + LQ, tau = M(q) u + C(q, qd) qd + G(q) + F_v qd, u = qdd_r - K (x - r) (3.9).

    Args:
        skel: raw skeleton (Kinect or BVH).
        settings: how to imitate (default :class:`ScaraSettings()`).
        robot: default ``Robot.load("scara2")``.
        controller: default ``ComputedTorqueLQ(robot, dt=settings.dt)``.
        workcell: a MuJoCo ``Workcell`` of ``robot`` (default: built here, no table).
        predictor: an object with ``update(t, q)``, ``predict(t) -> (q, qd)``, ``t`` (capture time
            of the last frame) and ``reset()``, e.g. an ``ARPredictor`` from ``fit_predictor``
            (fitted on *other* recordings); default a :class:`KalmanPredictor`
            (``settings.predictor_psd``). Used with ``compensate`` (the angles now), with
            ``delay`` (the angles at t - delay: it bridges the newest frame's age) and by the
            legacy follower / reference-model shaping.
        **overrides: fields of :class:`ScaraSettings` replacing those of ``settings``.

    Returns:
        :class:`ScaraResult` (errors against the true human angles at the same instant).

    Raises:
        InvalidInput: a setting out of range, an unknown setting, or a robot without 2 joints.
    """
    base = settings or ScaraSettings()
    unknown = set(overrides) - {f.name for f in dataclasses.fields(ScaraSettings)}
    if unknown:
        raise InvalidInput(f"simulate_scara: unknown settings {sorted(unknown)}", value=sorted(unknown))
    cfg = dataclasses.replace(base, **overrides) if overrides else base
    shaping, offline, compensate, latency, dt = (cfg.effective_shaping, cfg.offline, cfg.compensate,
                                                 cfg.latency, cfg.dt)
    robot = robot or Robot.load("scara2")
    if robot.nq != 2:
        raise InvalidInput(f"simulate_scara needs a 2-joint robot, got {robot.nq}", value=robot.name)
    t_h, q_true, q_meas = human_reference(skel, cfg.side, elbow=cfg.elbow, live_cutoff_hz=cfg.live_cutoff_hz)
    q_true = np.clip(q_true, robot.lower, robot.upper)
    t_f = t_h  # capture times of the frames the controller receives
    if cfg.clock == "frames" and not offline:
        t_f, q_meas = received_frames(skel, cfg.side, elbow=cfg.elbow)
    q_meas = np.clip(q_meas, robot.lower, robot.upper)
    T = float(np.median(np.diff(t_f)))
    tb = BLEND_FRAMES * T if cfg.blend_time is None else float(cfg.blend_time)
    if not (dt <= tb <= 1.0):
        raise InvalidInput(f"blend_time must be in [dt, 1] s, got {tb}", value=tb)
    ctrl = controller or ComputedTorqueLQ(robot, dt=dt)
    if workcell is None:
        workcell = Workcell(robot, table=False, ft_sensor=False, timestep=dt)
    M = int(np.floor(t_h[-1] / dt)) + 1
    t = np.arange(M) * dt
    spline = CubicSpline(t_h, q_true, axis=0)
    truth, truth_d, truth_dd = spline(t), spline(t, 1), spline(t, 2)
    pred: Predictor
    aim = cfg.delay if cfg.delay is not None and not offline else None
    if shaping in ("model", "follower") or compensate or aim is not None:
        pred = KalmanPredictor(2, accel_psd=cfg.predictor_psd) if predictor is None else predictor
    else:
        pred = HoldPredictor()
    pred.reset()
    acc = np.broadcast_to(np.asarray(cfg.max_accel, float), (2,))
    follow = JerkLimitedFollower(robot.velocity_limit, acc, cfg.jerk_factor * acc, dt=dt, gain=cfg.follow_gain,
                                 lower=robot.lower, upper=robot.upper)
    arrival = t_f + latency
    nxt = 0
    # the robot starts at rest at the first frame's pose (the operator is in view before start)
    pred.update(t_f[0], q_meas[0])
    follow.reset(q_meas[0])
    shaper = None
    feasible = cfg.feasible
    if feasible is None:
        feasible = not offline and shaping == "blend"
    if feasible:
        shaper = FeasibleReference(robot, dt, **(feasible if isinstance(feasible, dict) else {}))
        shaper.reset(q_meas[0])
    workcell.reset(q_meas[0], np.zeros(2))
    q_log, ref_log, tau_log = np.zeros((M, 2)), np.zeros((M, 2)), np.zeros((M, 2))
    del_log, pred_log, tgt_log = np.zeros((M, 2)), np.zeros((M, 2)), np.zeros((M, 2))
    wn = 2.0 * np.pi * cfg.smooth_hz
    qf, vf = np.array(q_meas[0], float), np.zeros(2)
    k = 0

    def horizon(p: Predictor) -> float:  # the time to estimate for, at most 0.5 s past the newest frame
        assert p.t is not None
        if compensate:
            return min(t[k], p.t + 0.5)
        return min(max(t[k] - (latency if aim is None else aim), t_f[0]), p.t + 0.5)

    blend = Transition(copy.deepcopy(pred), -np.inf, np.full(2, tb), None, horizon)
    for k in range(M):
        while nxt < len(t_f) and arrival[nxt] <= t[k] + 1e-12:
            if nxt > 0:
                pred.update(t_f[nxt], q_meas[nxt])
                if shaping == "blend" and not offline:
                    blend = Transition(copy.deepcopy(pred), arrival[nxt], np.full(2, tb), blend, horizon)
            nxt += 1
        del_log[k] = q_meas[max(nxt - 1, 0)]
        if offline:
            raw = truth[k]
            q_r, qd_r, qdd_r = (follow.step(raw, truth_d[k]) if shaping == "follower" else
                                (raw, truth_d[k], truth_dd[k]))
        elif shaping == "model":
            raw = np.clip(pred.predict(horizon(pred))[0], robot.lower, robot.upper)
            acc_r = wn * wn * (raw - qf) - 2.0 * wn * vf
            qf, vf = qf + dt * vf + 0.5 * dt * dt * acc_r, vf + dt * acc_r
            q_r, qd_r, qdd_r = qf, vf, acc_r
        elif shaping == "follower":
            raw, rate = pred.predict(horizon(pred))
            q_r, qd_r, qdd_r = follow.step(np.clip(raw, robot.lower, robot.upper), rate)
        elif shaping == "none":
            raw, rate = pred.predict(horizon(pred))
            q_r, qd_r, qdd_r = raw, rate, np.zeros(2)
        else:
            raw = pred.predict(horizon(pred))[0]
            q_r, qd_r, qdd_r = blend(t[k])
        pred_log[k] = raw
        tgt_log[k] = q_r
        if shaper is not None:
            q_r, qd_r, qdd_r = shaper.step(q_r, qd_r)
        q_r = np.clip(q_r, robot.lower, robot.upper)
        q, qd = workcell.q, workcell.qd
        tau = ctrl.torque(q, qd, q_r, qd_r, qdd_r)
        workcell.step(tau)
        q_log[k], ref_log[k], tau_log[k] = q, q_r, tau
    sat = float(np.mean(np.any(np.abs(tau_log) >= robot.effort_limit - 1e-9, axis=1)))
    target = np.clip(tgt_log, robot.lower, robot.upper)
    return ScaraResult(t, q_log, truth, ref_log, tau_log, _rms(q_log - truth), _rms(q_log - ref_log), sat,
                       0.0 if offline else latency, compensate and not offline, skel.source, offline,
                       del_log, pred_log, _rms(pred_log - truth), target, _rms(q_log - target))
