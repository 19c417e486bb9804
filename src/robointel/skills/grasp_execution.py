"""Execute a grasp on any robot interface: approach, descend, close, lift; the gripper beside the arm.

A :class:`GraspMotion` (the grasp frame's world pose, the opening, the approach distance back along
the grasp's z, the lift height) becomes three joint trajectories, each timed by the jerk-limited
follower (ruckig, rest to rest, within ``speed`` of the joint limits) and streamed through
``arm.execute``; the gripper opens before the approach and closes at the grasp pose. The grasp pose
comes from the Ch. 6 pipeline (``GraspPlan.search``: the grasp and its IK solution) or any planner.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel.control.follower import JerkLimitedFollower
from robointel.errors import IKFailure, InvalidInput
from robointel.interface.backend import Backend, ExecutionResult
from robointel.interface.gripper import Gripper, GripResult
from robointel.interface.protocol import CycleCallback
from robointel.outcome import Failure, TrialOutcome
from robointel.trajectory import Trajectory

Vector = npt.NDArray[np.float64]


@dataclass(frozen=True)
class GraspMotion:
    """What to execute.

    Attributes:
        grasp: (4, 4) world pose of the grasp frame (origin between the pads, y closing axis, z approach).
        width: opening before the approach, m.
        approach: pre-grasp distance back along the grasp's z, m.
        lift: lift height along world z after closing, m.
        q_grasp: (n,) joint solution at the grasp (None: the IK solution nearest the arm's posture).
    """

    grasp: Vector
    width: float
    approach: float = 0.08
    lift: float = 0.10
    q_grasp: Vector | None = None

    def __post_init__(self) -> None:
        G = np.asarray(self.grasp, dtype=float)
        if G.shape != (4, 4) or not np.all(np.isfinite(G)):
            raise InvalidInput("GraspMotion.grasp must be a finite 4x4 pose", value=self.grasp)
        R = G[:3, :3]
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise InvalidInput("GraspMotion.grasp must hold a proper rotation", value=self.grasp)
        for name in ("width", "approach", "lift"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v >= 0):
                raise InvalidInput(f"GraspMotion.{name} must be finite and >= 0, got {v}", value=v)
        if not self.width > 0:
            raise InvalidInput(f"GraspMotion.width must be > 0 m, got {self.width}", value=self.width)
        object.__setattr__(self, "grasp", G)

    def poses(self) -> tuple[Vector, Vector, Vector]:
        """(pre-grasp, grasp, lifted) world poses of the grasp frame, each (4, 4)."""
        pre, up = self.grasp.copy(), self.grasp.copy()
        pre[:3, 3] -= self.approach * self.grasp[:3, 2]
        up[2, 3] += self.lift
        return pre, self.grasp, up


@dataclass
class GraspRun:
    """What the execution did: the outcome, each phase's execution and the gripper's answers."""

    outcome: TrialOutcome
    q: dict[str, Vector] = field(default_factory=dict)
    phases: dict[str, ExecutionResult] = field(default_factory=dict)
    grip: dict[str, GripResult] = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """The object was gripped and lifted."""
        return self.outcome.success


def joint_move(robot: Any, q0: npt.ArrayLike, q1: npt.ArrayLike, dt: float, *, speed: float = 0.3) -> Trajectory:
    """A jerk-limited rest-to-rest joint motion q0 -> q1 (ruckig), sampled every ``dt`` s.

    Args:
        robot: :class:`robointel.robot.Robot` (velocity and acceleration limits, joint names).
        q0: (n,) start, rad.
        q1: (n,) goal, rad.
        dt: sample period, s (the controller's).
        speed: share of the joint velocity and acceleration limits used, in (0, 1].

    Returns:
        The :class:`Trajectory` (at least two samples).

    Raises:
        InvalidInput: ``speed`` outside (0, 1].
    """
    if not (0 < speed <= 1):
        raise InvalidInput(f"speed must be in (0, 1], got {speed}", value=speed)
    a, b = robot.check_q(q0), robot.check_q(q1)
    vmax = speed * np.asarray(robot.velocity_limit, dtype=float)
    amax = speed * np.asarray(robot.acceleration_limit, dtype=float)
    f = JerkLimitedFollower(vmax, amax, 20.0 * amax, dt=dt)
    f.reset(a)
    qs, vs, accs = [a], [np.zeros_like(a)], [np.zeros_like(a)]
    for _ in range(int(600.0 / dt)):
        q, v, acc = f.step_position(b)
        qs.append(q)
        vs.append(v)
        accs.append(acc)
        if f.at_rest and np.allclose(q, b, atol=1e-9):
            break
    qs[-1] = b
    return Trajectory(np.arange(len(qs), dtype=np.float64) * dt, np.array(qs), np.array(vs), np.array(accs),
                      list(robot.joint_names))


def execute_grasp(arm: Backend, gripper: Gripper, robot: Any, motion: GraspMotion, *, speed: float = 0.3,
                  on_cycle: CycleCallback | None = None) -> GraspRun:
    """Open, approach the pre-grasp, descend to the grasp, close, lift; stop at the first failure.

    Args:
        arm: the robot interface at rest.
        gripper: the gripper beside it (:class:`~robointel.interface.gripper.SimGripper`,
            :class:`~robointel.interface.gripper.FanucGripper`).
        robot: :class:`robointel.robot.Robot` whose ``tool`` is the grasp frame.
        motion: the :class:`GraspMotion`.
        speed: share of the joint limits used by the moves (the descent and lift use half of it).
        on_cycle: passed to every ``arm.execute``.

    Returns:
        The :class:`GraspRun`: success when the gripper held something after closing and the lift completed.

    Raises:
        UnsafeCommand, ControllerFault, ConnectionLost: from the interface or the gripper (the arm holds/stops).
    """
    st = arm.state()
    q_start = np.asarray(st.q_cmd if st.q_cmd is not None else st.q, dtype=float)
    pre, G, up = motion.poses()
    try:
        q_grasp = (robot.check_q(motion.q_grasp) if motion.q_grasp is not None
                   else np.asarray(robot.ik(G, q_ref=q_start)[0]))
        q_pre = np.asarray(robot.ik(pre, q_ref=q_grasp)[0])
        q_up = np.asarray(robot.ik(up, q_ref=q_grasp)[0])
    except IKFailure as exc:
        return GraspRun(TrialOutcome(False, Failure.IK, f"approach, grasp or lift unreachable: {exc}"))
    run = GraspRun(TrialOutcome(True), q={"start": q_start, "pre": q_pre, "grasp": q_grasp, "up": q_up})
    run.grip["open"] = gripper.open(min(motion.width, gripper.max_width))
    dt = arm.period
    for name, a, b, s in (("approach", q_start, q_pre, speed), ("descend", q_pre, q_grasp, 0.5 * speed)):
        run.phases[name] = arm.execute(joint_move(robot, a, b, dt, speed=s), on_cycle=on_cycle)
    run.grip["close"] = close = gripper.close()
    if not close.success:
        run.phases["retreat"] = arm.execute(joint_move(robot, q_grasp, q_pre, dt, speed=0.5 * speed),
                                            on_cycle=on_cycle)
        run.outcome = TrialOutcome(False, Failure.NO_GRASP, close.message)
        return run
    run.phases["lift"] = arm.execute(joint_move(robot, q_grasp, q_up, dt, speed=0.5 * speed), on_cycle=on_cycle)
    run.outcome = TrialOutcome(True, detail=close.message, figures={"grip_width_m": close.width})
    return run
