"""A learned insertion skill on any robot interface: admittance over streamed joint positions.

The torque-level Cartesian impedance of the insertion cell needs a torque-controlled arm; an industrial
controller takes one joint *position* target per period. Here, every period, the wrench on the tool is
read (:class:`~robointel.interface.wrench_source.WrenchSource`), the skill maps it to a corrective tool
twist (5.14)-(5.17), the admittance law adds the yield to the contact wrench (3.10)-(3.11), and the sum
becomes the next joint position target through the damped pseudo-inverse (3.12)-(3.13):

    V = Ad(R) [v_skill; w_skill] + C F_E,   q_{k+1} = q_k + J^#(q_k) V dt

scaled into the joint speed limits, through the interface's safety gate. A force or torque above the
limits stops the robot (``stop`` with the reason); a wrench that stops arriving holds it.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel.control.admittance import AdmittanceGains, admittance_twist, damped_pinv
from robointel.errors import InvalidInput, SafetyStop
from robointel.interface.backend import Backend, sleep_until
from robointel.interface.state import RobotState
from robointel.interface.wrench_source import StateWrench, WrenchSource
from robointel.outcome import Failure, TrialOutcome

Vector = npt.NDArray[np.float64]
Policy = Callable[[Vector], Vector]
"""A skill: the wrench (6,) [N; N m] in the tool frame about the sensor -> tool twist (5,) [vx, vy, vz, wx, wy]."""


@dataclass(frozen=True)
class SkillLimits:
    """The safety envelope of a skill run.

    Attributes:
        max_force: felt force norm (N) that stops the robot.
        max_torque: felt torque norm (N m) that stops the robot.
        max_speed: cap on the commanded TCP speed, m/s.
        max_angular_speed: cap on the commanded tool angular speed, rad/s.
        missing_wrench_periods: consecutive periods without a valid wrench before the run holds and raises.
    """

    max_force: float = 60.0
    max_torque: float = 6.0
    max_speed: float = 0.03
    max_angular_speed: float = 0.3
    missing_wrench_periods: int = 3

    def __post_init__(self) -> None:
        for name in ("max_force", "max_torque", "max_speed", "max_angular_speed"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InvalidInput(f"SkillLimits.{name} must be > 0, got {v!r}", value=v)
        if self.missing_wrench_periods < 1:
            raise InvalidInput("SkillLimits.missing_wrench_periods must be >= 1", value=self.missing_wrench_periods)


@dataclass
class SkillRun:
    """What a skill run on the interface recorded, one row per controller period.

    Attributes:
        outcome: success (the goal depth reached), or why not (force limit, timeout).
        t: (K,) robot time, s.
        q: (K, n) measured joints, rad.
        q_cmd: (K, n) targets sent, rad.
        wrench: (K, 6) the policy's input (tool frame about the sensor), N and N m.
        twist: (K, 5) the policy's output [m/s, rad/s].
        advance: (K,) TCP advance along the start tool axis (measured joints), m.
    """

    outcome: TrialOutcome
    t: Vector
    q: Vector
    q_cmd: Vector
    wrench: Vector
    twist: Vector
    advance: Vector
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """Whether the goal was reached within the limits."""
        return self.outcome.success


def tool_wrench(robot: Any, wrench_flange: Vector) -> Vector:
    """A flange-frame wrench (6,) in the tool axes (the robot's TCP rotation), torque still about the flange."""
    R = robot.tool[:3, :3]
    return np.concatenate([R.T @ wrench_flange[:3], R.T @ wrench_flange[3:]])


def world_wrench_at_tcp(robot: Any, q: Vector, wrench_flange: Vector) -> Vector:
    """A flange-frame wrench (6,) about the flange origin -> world axes, torque about the TCP."""
    R = robot.frame_pose(q, robot.flange_frame)[:3, :3]
    f, m = R @ wrench_flange[:3], R @ wrench_flange[3:]
    r = R @ robot.tool[:3, 3]
    return np.concatenate([f, m - np.cross(r, f)])


def twist_step(robot: Any, q_cmd: Vector, V: Vector, dt: float, limits: SkillLimits) -> Vector:
    """The next joint target q_cmd + J^#(q_cmd) V dt (3.12)-(3.13) with V capped by ``limits``, (n,) rad.

    Args:
        robot: :class:`robointel.robot.Robot` whose TCP is the twist's reference point.
        q_cmd: (n,) current target, rad.
        V: (6,) world twist [v (m/s); w (rad/s)] of the TCP.
        dt: period, s.
        limits: speed caps.
    """
    V = np.asarray(V, dtype=float).copy()
    for sl, cap in ((slice(0, 3), limits.max_speed), (slice(3, 6), limits.max_angular_speed)):
        n = float(np.linalg.norm(V[sl]))
        if n > cap:
            V[sl] *= cap / n
    qd = damped_pinv(robot.jacobian(q_cmd)) @ V
    ratio = float(np.max(np.abs(qd) / robot.velocity_limit))
    if ratio > 1.0:
        qd = qd / ratio
    return np.asarray(np.clip(q_cmd + qd * dt, robot.lower, robot.upper))


def read_wrench(source: WrenchSource, st: RobotState, missing: int, limits: SkillLimits,
                arm: Backend) -> tuple[Vector | None, int]:
    """The source's wrench, or None counted in ``missing``; too many misses hold the arm and raise SafetyStop."""
    w = source.wrench(st)
    if w is not None and np.all(np.isfinite(w)):
        return np.asarray(w, dtype=float), 0
    missing += 1
    if missing >= limits.missing_wrench_periods:
        arm.hold()
        raise SafetyStop(f"no valid wrench for {missing} periods: the skill holds the robot; check the F/T "
                         "sensor", value=w)
    return None, missing


def over_limits(w_flange: Vector, limits: SkillLimits) -> str:
    """Why the wrench breaks the limits ('' when it does not)."""
    f, m = float(np.linalg.norm(w_flange[:3])), float(np.linalg.norm(w_flange[3:]))
    if f > limits.max_force:
        return f"force limit: {f:.1f} N > {limits.max_force:.1f} N"
    if m > limits.max_torque:
        return f"torque limit: {m:.2f} N m > {limits.max_torque:.2f} N m"
    return ""


def run_insertion(arm: Backend, robot: Any, policy: Policy, depth: float, *, source: WrenchSource | None = None,
                  gains: AdmittanceGains | None = None, limits: SkillLimits | None = None,
                  time_limit: float = 10.0, tolerance: float = 1e-3,
                  on_cycle: Callable[[int, RobotState], None] | None = None) -> SkillRun:
    """Run an insertion skill on ``arm`` until the TCP has advanced ``depth`` m along the tool axis.

    Args:
        arm: the robot interface (``sim`` or ``fanuc``), at the start pose (the peg over the hole).
        robot: :class:`robointel.robot.Robot` of the arm whose ``tool`` is the skill's tool frame: z
            is the insertion axis, the origin the point the skill's twist moves (compliance centre).
        policy: the skill (:class:`~robointel.learning.insertion.InsertionSkill` ``.predict`` or a baseline).
        depth: how far (m) the TCP must advance along the start tool z axis (measured joints).
        source: where the wrench comes from (default: the state's sensor, uncompensated).
        gains: the admittance yield C of (3.11) added to the skill's twist (default: 1 mm/s per N,
            0.02 rad/s per N m, 0.5 N / 0.05 N m deadbands).
        limits: force, torque and speed limits.
        time_limit: s of robot time.
        tolerance: success when the advance is within this of ``depth``, m.
        on_cycle: called with (cycle, state) after each target.

    Returns:
        The :class:`SkillRun`; after a force limit the arm is stopped (``recover()`` to go on).

    Raises:
        InvalidInput: bad depth, time limit or a policy output that is not 5 finite numbers.
        SafetyStop: the wrench stopped arriving (the arm holds).
        UnsafeCommand, ControllerFault, ConnectionLost: from the interface (e-stop, fault, gate).
    """
    if not (np.isfinite(depth) and depth > 0):
        raise InvalidInput(f"depth must be > 0 m, got {depth}", value=depth)
    if not (np.isfinite(time_limit) and time_limit > 0):
        raise InvalidInput(f"time_limit must be > 0 s, got {time_limit}", value=time_limit)
    src = source if source is not None else StateWrench(robot)
    g = gains if gains is not None else AdmittanceGains(1e-3, 0.02, 0.5, 0.05)
    lim = limits if limits is not None else SkillLimits()
    st = arm.state()
    q_cmd = (st.q_cmd if st.q_cmd is not None else st.q).copy()
    T0 = robot.fk(st.q)
    axis, p0 = T0[:3, 2].copy(), T0[:3, 3].copy()
    K = int(round(time_limit / arm.period))
    n = len(q_cmd)
    ts, qs, qc = np.zeros(K), np.zeros((K, n)), np.zeros((K, n))
    ws, tws, adv = np.zeros((K, 6)), np.zeros((K, 5)), np.zeros(K)
    outcome = TrialOutcome(False, Failure.TIMEOUT, f"time limit {time_limit:g} s")
    missing, k, t0 = 0, 0, time.perf_counter()
    w_last = np.zeros(6)
    # a force loop: each target goes out at once, no queue; paced: a real-time section
    with arm.force_loop():
        try:
            for k in range(K):
                if arm.paced:
                    sleep_until(t0 + k * arm.period)
                st = arm.state()
                w, missing = read_wrench(src, st, missing, lim, arm)
                w = w_last if w is None else w
                w_last = w
                a = float(axis @ (robot.fk(st.q)[:3, 3] - p0))
                ts[k], qs[k], qc[k], ws[k], adv[k] = st.t, st.q, q_cmd, tool_wrench(robot, w), a
                why = over_limits(w, lim)
                if why:
                    arm.stop(f"insertion skill: {why}")
                    outcome = TrialOutcome(False, Failure.FORCE_LIMIT, why)
                    break
                if a >= depth - tolerance:
                    outcome = TrialOutcome(True, figures={"time_s": float(k * arm.period)})
                    break
                tw = np.asarray(policy(ws[k]), dtype=float)
                if tw.shape != (5,) or not np.all(np.isfinite(tw)):
                    raise InvalidInput(f"the skill must return 5 finite numbers [vx, vy, vz, wx, wy], got {tw}",
                                       value=tw)
                tws[k] = tw
                R = robot.fk(q_cmd)[:3, :3]
                V = np.concatenate([R @ tw[:3], R @ np.array([tw[3], tw[4], 0.0])])
                V += admittance_twist(world_wrench_at_tcp(robot, st.q, w), g)
                q_cmd = twist_step(robot, q_cmd, V, arm.period, lim)
                arm.stream(q_cmd)
                qc[k] = q_cmd
                if on_cycle is not None:
                    on_cycle(k, st)
        finally:
            arm.hold()
    m = k + 1
    figs = dict(outcome.figures, max_force_n=float(np.max(np.linalg.norm(ws[:m, :3], axis=1))),
                advance_m=float(adv[m - 1]))
    outcome = TrialOutcome(outcome.success, outcome.reason, outcome.detail, figs)
    return SkillRun(outcome, ts[:m], qs[:m], qc[:m], ws[:m], tws[:m], adv[:m])
