"""Part I recordings as dataset episodes (LeRobot / robomimic export).

Imitation runs, guided runs and teleoperated programs executed through the streaming interface.

Each converter keeps the robot's measured joints as ``state`` and what was commanded as ``action``:

- imitation (LR Mate, 3.1): state q, observation qd, action the 1 kHz joint reference;
- imitation (SCARA, (3.2)-(3.9)): state q, observations the true human angles, the received
  (delayed) frames and the torques, action the joint reference the LQ tracked;
- guidance (Ch. 4): state q, observations the TCP position and the operator's target, action the
  commanded TCP twist;
- teleoperation: a program's waypoints streamed as joint targets to the simulated robot at
  ``stream_hz`` (:class:`StreamingController`), state q, observation the jerk-limited reference,
  action the streamed target.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput
from robointel.io.episode import Episode
from robointel.robot import Robot
from robointel.teach.imitation import ImitationRun
from robointel.teach.scara import ScaraResult
from robointel.teach.scenarios import ScenarioResult
from robointel.teach.stream_control import LOCAL, StreamingController

TWIST_NAMES = ("vx", "vy", "vz", "wx", "wy", "wz")


def scara_episode(result: ScaraResult, *, task: str = "dynamic imitation of a human arm (SCARA)") -> Episode:
    """A SCARA imitation run (1 kHz) as an episode.

    Args:
        result: the run of ``simulate_scara``.
        task: the task description.

    Returns:
        Episode: state q (N, 2) [rad]; observations ``human`` (true human angles, rad), ``received``
        (the newest received frame, rad; live runs), ``torque`` (N m); action q_ref (N, 2) [rad];
        kind "imitation".
    """
    obs = {"state": result.q, "human": result.q_human, "torque": result.tau}
    if result.q_delayed is not None and not result.offline:
        obs["received"] = result.q_delayed
    names: dict[str, tuple[str, ...]] = {k: ("q1", "q2") for k in (*obs, "action") if k != "torque"}
    names["torque"] = ("tau1", "tau2")
    meta = {"robot": "scara2", "source": result.source, "latency_s": result.latency,
            "compensated": result.compensated, "offline": result.offline, "rms_rad": result.rms.tolist()}
    return Episode.create(result.t, obs, result.q_ref, names=names, task=task, kind="imitation",
                          name=f"scara {result.source}", meta=meta)


def imitation_episode(run: ImitationRun, robot: Robot, *,
                      task: str = "kinematic imitation of a human arm (LR Mate)") -> Episode:
    """An LR Mate imitation run tracked in MuJoCo (1 kHz) as an episode.

    Args:
        run: the run of ``simulate_imitation``.
        robot: the robot it ran on (joint names).
        task: the task description.

    Returns:
        Episode: state q (N, n) [rad], observation ``velocity`` qd [rad/s], action q_ref [rad];
        kind "imitation".
    """
    log = run.log
    joints = tuple(robot.joint_names)
    return Episode.create(log.t, {"state": log.q, "velocity": log.qd}, log.q_ref,  # type: ignore[attr-defined]
                          names={"state": joints, "velocity": joints, "action": joints}, task=task,
                          kind="imitation", name=f"lrmate {run.plan.source}",
                          meta={"robot": robot.name, "source": run.plan.source, "rms_rad": run.rms.tolist()})


def guidance_episode(result: ScenarioResult, robot: Robot, *, task: str = "") -> Episode:
    """A guided (lead-through) run with collision avoidance as an episode.

    Args:
        result: the run of ``run_scenario``.
        robot: the robot it ran on (joint names).
        task: the task description (default "guidance, scenario N").

    Returns:
        Episode: state q (N, n) [rad], observations ``tcp`` and ``target`` (N, 3) [m], action the
        commanded TCP twist (N, 6) [m/s, rad/s]; kind "guidance".
    """
    joints = tuple(robot.joint_names)
    return Episode.create(result.t, {"state": result.q, "tcp": result.tcp, "target": result.target}, result.v_cmd,
                          names={"state": joints, "tcp": ("x", "y", "z"), "target": ("x", "y", "z"),
                                 "action": TWIST_NAMES},
                          task=task or f"guidance, scenario {result.scenario}", kind="guidance",
                          name=f"scenario {result.scenario} ({result.method})",
                          meta={"robot": robot.name, "scenario": result.scenario, "method": result.method})


def teleop_episode(waypoints: npt.ArrayLike, *, robot: Robot | None = None, stream_hz: float = 50.0,
                   tolerance: float = 1e-3, dwell: float = 0.2, timeout: float = 10.0,
                   task: str = "teleoperated program", name: str = "teleop program") -> Episode:
    """Execute a teleoperated program through the streaming interface and record it.

    The waypoints are streamed one after another as joint targets (re-sent at ``stream_hz`` in
    simulated time, like the teleoperation page) to a :class:`StreamingController` stepping the
    MuJoCo workcell at 1 kHz; the next waypoint is sent once the robot is within ``tolerance`` of
    the current one and has dwelt there ``dwell`` seconds.

    Args:
        waypoints: (m, n) joint positions [rad], m >= 2.
        robot: default the LR Mate.
        stream_hz: target message rate [Hz].
        tolerance: joint distance [rad] at which a waypoint counts as reached.
        dwell: time [s] spent at each waypoint.
        timeout: longest time [s] per waypoint.
        task: the task description.
        name: the episode's name.

    Returns:
        Episode: state q (N, n) [rad], observation ``reference`` (the jerk-limited reference, rad),
        action the streamed target [rad]; kind "teleoperation".

    Raises:
        InvalidInput: fewer than 2 waypoints, a waypoint outside the limits, or one not reached
            within ``timeout``.
    """
    robot = robot or Robot.load("lrmate200id7l")
    W = np.asarray(waypoints, float)
    if W.ndim != 2 or W.shape[0] < 2 or W.shape[1] != robot.nq:
        raise InvalidInput(f"waypoints must be (m >= 2, {robot.nq}), got {W.shape}", value=W.shape)
    for i, w in enumerate(W):
        robot.check_q(w, f"waypoints[{i}]", limits=True)
    ctrl = StreamingController(robot, q0=W[0], realtime=False)
    ctrl.acquire(LOCAL)  # this program is the one commanding client
    every = max(1, int(round(1.0 / (stream_hz * ctrl.dt))))
    t, q, ref, target = [], [], [], []
    for i, w in enumerate(W):
        settled, k = 0.0, 0
        while settled < dwell:
            if k % every == 0:
                reply = ctrl.submit({"type": "joint_target", "q": w.tolist(), "seq": i})
                if reply is not None:
                    raise InvalidInput(f"waypoint {i} rejected: {reply['message']}", value=i)
            ctrl.advance(1)
            k += 1
            t.append(ctrl.wc.time)
            q.append(ctrl.wc.q.copy())
            ref.append(ctrl.q_ref.copy())
            target.append(w)
            settled = settled + ctrl.dt if np.max(np.abs(ctrl.wc.q - w)) < tolerance else 0.0
            if k * ctrl.dt > timeout:
                raise InvalidInput(f"waypoint {i} not reached within {timeout} s", value=i)
    joints = tuple(robot.joint_names)
    return Episode.create(np.array(t), {"state": np.array(q), "reference": np.array(ref)}, np.array(target),
                          names={"state": joints, "reference": joints, "action": joints}, task=task,
                          kind="teleoperation", name=name,
                          meta={"robot": robot.name, "waypoints": W.tolist(), "stream_hz": stream_hz})

