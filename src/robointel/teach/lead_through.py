"""Lead-through teaching on any robot interface (Ch. 3.3, Ch. 4): admittance over streamed positions.

A position-controlled industrial arm is guided by hand through its F/T sensor: every controller
period the measured wrench is payload-compensated (3.20), expressed in world axes about the TCP,
turned into a joint velocity by the guidance controller (compliance (3.10)-(3.13) with collision
avoidance (4.11)) and integrated into the next joint *position* target, which goes through the
interface's safety gate to the robot (``sim`` or ``fanuc``).
"""
from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel.control.payload import PayloadCompensation
from robointel.errors import InvalidInput
from robointel.interface.backend import Backend
from robointel.interface.realtime import sleep_until
from robointel.teach.guidance import GuidanceConfig, GuidanceController, GuidanceStep


@dataclass
class LeadThroughResult:
    """What a lead-through run recorded, one row per controller period.

    Attributes:
        t: (K,) robot time, s.
        q: (K, n) measured joint positions, rad.
        q_cmd: (K, n) joint position targets sent, rad.
        wrench: (K, 6) compensated wrench at the TCP in world axes, N and N m.
        distance: (K,) smallest robot-obstacle distance the controller saw, m.
        held: (K,) the controller refused the F/T reading and held.
    """

    t: npt.NDArray[np.float64]
    q: npt.NDArray[np.float64]
    q_cmd: npt.NDArray[np.float64]
    wrench: npt.NDArray[np.float64]
    distance: npt.NDArray[np.float64]
    held: npt.NDArray[np.bool_]


def tcp_wrench(robot: Any, q: npt.NDArray[np.float64], wrench_sensor: npt.NDArray[np.float64]) -> npt.NDArray[
        np.float64]:
    """A wrench measured in the flange (sensor) frame, in world axes about the TCP.

    Args:
        robot: :class:`robointel.robot.Robot` (flange frame = sensor frame; TCP = flange + tool).
        q: (n,) joint positions, rad.
        wrench_sensor: (6,) [f (N); m (N m)] in the sensor frame about its origin.

    Returns:
        (6,) [f; m] in world axes, torque about the TCP.
    """
    Ts = robot.frame_pose(q, robot.flange_frame)
    R = Ts[:3, :3]
    f, m = R @ wrench_sensor[:3], R @ wrench_sensor[3:]
    r = robot.fk(q)[:3, 3] - Ts[:3, 3]
    return np.concatenate([f, m - np.cross(r, f)])


def lead_through(arm: Backend, robot: Any, duration: float, *, obstacles: Sequence[Any] = (),
                 payload: PayloadCompensation | None = None, config: GuidanceConfig | None = None,
                 on_cycle: Callable[[int, GuidanceStep], None] | None = None,
                 step_world: Callable[[int], None] | None = None) -> LeadThroughResult:
    """Guide ``arm`` by hand for ``duration`` seconds, one position target per controller period.

    Args:
        arm: a robot interface whose state carries the F/T wrench (``sim``; ``fanuc`` with a wrist
            F/T sensor, ``FanucRobot(ft_sensor=...)``); a missing reading holds the arm that period.
        robot: the :class:`robointel.robot.Robot` of the arm (kinematics, limits, collision spheres).
        duration: s.
        obstacles: :mod:`robointel.geometry` obstacles to avoid (world frame).
        payload: the tool's weight and the sensor biases to remove (3.20); None: none.
        config: :class:`GuidanceConfig` (its ``dt`` is replaced by the arm's period).
        on_cycle: called with (cycle, :class:`GuidanceStep`) after each target.
        step_world: called with the cycle index before each reading (e.g. a simulated hand).

    Returns:
        The :class:`LeadThroughResult`.

    Raises:
        InvalidInput: non-positive duration, or the arm reports no wrench (no F/T sensor).
        UnsafeCommand, ControllerFault, ConnectionLost: from the interface (the arm holds/stops).
    """
    if not (np.isfinite(duration) and duration > 0):
        raise InvalidInput(f"duration must be > 0 s, got {duration}", value=duration)
    st = arm.state()
    if not arm.has_wrench:
        raise InvalidInput("this robot reports no F/T wrench (no sensor, or a controller without force telemetry, "
                           "such as Stream Motion v3); lead-through needs one: give the wrist F/T sensor "
                           "(FanucRobot(ft_sensor=...), or --ft netft://HOST on the command line)", value=st)
    cfg = dataclasses.replace(config or GuidanceConfig(), dt=arm.period)
    ctl = GuidanceController(robot, obstacles, cfg)
    K = int(round(duration / arm.period))
    n = len(st.q)
    out = LeadThroughResult(np.zeros(K), np.zeros((K, n)), np.zeros((K, n)), np.zeros((K, 6)), np.zeros(K),
                            np.zeros(K, dtype=bool))
    q_cmd = (st.q_cmd if st.q_cmd is not None else st.q).copy()
    # a force loop: each target goes out at once, no queue; paced: a real-time section
    with arm.force_loop():
        t0 = time.perf_counter()
        try:
            for k in range(K):
                if arm.paced:
                    sleep_until(t0 + k * arm.period)
                if step_world is not None:
                    step_world(k)
                st = arm.state()
                w = st.wrench if st.wrench is not None else np.full(6, np.nan)  # a lost reading holds
                if payload is not None and st.wrench is not None:
                    R = robot.frame_pose(st.q, robot.flange_frame)[:3, :3]
                    w = payload.compensate(w, R)
                ww = tcp_wrench(robot, st.q, w)
                s = ctl.step(st.q, ww)
                q_cmd = np.clip(q_cmd + s.qd * arm.period, robot.lower, robot.upper)
                arm.stream(q_cmd)
                out.t[k], out.q[k], out.q_cmd[k], out.wrench[k] = st.t, st.q, q_cmd, ww
                out.distance[k], out.held[k] = s.distance, s.held
                if on_cycle is not None:
                    on_cycle(k, s)
        finally:
            arm.hold()
    return out
