"""The LR Mate 200iD/7L with the demonstration device's tool at its flange, over a task, in MuJoCo.

The robot model is :func:`robointel.sim.build_spec` (the robot core's URDF, table, motors, reflected
rotor inertia); the task's environment and the tool (with its F/T sensor) are added to that spec.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from robointel.control import JointController, model_with_payload
from robointel.geometry.rotations import rotation_about, so3_exp
from robointel.learning.hdd import Tool, ToolFT, add_tool_sensors
from robointel.learning.insertion.impedance import CartesianImpedance, ImpedanceGains
from robointel.learning.insertion.peg_hole import PegHole, tip_point, wall_geom_range, wall_penetration
from robointel.outcome import Failure, TrialOutcome
from robointel.robot import Robot
from robointel.sim import Payload, build_spec

#: tool frame in the flange frame: the tool axis (z) is the flange's approach axis (x)
R_FLANGE_TOOL = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
#: reflected motor-rotor inertia of the LR Mate's joints (kg m^2), in MuJoCo and in the controller's model
ARMATURE = (0.5, 0.5, 0.2, 0.05, 0.05, 0.02)

#: an insertion policy: felt wrench (6,) [N; N m] in the tool frame -> tool twist [vx, vy, vz, wx, wy] (m/s, rad/s);
#: a policy whose ``proprioceptive`` attribute is true is also given the tool pose (4, 4) relative to its pose at
#: the first call, and is ``reset()`` before each trial
Policy = Callable[..., npt.NDArray[np.float64]]


@dataclass(frozen=True)
class InsertionTrial:
    """One insertion by the robot.

    Attributes:
        outcome: The shared trial outcome (success, :class:`Failure` reason, figures).
        seated: Tip within 1 mm of the bottom.
        depth_error: Final tip height above the bottom (m).
        max_penetration: Deepest penetration into the hole wall (m).
        time: Time to seat, or to the stop (s).
        max_force: Largest felt force (N).
        t: (n,) log times (s) at 100 Hz.
        tip: (n, 3) tip positions (m).
        wrench: (n, 6) felt wrenches (tool frame).
        twist: (n, 5) policy outputs.
    """

    outcome: TrialOutcome
    seated: bool
    depth_error: float
    max_penetration: float
    time: float
    max_force: float
    t: npt.NDArray[np.float64]
    tip: npt.NDArray[np.float64]
    wrench: npt.NDArray[np.float64]
    twist: npt.NDArray[np.float64]

    @property
    def success(self) -> bool:
        """Whether the peg was seated without pressing into the wall."""
        return self.outcome.success

    @property
    def reason(self) -> str:
        """The outcome's failure reason and detail as text."""
        return self.outcome.detail or self.outcome.reason.value


class RobotCell:
    """The LR Mate with a :class:`Tool` at its flange over a task (the peg-hole or a grinding plate).

    Two controllers: :meth:`insert`, a torque-level Cartesian impedance (:class:`CartesianImpedance`)
    whose equilibrium an insertion policy moves, and :meth:`insert_position_only`, the sim module's stiff
    joint servo (PID + inverse-dynamics feed-forward, Fig. 2.3) tracking a straight line (the
    position-only baseline). :meth:`servo_step` exposes the joint servo to other tasks (grinding).
    """

    def __init__(self, task: Any = None, robot: Robot | None = None, *, tool: Tool | None = None,
                 interference: float = 0.0, armature: tuple[float, ...] = ARMATURE) -> None:
        """Build the cell.

        Args:
            task: The task (default: :class:`PegHole`): builds its environment into a spec, names its tool,
                its ``contact`` settings and a ``pre_insert_pose``.
            robot: The robot (default: the LR Mate 200iD/7L).
            tool: The tool (default: the task's, with ``interference`` for a peg-hole).
            interference: Diametral oversize (m) of the peg-hole's peg.
            armature: (6,) reflected rotor inertias (kg m^2).
        """
        self.task: Any = task or PegHole()
        self.robot = robot if robot is not None else Robot.load("lrmate200id7l")
        if tool is None:
            tool = self.task.tool(interference=interference) if isinstance(self.task, PegHole) else self.task.tool()
        self.tool = tool
        self.armature = np.asarray(armature, float)
        spec, _ = build_spec(self.robot, table=True, ft_sensor=False, armature=self.armature)
        self.task.build(spec)
        self.tool.add_to(spec.body("tool"), self.task.contact, R_body_tool=R_FLANGE_TOOL, contype=1, conaffinity=2)
        add_tool_sensors(spec)
        self.spec = spec
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.qadr = np.array([m.jnt_qposadr[m.joint(n).id] for n in self.robot.joint_names])
        self.vadr = np.array([m.jnt_dofadr[m.joint(n).id] for n in self.robot.joint_names])
        self.aid = np.array([m.actuator(n).id for n in self.robot.joint_names])
        self.ft = ToolFT(m, self.tool)
        self._walls = wall_geom_range(m)
        self._peg = m.geom(self.tool.name + "/peg").id
        t = self.tool
        I_tool = np.diag([t.mass * (3 * t.radius ** 2 + t.length ** 2) / 12] * 2 + [0.5 * t.mass * t.radius ** 2])
        payload = Payload(mass=t.mass, com=R_FLANGE_TOOL @ t.com, inertia=R_FLANGE_TOOL @ I_tool @ R_FLANGE_TOOL.T)
        pin_model = model_with_payload(self.robot, payload)
        pin_model.armature = self.armature.copy()
        self.controller = JointController(self.robot, model=pin_model)
        self.T_flange_tool = np.eye(4)
        self.T_flange_tool[:3, :3] = R_FLANGE_TOOL
        self._q_nominal: npt.NDArray[np.float64] | None = None

    # ------------------------------------------------------------------ poses
    def flange_target(self, T_tool: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Flange pose (4, 4) that puts the tool frame at ``T_tool`` (4, 4)."""
        return T_tool @ np.linalg.inv(self.T_flange_tool)

    def ik(self, T_tool: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Joint configuration (6,) rad placing the tool frame at ``T_tool`` (closed-form IK, elbow up)."""
        if self._q_nominal is None:
            T_pre = self.task.pre_insert_pose(self.tool)
            self._q_nominal = self.robot.ik(self.flange_target(T_pre), q_ref=np.array([0, 0.5, -0.4, 0, -0.7, 0]))[0]
        return self.robot.ik(self.flange_target(T_tool), q_ref=self._q_nominal)[0]

    def tool_pose(self) -> npt.NDArray[np.float64]:
        """The tool's (4, 4) world pose now."""
        return self.ft.pose(self.data)

    def start_pose(self, lateral: npt.ArrayLike, tilt_axis_angle: tuple[float, float]) -> npt.NDArray[np.float64]:
        """Pre-insertion tool pose with a pose error.

        Args:
            lateral: (2,) lateral offset of the tip in the table plane (m).
            tilt_axis_angle: (phi, tilt): a tilt of ``tilt`` rad about the horizontal axis at angle ``phi``
                (rad), about the tip point.

        Returns:
            The (4, 4) tool pose.
        """
        if not isinstance(self.task, PegHole):
            raise TypeError("start_pose needs a PegHole task")
        T = self.task.pre_insert_pose(self.tool)
        phi, tilt = tilt_axis_angle
        R = rotation_about(np.array([np.cos(phi), np.sin(phi), 0.0]), tilt)
        tip = tip_point(T, self.tool)
        lat = np.asarray(lateral, float)
        T2 = np.eye(4)
        T2[:3, :3] = R @ T[:3, :3]
        T2[:3, 3] = tip - T2[:3, 2] * self.tool.tip + np.array([lat[0], lat[1], 0.0])
        return T2

    # ------------------------------------------------------------------ joint servo
    def reset(self, q: npt.NDArray[np.float64], settle: float = 0.3) -> None:
        """Put the robot at ``q`` (6,) rad and hold it there with the joint servo for ``settle`` s."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self.qadr] = q
        mujoco.mj_forward(self.model, self.data)
        self.controller.reset()
        z = np.zeros(len(q))
        for _ in range(int(settle / self.model.opt.timestep)):
            self.servo_step(q, z)

    def servo_step(self, q_ref: npt.NDArray[np.float64], qd_ref: npt.NDArray[np.float64]) -> None:
        """One 1 ms step of the joint servo toward ``q_ref`` (6,) rad, ``qd_ref`` (6,) rad/s."""
        d = self.data
        tau = self.controller.compute(d.qpos[self.qadr], d.qvel[self.vadr], q_ref, qd_ref, np.zeros(len(q_ref)))
        d.ctrl[self.aid] = tau
        mujoco.mj_step(self.model, d)

    def _penetration(self) -> float:
        return wall_penetration(self.data, self._walls, self._peg)

    def _finish(self, seated: bool, stop: Failure, detail: str, max_pen: float, time: float, max_force: float,
                logs: list[list[npt.NDArray[np.float64]]], log_t: list[float]) -> InsertionTrial:
        bottom = self.task.bottom_z if isinstance(self.task, PegHole) else 0.0
        depth = float(tip_point(self.ft.pose(self.data), self.tool)[2] - bottom)
        clearance = self.task.clearance if isinstance(self.task, PegHole) else np.inf
        ok_pen = max_pen < 0.5 * clearance
        if seated and not ok_pen:
            stop, detail = Failure.COLLISION, "seated but wall penetration exceeded half the clearance"
        success = seated and ok_pen
        outcome = TrialOutcome(success, Failure.NONE if success else stop, "" if success else detail,
                               figures={"time_s": time, "max_force_n": max_force, "max_penetration_m": max_pen,
                                        "depth_error_m": depth})
        arr = [np.array(x) for x in logs]
        return InsertionTrial(outcome, seated, depth, max_pen, time, max_force, np.array(log_t), *arr)

    def insert_position_only(self, T_start: npt.NDArray[np.float64], *, time_limit: float = 10.0,
                             speed: float = 0.008, f_abort: float = 150.0, force_noise: float = 0.05,
                             torque_noise: float = 0.002, seed: int = 0) -> InsertionTrial:
        """The position-only baseline: the stiff joint servo drives the tool along its axis, no force feedback.

        Args:
            T_start: (4, 4) start tool pose.
            time_limit: Trial time limit (s).
            speed: Speed along the tool axis (m/s).
            f_abort: Felt force (N) that stops the trial (a safety stop: failure).
            force_noise: F/T force noise std (N).
            torque_noise: F/T torque noise std (N m).
            seed: Seed of the sensor noise.

        Returns:
            The trial.
        """
        if not isinstance(self.task, PegHole):
            raise TypeError("insertion needs a PegHole task")
        rng = np.random.default_rng(seed)
        q_ref = self.ik(T_start)
        self.reset(q_ref)
        dt = float(self.model.opt.timestep)
        T = self.ft.pose(self.data)
        a = T[:3, 2]
        v_flange = np.concatenate([a * speed, np.zeros(3)])
        max_pen, max_force = 0.0, 0.0
        logs: list[list[npt.NDArray[np.float64]]] = [[], [], [], []]
        log_t: list[float] = []
        stop, detail, seated = Failure.TIMEOUT, "time limit", False
        k = 0
        for k in range(int(time_limit / dt)):
            T = self.ft.pose(self.data)
            w = self.ft.wrench(self.data, T[:3, :3])
            w[:3] += force_noise * rng.standard_normal(3)
            w[3:] += torque_noise * rng.standard_normal(3)
            tip = tip_point(T, self.tool)
            fmag = float(np.linalg.norm(w[:3]))
            max_force = max(max_force, fmag)
            if k % 10 == 0:
                log_t.append(k * dt)
                for lst, v in zip(logs, (tip, w, np.array([0.0, 0.0, speed, 0.0, 0.0])), strict=False):
                    lst.append(v)
            if tip[2] - self.task.bottom_z <= 1e-3:
                seated = True
                break
            if fmag > f_abort:
                stop, detail = Failure.FORCE_LIMIT, "force limit (safety stop)"
                break
            qd_ref = np.linalg.solve(self.robot.jacobian(q_ref), v_flange)
            q_ref = q_ref + qd_ref * dt
            self.servo_step(q_ref, qd_ref)
            max_pen = max(max_pen, self._penetration())
        return self._finish(seated, stop, detail, max_pen, float(k * dt), max_force, logs[:3], log_t)

    # ------------------------------------------------------------------ torque-level impedance
    def impedance(self, gains: ImpedanceGains | None = None) -> CartesianImpedance:
        """The cell's torque-level :class:`CartesianImpedance`.

        The Pinocchio model carries the tool as payload and the armature; the compliance centre is on the
        tool axis (default: the tip sphere's centre).

        Args:
            gains: The impedance gains (default :class:`ImpedanceGains`).

        Returns:
            The controller.
        """
        g = gains or ImpedanceGains()
        back = g.center_from_tip if g.center_from_tip is not None else self.tool.radius
        T_fc = self.T_flange_tool.copy()
        T_fc[:3, 3] = R_FLANGE_TOOL @ np.array([0.0, 0.0, self.tool.tip - back])
        return CartesianImpedance(self.controller.model, self.robot.flange_frame, T_fc, g, self.robot.viscous,
                                  self.robot.coulomb, self.controller.effort_limit)

    def insert(self, policy: Policy, T_start: npt.NDArray[np.float64], *, time_limit: float = 10.0,
               gains: ImpedanceGains | None = None, f_abort: float = 150.0, policy_dt: float = 0.01,
               force_noise: float = 0.05, torque_noise: float = 0.002, settle: float = 0.3,
               seed: int = 0) -> InsertionTrial:
        """One insertion from ``T_start`` under the torque-level Cartesian impedance, driven by ``policy``.

        The motors get tau = J^T W + h(q, qd) + friction (:class:`CartesianImpedance`); there is no joint
        position servo and no knowledge of the hole: only the F/T sensor and the robot's kinematics. Every
        ``policy_dt`` the policy maps the felt wrench (6,) (tool frame, with sensor noise) to a tool twist
        [vx, vy, vz, wx, wy]: [vx, vy] moves the impedance equilibrium laterally, [wx, wy] rotates it about the
        compliance centre, and vz is the speed of the force-limited axial damper (5.17). A proprioceptive
        policy (``policy.proprioceptive`` true, e.g. :class:`~robointel.learning.insertion.felt.FeltStrategy`)
        is reset first and also gets the tool pose relative to the first call (the arm's kinematics, no
        world frame).

        Args:
            policy: Wrench -> tool twist (the learned skill, a constant push, a hand-tuned admittance).
            T_start: (4, 4) start tool pose.
            time_limit: Trial time limit (s).
            gains: Impedance gains.
            f_abort: Felt force (N) that stops the trial (a safety stop: failure).
            policy_dt: Period of the policy (s).
            force_noise: F/T force noise std (N).
            torque_noise: F/T torque noise std (N m).
            settle: Hold time at the start pose before the trial (s).
            seed: Seed of the sensor noise.

        Returns:
            The trial: success when the tip is within 1 mm of the bottom with the wall penetration below half
            the clearance, within ``time_limit``.
        """
        if not isinstance(self.task, PegHole):
            raise TypeError("insertion needs a PegHole task")
        g = gains or ImpedanceGains()
        imp = self.impedance(g)
        rng = np.random.default_rng(seed)
        q0 = self.ik(T_start)
        d, m = self.data, self.model
        mujoco.mj_resetData(m, d)
        d.qpos[self.qadr] = q0
        mujoco.mj_forward(m, d)
        imp.set_gains(q0)
        dt = float(m.opt.timestep)
        n_policy = max(1, int(round(policy_dt / dt)))
        x0, R0, _, _ = imp.pose_twist(q0, np.zeros(len(q0)))
        for _ in range(int(settle / dt)):
            d.ctrl[self.aid] = imp.torque(d.qpos[self.qadr], d.qvel[self.vadr], x0, R0, 0.0)[0]
            mujoco.mj_step(m, d)
        imp.set_gains(d.qpos[self.qadr].copy(), lateral_stiffness=g.insert_lateral_stiffness)
        tw = np.zeros(5)
        max_pen, max_force = 0.0, 0.0
        logs: list[list[npt.NDArray[np.float64]]] = [[], [], []]
        log_t: list[float] = []
        stop, detail, seated = Failure.TIMEOUT, "time limit", False
        proprio = bool(getattr(policy, "proprioceptive", False))
        if proprio:
            policy.reset()  # type: ignore[attr-defined]
        T_first: npt.NDArray[np.float64] | None = None
        k = 0
        for k in range(int(time_limit / dt)):
            q, qd = d.qpos[self.qadr], d.qvel[self.vadr]
            T = self.ft.pose(d)
            w = self.ft.wrench(d, T[:3, :3])
            w[:3] += force_noise * rng.standard_normal(3)
            w[3:] += torque_noise * rng.standard_normal(3)
            tip = tip_point(T, self.tool)
            fmag = float(np.linalg.norm(w[:3]))
            max_force = max(max_force, fmag)
            if tip[2] - self.task.bottom_z <= 1e-3:
                seated = True
                break
            if fmag > f_abort:
                stop, detail = Failure.FORCE_LIMIT, "force limit (safety stop)"
                break
            if k % n_policy == 0:
                if T_first is None:
                    T_first = T.copy()
                if proprio:
                    tw = np.asarray(policy(w, np.linalg.solve(T_first, T)), float)  # type: ignore[call-arg]
                else:
                    tw = np.asarray(policy(w), float)
            if k % 10 == 0:
                log_t.append(k * dt)
                for lst, v in zip(logs, (tip, w, tw.copy()), strict=True):
                    lst.append(v)
            x, R, _, _ = imp.pose_twist(q, qd)
            x0 = x0 + R @ np.array([tw[0], tw[1], 0.0]) * dt
            x0 = x0 + R[:, 2] * (R[:, 2] @ (x - x0))  # no axial spring: the axis is force controlled
            R0 = so3_exp(R @ np.array([tw[3], tw[4], 0.0]) * dt) @ R0
            d.ctrl[self.aid] = imp.torque(q, qd, x0, R0, float(tw[2]), np.array([*tw, 0.0]))[0]
            mujoco.mj_step(m, d)
            max_pen = max(max_pen, self._penetration())
        if stop is Failure.TIMEOUT and not seated:
            depth = self.task.top[2] - tip_point(self.ft.pose(d), self.tool)[2]
            if depth > self.tool.radius - 1e-3:
                stop, detail = Failure.WEDGED, f"time limit with the peg stuck {1e3 * depth:.1f} mm deep"
        return self._finish(seated, stop, detail, max_pen, float(k * dt), max_force, logs, log_t)


def random_start_errors(rng: np.random.Generator, n: int, *, lateral: float = 2e-3,
                        max_tilt: float = np.radians(5.0)) -> list[tuple[npt.NDArray[np.float64], tuple[float, float]]]:
    """``n`` randomised start errors for :meth:`RobotCell.start_pose`.

    Args:
        rng: The random generator.
        n: Number of starts.
        lateral: Lateral error bound (m), uniform in +/- per axis.
        max_tilt: Tilt bound (rad), uniform in [0, max_tilt] about a random horizontal axis.

    Returns:
        ``n`` pairs (lateral (2,), (phi, tilt)).
    """
    return [(rng.uniform(-lateral, lateral, 2), (float(rng.uniform(0, 2 * np.pi)), float(rng.uniform(0, max_tilt))))
            for _ in range(n)]

