"""A learned grinding skill on any robot interface: a force set-point map over streamed joint positions.

The tool's TCP follows a straight path across the workpiece, position controlled sideways; along the
tool axis an admittance moves the target by ``v = k_force (F_set - F_filtered)`` (the skill's set-point
from the tool position (5.14)-(5.17), the felt pressing force low-passed). The Cartesian target becomes
the next joint position target by one damped-pseudo-inverse step (3.12)-(3.13) from the last target,
through the interface's safety gate; force, torque and speed limits as for the insertion skill.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput
from robointel.geometry.rotations import so3_log
from robointel.interface.backend import Backend
from robointel.interface.state import RobotState
from robointel.interface.tick_pacer import TickPacer
from robointel.interface.wrench_source import StateWrench, WrenchSource
from robointel.outcome import Failure, TrialOutcome
from robointel.skills.insertion import SkillLimits, over_limits, read_wrench, tool_wrench, twist_step

Vector = npt.NDArray[np.float64]
SetPoint = Callable[[Vector], float]
"""The skill: world TCP position (3,) m -> pressing force set-point, N."""


@dataclass
class GrindingRun:
    """A grinding pass on the interface, one row per controller period.

    Attributes:
        outcome: success when the path was completed within the limits.
        t: (K,) robot time, s.
        position: (K, 3) measured TCP position, m.
        force: (K,) felt pressing force along the tool axis, N.
        setpoint: (K,) the skill's set-point, N.
        on_path: (K,) the row is on the path (after the touch-down), not in the touch phase.
    """

    outcome: TrialOutcome
    t: Vector
    position: Vector
    force: Vector
    setpoint: Vector
    on_path: npt.NDArray[np.bool_]

    def rms_rel(self, reference: Vector | None = None) -> float:
        """RMS(force - reference) / max |reference| on the path (reference: the set-point)."""
        ref = self.setpoint if reference is None else np.asarray(reference, dtype=float)
        m = self.on_path
        return float(np.sqrt(np.mean((self.force[m] - ref[m]) ** 2)) / max(np.max(np.abs(ref[m])), 1e-9))


def run_grinding(arm: Backend, robot: Any, setpoint: SetPoint, start: npt.ArrayLike, end: npt.ArrayLike, *,
                 source: WrenchSource | None = None, speed: float = 0.03, k_force: float = 1.0 / 3000.0,
                 filter_hz: float = 5.0, t_touch: float = 1.0, limits: SkillLimits | None = None,
                 on_cycle: Callable[[int, RobotState], None] | None = None) -> GrindingRun:
    """Press and move the TCP from ``start`` to ``end`` with the force the skill asks for.

    Args:
        arm: the robot interface, at the start pose (the tool just above the surface at ``start``).
        robot: :class:`robointel.robot.Robot` whose ``tool`` is the tool frame (z: the pressing axis).
        setpoint: the learned force map (TCP position (3,) m -> N).
        start: (3,) world start point of the TCP path, m (its height is the arm's current one).
        end: (3,) world end point, m (only the lateral motion is commanded: the axis is force controlled).
        source: where the wrench comes from (default: the state's sensor, uncompensated).
        speed: path speed, m/s.
        k_force: admittance gain along the axis, m/(N s).
        filter_hz: cut-off of the force low-pass, Hz.
        t_touch: pressing at the start before moving, s.
        limits: force, torque and speed limits.
        on_cycle: called with (cycle, state) after each target.

    Returns:
        The :class:`GrindingRun`; after a force limit the arm is stopped.

    Raises:
        InvalidInput: bad path, speed or gains. SafetyStop: the wrench stopped arriving (the arm holds).
        UnsafeCommand, ControllerFault, ConnectionLost: from the interface.
    """
    a, b = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    if a.shape != (3,) or b.shape != (3,) or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise InvalidInput("start and end must be 3 finite numbers (m)", value=(start, end))
    for name, v in (("speed", speed), ("k_force", k_force), ("filter_hz", filter_hz)):
        if not (np.isfinite(v) and v > 0):
            raise InvalidInput(f"{name} must be > 0, got {v}", value=v)
    if not (np.isfinite(t_touch) and t_touch >= 0):
        raise InvalidInput(f"t_touch must be >= 0 s, got {t_touch}", value=t_touch)
    src = source if source is not None else StateWrench(robot)
    lim = limits if limits is not None else SkillLimits(max_speed=max(2 * speed, 0.03))
    dt = arm.period
    st = arm.state()
    q_cmd = (st.q_cmd if st.q_cmd is not None else st.q).copy()
    T0 = robot.fk(q_cmd)
    R0, axis = T0[:3, :3].copy(), T0[:3, 2].copy()
    lateral = (b - a) - axis * (axis @ (b - a))
    L = float(np.linalg.norm(lateral))
    K = int(np.ceil((t_touch + L / speed) / dt)) + 1
    alpha = 1.0 - np.exp(-2 * np.pi * filter_hz * dt)
    ts, ps, fs, sps = np.zeros(K), np.zeros((K, 3)), np.zeros(K), np.zeros(K)
    on = np.zeros(K, dtype=bool)
    p_line, z = T0[:3, 3].copy(), 0.0  # z: offset of the target along the axis
    f_filt, missing, k = 0.0, 0, 0
    w_last = np.zeros(6)
    outcome = TrialOutcome(True)
    pacer = TickPacer(arm)  # on a clocked robot each cycle answers the newest state at once
    # a force loop: each target goes out at once, no queue; paced: a real-time section
    with arm.force_loop():
        try:
            for k in range(K):
                st = pacer.next()
                w, missing = read_wrench(src, st, missing, lim, arm)
                w = w_last if w is None else w
                w_last = w
                push = -float(tool_wrench(robot, w)[2])  # the surface pushes back against the tool axis
                f_filt += alpha * (push - f_filt)
                p_meas = robot.fk(st.q)[:3, 3]
                f_set = float(setpoint(p_meas))
                ts[k], ps[k], fs[k], sps[k], on[k] = st.t, p_meas, push, f_set, k * dt >= t_touch
                why = over_limits(w, lim)
                if why:
                    arm.stop(f"grinding skill: {why}")
                    outcome = TrialOutcome(False, Failure.FORCE_LIMIT, why)
                    break
                s = float(np.clip((k * dt - t_touch) * speed / L, 0.0, 1.0)) if L > 0 else 1.0
                z += k_force * (f_set - f_filt) * dt  # press deeper while the felt force is below the set-point
                target = p_line + s * lateral + axis * z
                Tc = robot.fk(q_cmd)
                V = np.concatenate([(target - Tc[:3, 3]) / dt, so3_log(R0 @ Tc[:3, :3].T) / dt])
                q_cmd = twist_step(robot, q_cmd, V, dt, lim)
                arm.stream(q_cmd)
                if on_cycle is not None:
                    on_cycle(k, st)
        finally:
            arm.hold()
    m = k + 1
    return GrindingRun(outcome, ts[:m], ps[:m], fs[:m], sps[:m], on[:m])
