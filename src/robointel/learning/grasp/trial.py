"""MuJoCo lift-and-shake grasp trials (Table 6.2).

:func:`grasp_trial` places an object at a random pose, perceives it with the two simulated depth
cameras, plans with a :class:`~robointel.learning.grasp.pipeline.GraspPlanner`, then has the whole LR
Mate in MuJoCo (joint servos, links colliding, the gripper on its flange) follow the joint path (park,
hover, pre-grasp, grasp, close, lift 10 cm, shake with J1 and J6) and reports success when the object
rose and is still between the fingers at the end (``arm=False``: the earlier simplification, the
gripper alone on the path's forward kinematics).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from robointel.errors import IKFailure, InvalidInput
from robointel.learning.grasp.hand import (
    EMPTY_OPENING,
    HandReading,
    HandVerdict,
    after_close,
    after_lift,
    between_jaws,
    read_hand,
)
from robointel.learning.grasp.objects import ObjectModel
from robointel.learning.grasp.perception import DepthCamera, default_cameras, depth_image, perceive
from robointel.learning.grasp.pipeline import GraspPlan, GraspPlanner
from robointel.learning.grasp.quality import (
    ParallelGripper,
)
from robointel.learning.grasp.scene import ARM_KP, ARM_KV, Placement, arm_scene, close_command, scene_xml
from robointel.learning.grasp.search import PRE_GRASP
from robointel.learning.grasp.transfer import Grasp
from robointel.robot import Robot

__all__ = ["ATTEMPTS", "HOVER_CLEARANCE", "LIFT_MIN", "PHASES", "Q_PARK", "SETTLE_MAX", "GraspTrialResult",
           "grasp_trial", "settle_until_at_rest"]


@dataclass
class GraspTrialResult:
    """One lift-and-shake trial's result.

    One lift-and-shake trial: ``success``, the planned ``plan`` (None if perception failed),
    the predicted ``category``, the object's final height (m), a ``reason`` and a ``log``: the state at
    the end of each phase (:data:`PHASES`, each entry with its ``attempt``; see :func:`_phase_state`),
    ``settle_s``: the simulated time (s) the object took to come to rest before the cameras looked,
    ``attempts``: the grasp attempts made (0 when none was: nothing perceived or planned), and
    ``let_go``: why each attempt the hand's checks rejected was let go.
    """

    success: bool
    reason: str
    category: str | None = None
    plan: GraspPlan | None = None
    final_height: float = float("nan")
    cloud: np.ndarray | None = None
    log: list[dict[str, Any]] = field(default_factory=list)
    settle_s: float = float("nan")
    attempts: int = 0
    let_go: list[str] = field(default_factory=list)

    @property
    def gripper(self) -> str | None:
        """Name of the gripper the trial used (None when nothing was planned)."""
        return self.plan.gripper.name if self.plan is not None else None


#: The phases of a trial's joint path, in order ("back off": a rejected attempt let go, back at the park pose).
PHASES = ("approach", "descend", "close", "lift", "shake", "hold", "back off")


def _phase_state(m: mujoco.MjModel, d: mujoco.MjData, phase: str, body: int, gbody: int, fingers: set[int], fp: int,
                 g: ParallelGripper) -> dict[str, Any]:
    """Diagnostics at the end of a trial phase.

    Diagnostics at the end of a trial phase: ``phase``; the object's position in the gripper's
    frame ``obj_in_gripper`` (m, (3,)); its height ``obj_z`` (m); the lowest fingertip corner's height
    ``fingertip_z`` (m, world); the jaw opening ``opening`` (m); the
    summed normal force of the finger-object contacts ``grip_normal_N`` (N) and their summed
    tangential (friction) force ``grip_tangential_N`` (N); ``contacts`` (count).
    """
    R = d.xmat[gbody].reshape(3, 3)
    rel = R.T @ (d.xpos[body] - d.xpos[gbody])
    fn = ft = 0.0
    n = 0
    f6 = np.zeros(6)
    for i in range(d.ncon):
        c = d.contact[i]
        b1, b2 = m.geom_bodyid[c.geom1], m.geom_bodyid[c.geom2]
        if (b1 == body and b2 in fingers) or (b2 == body and b1 in fingers):
            mujoco.mj_contactForce(m, d, i, f6)
            fn += abs(f6[0])
            ft += float(np.hypot(f6[1], f6[2]))
            n += 1
    tips = min(float((d.geom_xpos[j] + d.geom_xmat[j].reshape(3, 3) @ (np.array([sx, sy, sz]) * m.geom_size[j]))[2])
               for j in range(m.ngeom) if m.geom_bodyid[j] in fingers
               for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1))
    return {"phase": phase, "obj_in_gripper": rel.round(4).tolist(), "obj_z": round(float(d.xpos[body][2]), 4),
            "fingertip_z": round(tips, 4),
            "opening": round(float(g.max_width - 2 * d.qpos[m.jnt_qposadr[fp]]), 4),
            "grip_normal_N": round(fn, 2), "grip_tangential_N": round(ft, 2), "contacts": n}


def _smooth(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    s = 0.5 - 0.5 * np.cos(np.linspace(0, np.pi, n))
    return a + (b - a) * s[:, None]


#: Least rise (m) of a held object over its resting height at the end of a trial (the lift is 10 cm).
LIFT_MIN = 0.05

#: Height (m) of the pre-grasp pose's grasp centre above the perceived top of the object on the way in:
#: the arm swings from :data:`Q_PARK` to that pose, then moves straight down to the pre-grasp (half the
#: height when that pose is out of reach, the pre-grasp itself when neither is reachable).
HOVER_CLEARANCE = 0.15

#: Where the arm waits while the cameras look (joint angles, rad): turned 90 deg away from the table
#: and folded up, out of the cameras' view of the workspace.
Q_PARK = np.radians([90.0, -20.0, 10.0, 0.0, -60.0, 0.0])


#: The object is at rest when its linear speed stays below :data:`REST_SPEED` (m/s) and its angular speed
#: below :data:`REST_SPIN` (rad/s) for :data:`REST_HOLD` (s); the cameras look then, at the latest after
#: :data:`SETTLE_MAX` (s).
REST_SPEED, REST_SPIN, REST_HOLD, SETTLE_MAX = 0.002, 0.05, 0.1, 5.0


def settle_until_at_rest(m: mujoco.MjModel, d: mujoco.MjData, body: int, least: float,
                         most: float = SETTLE_MAX) -> float:
    """Step the scene until the object ``body`` has come to rest; return the simulated time (s).

    The cameras of a trial look at a resting object: a toy arm set on its base falls over and is
    still tipping 0.3 s after it was placed (1-2 s to rest), and a plan from a cloud of the falling
    arm puts the jaws where it no longer is.

    Args:
        m: The scene's model.
        d: Its data (stepped in place).
        body: The object's body id.
        least: Least simulated time to step (s).
        most: Most simulated time to step (s).

    Returns:
        The simulated time stepped (s): at least ``least``; then until the object's speeds
        (``d.cvel``: angular, linear) stayed below :data:`REST_SPIN` (rad/s) and :data:`REST_SPEED` (m/s)
        for :data:`REST_HOLD` s, or ``most`` s have passed.
    """
    dt = m.opt.timestep
    still, t = 0, 0.0
    while t < most:
        mujoco.mj_step(m, d)
        t += dt
        w, v = d.cvel[body][:3], d.cvel[body][3:]
        still = still + 1 if np.linalg.norm(v) < REST_SPEED and np.linalg.norm(w) < REST_SPIN else 0
        if t >= least and still * dt >= REST_HOLD:
            break
    return t


#: Attempts of a trial by default: a grasp the hand's checks (:mod:`.hand`) find empty, partial or slipping
#: is let go and planned again from a new look, up to this many times in all.
ATTEMPTS = 3


def grasp_trial(obj: ObjectModel, placement: Placement, planner: GraspPlanner, *,
                rng: np.random.Generator | int | None = None, cameras: list[DepthCamera] | None = None,
                shake_amplitude: float = 0.15, settle: float = 0.3, arm: bool = True,
                attempts: int = ATTEMPTS, plan: GraspPlan | None = None) -> GraspTrialResult:
    """Run one lift-and-shake trial (Table 6.2) in MuJoCo, the loop closed at the hand.

    Place ``obj`` (free body), perceive, plan, approach, close, lift 10 cm, shake; success if the
    object is still held: raised by more than :data:`LIFT_MIN` over its height before the jaws closed,
    touching a finger, and within 3 cm of where it sat in the gripper after the lift.

    ``arm=True`` (default): the whole LR Mate is in the MuJoCo scene (:func:`scene.arm_scene`): its
    joint servos track the planned joint path (park -> the pre-grasp pose raised to
    :data:`HOVER_CLEARANCE` above the perceived top of the object -> down to the pre-grasp 8 cm back
    along the approach -> grasp -> close -> lift 10 cm -> shake with J1 and J6), its links collide
    with the table and the object, and the held object loads its joints. ``arm=False``: the gripper
    alone follows the forward kinematics of the path from the pre-grasp on (a mocap weld), no arm
    links, one attempt. The gripper on the flange is the one the plan chose (:class:`GraspPlanner`: the
    48 mm one, or the 85 mm one for wide parts), driven with its own ``grip_force``.

    The hand's checks (:mod:`robointel.learning.grasp.hand`) decide whether to go on: at the
    pre-grasp, the perceived part must lie between the jaws at the grasp pose the measured arm pose
    leads to; after closing, the jaw opening and the pads' forces must show a grip (not an empty or a
    partial one); after the lift, they must not have changed (a slip). A failed check lets go, backs
    out to the park pose, waits for the part to come to rest, looks again and plans again with the
    same gripper, avoiding the grasps that failed (:meth:`GraspPlanner.plan`'s ``avoid``), up to
    ``attempts`` attempts (the last one goes on to the lift and the shake whatever its checks say); the
    shake is never retried.

    Args:
        obj: The object (a free body in the scene).
        placement: Where it rests on the table.
        planner: The grasp planner (its robot at the world origin with ``arm=True``).
        rng: Seed or generator of the sensor noise.
        cameras: The depth cameras (default :func:`default_cameras`).
        shake_amplitude: Amplitude of the J6 shake (rad; J1 shakes by 0.06 rad), both at 2 Hz for 1.5 s.
        settle: Least time the object settles before the cameras look (s); they look once it is at
            rest (its speeds below :data:`REST_SPEED` and :data:`REST_SPIN` for :data:`REST_HOLD`), at the
            latest after :data:`SETTLE_MAX`.
        arm: Simulate the whole arm (else the gripper alone, one attempt).
        attempts: Most grasp attempts (>= 1; :data:`ATTEMPTS`).
        plan: The first attempt's plan, made beforehand (None: planned on the trial's first look); its
            gripper goes on the flange.

    Returns:
        The trial's result (``success``, ``reason``, the plan, the state at the end of each phase, the
        attempts made and why each earlier one was let go).

    Raises:
        InvalidInput: the planner has no robot, (``arm``) its base is not at the world origin, or
            ``attempts`` < 1.
    """
    if int(attempts) < 1:
        raise InvalidInput(f"grasp_trial: attempts must be >= 1, got {attempts}", value=attempts)
    rng = np.random.default_rng(rng)
    cams = cameras or default_cameras()
    Tb = planner.base_pose
    # the scene is built before the plan (the cameras look at it); the plan may choose the wide gripper
    # (then the scene is rebuilt with it, the object and the noise draws as they were)
    return _trial(obj, placement, planner, plan.gripper if plan is not None else planner.gripper, rng, cams,
                  shake_amplitude, settle, arm, Tb, dict(rng.bit_generator.state), int(attempts) if arm else 1, plan)


class _Cell:
    """The trial's MuJoCo scene, the arm (or the gripper alone) following joint paths, and its log."""

    def __init__(self, placement: Placement, robot: Robot, g: ParallelGripper, arm: bool, Tb: np.ndarray) -> None:
        self.robot, self.g, self.arm, self.Tb = robot, g, arm, Tb
        if arm:
            m = arm_scene([placement], robot, g)
            self.jadr = np.array([m.jnt_qposadr[m.joint("arm/" + n).id] for n in robot.joint_names])
        else:
            m = mujoco.MjModel.from_xml_string(scene_xml([placement], dynamic=True, gripper=g))
        pre = "arm/" if arm else ""
        self.m, self.d = m, mujoco.MjData(m)
        self.gbody = m.body(pre + "gripper").id
        self.fp = m.joint(pre + "fp").id
        self.finger_ids = (m.body(pre + "fp").id, m.body(pre + "fn").id)
        self.body = m.body("obj0").id
        self.log: list[dict[str, Any]] = []
        self.q = Q_PARK.copy()
        self.ctrl = 0.0
        self.d.ctrl[:] = 0.0
        if arm:
            self.d.qpos[self.jadr] = Q_PARK
            self.d.ctrl[:6] = Q_PARK
        else:
            self.d.mocap_pos[0] = np.array([0.5, 0.0, 1.6])
        mujoco.mj_forward(self.m, self.d)

    def place_gripper(self, q: np.ndarray) -> None:
        """(``arm=False``) put the free gripper at the forward kinematics of ``q``, at rest."""
        m, d = self.m, self.d
        gadr = m.jnt_qposadr[m.joint("gripper").id]
        T0 = self.Tb @ self.robot.fk(q)
        q0 = np.empty(4)
        mujoco.mju_mat2Quat(q0, T0[:3, :3].ravel())
        d.qpos[gadr:gadr + 3] = T0[:3, 3]
        d.qpos[gadr + 3:gadr + 7] = q0
        d.qvel[m.jnt_dofadr[m.joint("gripper").id]:][:6] = 0.0

    def follow(self, qs: np.ndarray, ctrl: float, phase: str | None, attempt: int) -> None:
        """Track the joint path ``qs`` (one row per step) with the finger command ``ctrl``; log ``phase``."""
        m, d = self.m, self.d
        dt = m.opt.timestep
        kv_over_kp = np.asarray(ARM_KV) / np.asarray(ARM_KP)
        qd = np.gradient(qs, dt, axis=0) if len(qs) > 1 else np.zeros_like(qs)
        for q, v in zip(qs, qd):
            if self.arm:
                # servo torque kp (ctrl - q) - kv qdot = kp (q_ref - q) + kv (qdot_ref - qdot)
                d.ctrl[:6] = q + kv_over_kp * v
            else:
                T = self.Tb @ self.robot.fk(q)
                d.mocap_pos[0] = T[:3, 3]
                qw = np.empty(4)
                mujoco.mju_mat2Quat(qw, T[:3, :3].ravel())
                d.mocap_quat[0] = qw
            d.ctrl[-2:] = ctrl
            mujoco.mj_step(m, d)
        self.q, self.ctrl = np.asarray(qs[-1], float).copy(), ctrl
        if phase is not None:
            st = _phase_state(m, d, phase, self.body, self.gbody, set(self.finger_ids), self.fp, self.g)
            st["attempt"] = attempt
            self.log.append(st)

    def move(self, q: np.ndarray, seconds: float, ctrl: float, phase: str | None, attempt: int) -> None:
        """Move smoothly from where the arm was sent last to ``q`` in ``seconds`` (s)."""
        self.follow(_smooth(self.q, np.asarray(q, float), max(2, int(seconds / self.m.opt.timestep))), ctrl, phase,
                    attempt)

    def hand(self) -> HandReading:
        """The gripper's sensors now."""
        return read_hand(self.m, self.d, self.finger_ids, self.fp, self.g)

    def measured_grasp(self, ahead: float) -> Grasp:
        """The grasp frame ``ahead`` m along the approach from where the measured joint angles put it."""
        q = self.d.qpos[self.jadr] if self.arm else self.q
        T = self.Tb @ self.robot.fk(np.asarray(q, float))
        return Grasp(T[:3, 3] + ahead * T[:3, 2], T[:3, :3])

    def back_off(self, q_hover: np.ndarray, attempt: int) -> None:
        """Let go, rise to ``q_hover`` and return to the park pose, out of the cameras' view."""
        self.move(self.q, 0.3, 0.0, None, attempt)
        self.move(q_hover, 0.8, 0.0, None, attempt)
        self.move(Q_PARK, 1.5, 0.0, "back off", attempt)


def _plan_path(robot: Robot, Tb: np.ndarray, plan: GraspPlan, cloud: np.ndarray) -> tuple[np.ndarray, ...] | None:
    """Joint angles (hover, pre-grasp, grasp, lifted) of a plan's grasp; None when one is out of reach."""
    res = plan.search
    G = res.grasp.pose
    pre = G.copy()
    pre[:3, 3] -= PRE_GRASP * res.grasp.approach
    up = G.copy()
    up[2, 3] += 0.10
    Tbi = np.linalg.inv(Tb)
    try:
        q_grasp = np.asarray(res.q, float)
        q_pre = robot.ik(Tbi @ pre, q_ref=q_grasp)[0]
        q_up = robot.ik(Tbi @ up, q_ref=q_grasp)[0]
    except IKFailure:
        return None
    q_hover = q_pre  # when no raised pose is reachable, the swing ends at the pre-grasp itself
    for clearance in (HOVER_CLEARANCE, HOVER_CLEARANCE / 2):
        hover = pre.copy()
        hover[2, 3] = max(pre[2, 3], float(cloud[:, 2].max()) + clearance)
        try:
            q_hover = robot.ik(Tbi @ hover, q_ref=q_pre)[0]
            break
        except IKFailure:
            continue
    return q_hover, q_pre, q_grasp, q_up


def _trial(obj: ObjectModel, placement: Placement, planner: GraspPlanner, g: ParallelGripper, rng: np.random.Generator,
           cams: list[DepthCamera], shake_amplitude: float, settle: float, arm: bool, Tb: np.ndarray,
           rng_state: dict[str, Any], attempts: int, plan: GraspPlan | None = None) -> GraspTrialResult:
    robot = planner.robot_for(g)
    if robot is None:
        raise InvalidInput("grasp_trial needs a planner with a robot (robot='lrmate')", value=None)
    if arm and not np.allclose(Tb, np.eye(4)):
        raise InvalidInput("grasp_trial(arm=True) needs the planner's robot at the world origin", value=Tb)
    cell = _Cell(placement, robot, g, arm, Tb)
    m, d, body = cell.m, cell.d, cell.body
    # background: the same scene with the object moved far away (the empty workspace)
    qadr = m.jnt_qposadr[m.joint("obj0").id]
    saved = d.qpos[qadr:qadr + 7].copy()
    d.qpos[qadr:qadr + 3] = [5.0, 5.0, -5.0]
    mujoco.mj_forward(m, d)
    bgs = [depth_image(m, d, c, rng) for c in cams]
    d.qpos[qadr:qadr + 7] = saved
    mujoco.mj_forward(m, d)
    settled_s = settle_until_at_rest(m, d, body, settle)
    clouds = perceive(m, d, cams, bgs, rng=rng)
    if not clouds:
        return GraspTrialResult(False, "nothing perceived", settle_s=settled_s)
    cloud = clouds[0]
    if len(cloud) < 20:
        return GraspTrialResult(False, "cloud too small", cloud=cloud, settle_s=settled_s)
    if plan is None:
        plan = planner.plan(cloud, exclude=(obj.name,))
        if plan.gripper != g:  # the same placement and draws, the chosen gripper on the flange
            rng.bit_generator.state = rng_state
            return _trial(obj, placement, planner, plan.gripper, rng, cams, shake_amplitude, settle, arm, Tb,
                          rng_state, attempts, plan)
    failed: list[Grasp] = []
    let_go: list[str] = []
    first: GraspPlan = plan
    dt = m.opt.timestep
    shut = close_command(g)  # finger travel command 0 = open; closed: squeeze with the grip force at any width

    def result(success: bool, reason: str, **kw: Any) -> GraspTrialResult:
        return GraspTrialResult(success, reason, first.classification.category, plan, cloud=cloud, log=cell.log,
                                settle_s=settled_s, attempts=attempt, let_go=let_go, **kw)

    attempt = 0
    while attempt < attempts:
        attempt += 1
        if attempt > 1:  # look again from the park pose, with the part at rest, and plan again
            settle_until_at_rest(m, d, body, 0.3)
            clouds = perceive(m, d, cams, bgs, rng=rng)
            if not clouds or len(clouds[0]) < 20:
                return result(False, f"nothing perceived after attempt {attempt - 1} ({let_go[-1]})")
            cloud = clouds[0]
            plan = planner.plan(cloud, exclude=(obj.name,), gripper=g, avoid=failed)
        res = plan.search
        if not res.feasible or res.q is None:
            why = res.detail.reason if res.detail else "-"
            return result(False, f"no feasible grasp ({why})")
        qs = _plan_path(robot, Tb, plan, cloud)
        if qs is None:
            return result(False, "approach or lift unreachable")
        q_hover, q_pre, q_grasp, q_up = qs
        if arm:
            cell.move(q_hover, 1.5, 0.0, None, attempt)
            cell.move(q_pre, 0.5, 0.0, "approach", attempt)
        else:
            cell.place_gripper(q_pre)
            cell.follow(_smooth(q_pre, q_pre, int(0.1 / dt)), 0.0, "approach", attempt)
        # before closing: the perceived part between the jaws where the measured arm pose leads them
        # (measured once the arm has settled at the pre-grasp). A failed check lets go and tries again
        # while attempts are left; the last attempt goes on whatever its checks say.
        last = attempt == attempts
        cell.move(q_pre, 0.2, 0.0, None, attempt)
        at = cell.measured_grasp(PRE_GRASP)
        v = between_jaws(at, cloud, g)
        if not v.ok:
            off = float(np.linalg.norm(at.centre - res.grasp.centre))
            v = HandVerdict(False, v.state, f"{v.detail}; the arm {off * 1e3:.1f} mm off the planned grasp")
        if v.ok or last:
            if not v.ok:
                let_go.append(f"attempt {attempt}: {v.state} ({v.detail}), the last: closed anyway")
            cell.move(q_grasp, 0.8, 0.0, "descend", attempt)
            z_rest = float(d.xpos[body][2])  # the object's height before the jaws close
            cell.move(q_grasp, 0.6, shut, "close", attempt)
            closed = cell.hand()
            v = after_close(closed, res.detail.width if res.detail is not None else float("nan"), g)
            if v.ok or last:
                cell.move(q_up, 1.0, shut, "lift", attempt)
                rel_after_lift = (d.xpos[body] - d.xpos[cell.gbody]).copy()
                h_lift = float(d.xpos[body][2])
                if v.ok:
                    v = after_lift(closed, cell.hand(), g)
        if not v.ok and not last:
            failed.append(res.grasp)
            let_go.append(f"attempt {attempt}: {v.state} ({v.detail})")
            cell.back_off(q_hover, attempt)
            continue
        break
    n_sh = int(1.5 / dt)
    tt = np.arange(n_sh) * dt
    shake = np.tile(q_up, (n_sh, 1))
    shake[:, 0] += 0.06 * np.sin(2 * np.pi * 2.0 * tt)
    shake[:, 5] += shake_amplitude * np.sin(2 * np.pi * 2.0 * tt)
    cell.follow(shake, shut, "shake", attempt)
    cell.move(q_up, 0.4, shut, "hold", attempt)
    rel = d.xpos[body] - d.xpos[cell.gbody]
    h = float(d.xpos[body][2])
    moved = float(np.linalg.norm(rel - rel_after_lift))
    grip = closed.opening
    # held: raised by at least LIFT_MIN above where it rested, still in the jaws (touching a finger,
    # where it sat after the lift); an object's frame can rest above 5 cm (a toy arm lying on its side)
    held = h - z_rest > LIFT_MIN and moved < 0.03 and cell.log[-1]["contacts"] > 0
    if held:
        reason = "held"
    elif grip < EMPTY_OPENING:
        reason = "dropped: fingers closed on nothing"
    elif h_lift - z_rest < LIFT_MIN:
        reason = f"dropped: slipped during lift (height {h_lift:.3f} m, grip {grip:.3f} m)"
    else:
        reason = f"dropped: slipped during shake (moved {moved:.3f} m in hand, grip {grip:.3f} m)"
    return result(bool(held), reason, final_height=h)
