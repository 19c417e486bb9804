"""The program cell with objects on the table.

The whole LR Mate in MuJoCo with the parallel gripper on its flange, the program's fixtures, generated
objects on the table and two depth cameras (Ch. 6's grasp scene).

``grasp`` perceives the table, classifies each cluster against one taught template per category,
transfers the template's taught grasp by CPD and searches its orientation (the Ch. 6 pipeline,
:class:`robointel.learning.grasp.GraspPlanner`), then approaches on a planned motion, descends, closes,
lifts 15 cm and verifies the object is held. ``place`` carries the held object on a planned motion to
above the target, sets it down, opens and retreats, and verifies where it came to rest.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import mujoco
import numpy as np

from robointel.errors import IKFailure, InvalidInput
from robointel.geometry.obstacles import Obstacle
from robointel.geometry.table import ENVIRONMENT_NAMES
from robointel.learning.grasp import (
    GraspPlanner,
    ParallelGripper,
    Placement,
    Template,
    default_cameras,
    depth_image,
    perceive,
    primitive_object,
    random_placements,
    sample_points,
    taught_grasps,
    ycb_object,
)
from robointel.learning.grasp.pipeline import lrmate_with_gripper
from robointel.learning.grasp.scene import ARM_KP, ARM_KV, arm_scene, close_command
from robointel.learning.grasp.trial import Q_PARK
from robointel.outcome import Failure, TrialOutcome
from robointel.program.format import OBJECT_CATEGORIES, Program
from robointel.program.guide_step import GuideResult, PushOperator, guide_with_hand
from robointel.program.motion import CellPlanner, gripper_geometry, held_box
from robointel.trajectory import Trajectory

Planner = Callable[[np.ndarray, np.ndarray], "Trajectory | None"]
TEMPLATE_SEED = 900  # generated template instances: seeds never used for the objects placed in examples
LIFT_M = 0.15
MAX_LIFT_M = 0.35  # highest the part is raised (straight up) to start the carry clear of the fixtures
TRACKING_LIMIT_RAD = 0.08
CARRY_SPEED = 0.3  # fraction of the velocity limits (its square of the accelerations) while holding an object
SLIP_M = 0.02  # the object moved this far in the hand while lifted: the grasp is not firm (regrasp)
CARRY_SLIP_M = 0.05  # ... while carried: it slips out (the arm stops)
GRASP_ATTEMPTS = 2  # grasps tried (re-perceiving between them) before the step fails


def straight(q0: np.ndarray, q1: np.ndarray, duration: float, names: list[str]) -> Trajectory:
    """A rest-to-rest joint-space straight line with a quintic (minimum-jerk) time law.

    Args:
        q0: (n,) start, rad.
        q1: (n,) goal, rad.
        duration: Motion time, s.
        names: Joint names.

    Returns:
        The trajectory sampled every 10 ms.
    """
    t = np.linspace(0.0, duration, max(3, int(duration / 0.01) + 1))
    s = t / duration
    p = 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5
    dp = (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / duration
    ddp = (60 * s - 180 * s ** 2 + 120 * s ** 3) / duration ** 2
    dq = (q1 - q0)[None]
    return Trajectory(t, q0[None] + p[:, None] * dq, dp[:, None] * dq, ddp[:, None] * dq, names)


class GraspCell:
    """A program cell with the gripper, fixtures and objects (see the module docstring).

    Args:
        program: The program (its scene's obstacles become fixtures; its objects are placed on the table).
        q0: (n,) start configuration, rad.
        seed: Seed of the random placements, the depth noise and the perception.
        gripper: The parallel gripper.

    Raises:
        InvalidInput: The program has no objects.
    """

    def __init__(self, program: Program, q0: np.ndarray, *, seed: int = 0,
                 gripper: ParallelGripper | None = None) -> None:
        if not program.objects:
            raise InvalidInput("a GraspCell needs the program to list objects on the table", value=program.name)
        self.gripper = gripper or ParallelGripper()
        self.rng = np.random.default_rng(seed)
        self.robot = lrmate_with_gripper(self.gripper)
        models = [replace(ycb_object(o.ycb, o.category), name=f"{o.category}_{i}") if o.ycb is not None
                  else primitive_object(o.category, o.seed, name=f"{o.category}_{i}")
                  for i, o in enumerate(program.objects)]
        free = [m for m, o in zip(models, program.objects) if o.at is None]
        rand = iter(random_placements(free, self.rng)) if free else iter(())
        self.placements: list[Placement] = []
        for m, o in zip(models, program.objects):
            p = next(rand) if o.at is None else Placement(m, o.at[0], o.at[1], 0.0)
            if o.yaw is not None:
                p = Placement(m, p.x, p.y, o.yaw)
            self.placements.append(p)
        self.categories = [o.category for o in program.objects]
        fixtures = [o for o in program.scene.obstacles if getattr(o, "name", None) not in ENVIRONMENT_NAMES]
        self.model = arm_scene(self.placements, self.robot, self.gripper, obstacles=fixtures)  # has its own table
        m = self.model
        self.data = mujoco.MjData(m)
        self.names = list(self.robot.joint_names)
        self._jadr = np.array([m.jnt_qposadr[m.joint("arm/" + n).id] for n in self.names])
        self._vadr = np.array([m.jnt_dofadr[m.joint("arm/" + n).id] for n in self.names])
        self._gripper = m.body("arm/gripper").id
        self._fp = m.jnt_qposadr[m.joint("arm/fp").id]
        self._obj = [m.body(f"obj{i}").id for i in range(len(self.placements))]
        self._objq = [m.jnt_qposadr[m.joint(f"obj{i}").id] for i in range(len(self.placements))]
        self._kv_kp = np.asarray(ARM_KV) / np.asarray(ARM_KP)
        self._arm = {b for b in range(m.nbody) if m.body(b).name.startswith("arm/") and m.body_parentid[b] != 0}
        self._env_geoms = {g for g in range(m.ngeom) if m.geom(g).name.startswith("obstacle/")
                           or m.geom(g).name == "table"}
        self._obst_geoms = {g for g in range(m.ngeom) if m.geom(g).name.startswith("obstacle/")}
        self.observe_q = np.asarray(Q_PARK, float).copy()
        self.io: dict[str, float] = {}
        self.trace: list[np.ndarray] = []  # measured joints of every motion since the last pop_trace
        self.held: int | None = None
        self._grip_in_hand: np.ndarray | None = None
        self._held_box: Obstacle | None = None
        self._flange = m.body("arm/tool").id
        self.motion = CellPlanner(program.scene, seed=seed)
        self.seed = int(seed)
        self.operator: PushOperator | None = None  # the scripted operator of guide steps
        self.stations: dict[str, object] = {}  # insert/grind stations (default: the skills' own cells)
        self.tool = gripper_geometry(self.gripper)
        self.stopped: str | None = None
        d = self.data
        d.qpos[self._jadr] = q0
        self._ctrl = np.asarray(q0, float).copy()
        d.ctrl[:6] = self._ctrl
        d.ctrl[-2:] = 0.0
        mujoco.mj_forward(m, d)
        self.cameras = default_cameras()
        # the empty table seen with the arm at its observation pose (out of the cameras' view)
        d.qpos[self._jadr] = self.observe_q
        saved = [d.qpos[a:a + 7].copy() for a in self._objq]
        for k, a in enumerate(self._objq):
            d.qpos[a:a + 3] = [5.0 + k, 5.0, -5.0]
        mujoco.mj_forward(m, d)
        self._backgrounds = [depth_image(m, d, c, self.rng) for c in self.cameras]
        for a, s in zip(self._objq, saved):
            d.qpos[a:a + 7] = s
        d.qpos[self._jadr] = q0
        mujoco.mj_forward(m, d)
        self._step_for(0.3)
        self.rest_z = [float(d.xpos[b][2]) for b in self._obj]
        templates = [Template(f"{c}_template", c, sample_points(o, 800, 0), taught_grasps(o))
                     for c, o in ((c, primitive_object(c, TEMPLATE_SEED + k)) for k, c in enumerate(OBJECT_CATEGORIES))]
        self.planner = GraspPlanner(templates, gripper=self.gripper, wide_gripper=None)  # the mounted gripper only

    # ------------------------------------------------------------------ the Cell protocol
    @property
    def q(self) -> np.ndarray:
        """(n,) measured joint configuration, rad."""
        return np.asarray(self.data.qpos[self._jadr], float).copy()

    def object_position(self, i: int) -> np.ndarray:
        """(3,) world position of object ``i``'s frame, m."""
        return np.asarray(self.data.xpos[self._obj[i]], float).copy()

    def _step_for(self, seconds: float) -> None:
        for _ in range(max(1, int(round(seconds / self.model.opt.timestep)))):
            mujoco.mj_step(self.model, self.data)

    def _collision(self) -> str | None:
        d, m = self.data, self.model
        for c in d.contact[:d.ncon]:
            b1, b2 = m.geom_bodyid[c.geom1], m.geom_bodyid[c.geom2]
            for g, b in ((c.geom1, b2), (c.geom2, b1)):
                if g in self._env_geoms and b in self._arm:
                    return f"{m.body(b).name} touched {m.geom(g).name}"
                if g in self._obst_geoms and self.held is not None and b == self._obj[self.held]:
                    return f"the held object touched {m.geom(g).name}"
        return None

    def execute(self, trajectory: Trajectory) -> tuple[TrialOutcome, np.ndarray]:
        """Track ``trajectory`` with the joint servos.

        It stops at a contact of the arm or the held object with a fixture or the table.

        Returns:
            The outcome (COLLISION, TRACKING or success) and the measured joints (M, n).
        """
        dt = self.model.opt.timestep
        dense = trajectory.resample(dt)
        d = self.data
        Q = np.empty((len(dense.t), len(self.names)))
        err = 0.0
        for k, (q, v) in enumerate(zip(dense.q, dense.qd)):
            d.ctrl[:6] = q + self._kv_kp * v
            self._ctrl = q.copy()
            mujoco.mj_step(self.model, d)
            Q[k] = d.qpos[self._jadr]
            err = max(err, float(np.max(np.abs(Q[k] - q))))
            hit = self._collision() if d.ncon else None
            if hit is None and self.held is not None and k % 10 == 0:
                slip = self._slip()
                if slip is not None:
                    self.trace.append(Q[:k + 1])
                    self.stop("slip")
                    return TrialOutcome(False, Failure.SLIP, slip, {"tracking_max_rad": err}), Q[:k + 1]
            if hit:
                self.trace.append(Q[:k + 1])
                self.retreat(dense.q[max(0, k - int(0.15 / dt))])
                return TrialOutcome(False, Failure.COLLISION, hit, {"tracking_max_rad": err}), Q[:k + 1]
        self.trace.append(Q[:k + 1])
        if err > TRACKING_LIMIT_RAD:
            self.stop("tracking")
            return TrialOutcome(False, Failure.TRACKING, f"tracking error {err:.3f} rad", {"tracking_max_rad": err}), Q
        return TrialOutcome(True, figures={"tracking_max_rad": err}), Q

    def _slip(self) -> str | None:
        """Why the held object no longer sits where it was grasped in the hand (None while it does)."""
        assert self.held is not None and self._grip_in_hand is not None
        in_hand = np.linalg.inv(self._pose(self._gripper)) @ self._pose(self._obj[self.held])
        moved = float(np.linalg.norm(in_hand[:3, 3] - self._grip_in_hand[:3, 3]))
        if moved > CARRY_SLIP_M:
            return f"the held object slipped {moved * 100:.1f} cm in the hand"
        return None

    def pop_trace(self) -> np.ndarray:
        """Return the measured joints (M, n) of the motions since the last call, on a 1 ms grid, and clear them."""
        if not self.trace:
            return np.zeros((0, len(self.names)))
        Q = np.vstack(self.trace)
        self.trace = []
        return np.repeat(Q, max(1, int(round(self.model.opt.timestep / 1e-3))), axis=0)

    def hold(self, seconds: float) -> None:
        """Keep the last command for ``seconds``."""
        if seconds > 0:
            self._step_for(seconds)

    def stop(self, reason: str) -> None:
        """Hold where the robot is now."""
        self.stopped = reason
        self._ctrl = self.q
        self.data.ctrl[:6] = self._ctrl
        self._step_for(0.05)

    def retreat(self, q_safe: np.ndarray) -> None:
        """Back off to ``q_safe`` (a contact-free configuration already passed) and hold there."""
        self.stopped = "contact"
        self._ctrl = np.asarray(q_safe, float).copy()
        self.data.ctrl[:6] = self._ctrl
        self._step_for(0.3)

    def set_io(self, name: str, value: float) -> None:
        """Set an output; ``gripper`` 1 closes the fingers, 0 opens them.

        Closed, the fingers squeeze with the gripper's grip force at any width
        (:func:`~robointel.learning.grasp.scene.close_command`), as in the grasp trials.
        """
        self.io[name] = float(value)
        if name == "gripper":
            self.data.ctrl[-2:] = close_command(self.gripper) if value >= 0.5 else 0.0
            self._step_for(0.5)

    # ------------------------------------------------------------------ grasp and place
    def _run(self, traj: Trajectory | None) -> TrialOutcome:
        if traj is None:
            return TrialOutcome(True)
        return self.execute(traj)[0]

    def grasp(self, category: str, plan: Planner) -> TrialOutcome:
        """Perceive, find a cluster of ``category``, plan a grasp, approach, close, lift and verify.

        A grasp that does not lift the object, or lets it move in the hand while lifting, is released and
        retried from a new perception (``GRASP_ATTEMPTS`` in all). Before the carry the object is raised
        straight up (up to ``MAX_LIFT_M``) until the arm, gripper and object keep ``d_min`` from the fixtures.

        Args:
            category: The object category to pick.
            plan: The program's motion planner (start, goal) -> trajectory around the fixtures.

        Returns:
            The outcome: success when an object rose with the gripper and sits still in it; else NO_GRASP
            (nothing of the category perceived or no feasible grasp), IK, COLLISION or SLIP.
        """
        if self.held is not None:
            return TrialOutcome(False, Failure.ERROR, "the gripper already holds an object")
        out = TrialOutcome(False, Failure.NO_GRASP, "no attempt")
        for _ in range(GRASP_ATTEMPTS):
            out = self._grasp_once(category, plan)
            if out.success or out.reason is not Failure.SLIP:
                break
            self.set_io("gripper", 0)  # let go of what was not held and back off straight up
            self.held = None
            T = self.robot.fk(self.q)
            T[2, 3] += 0.08
            sols = self.robot.ik(T, q_ref=self.q)
            if len(sols):
                back = self._run(straight(self.q, np.asarray(sols[0], float), 0.8, self.names))
                if not back.success:
                    return back
        if not out.success:
            return out
        return self._clear_for_carry(out)

    def _grasp_once(self, category: str, plan: Planner) -> TrialOutcome:
        if float(np.max(np.abs(self.q - self.observe_q))) > 0.02:  # look from where the arm hides nothing
            out = self._run(plan(self.q, self.observe_q))
            if not out.success:
                return out
        clouds = [c for c in perceive(self.model, self.data, self.cameras, self._backgrounds, rng=self.rng)
                  if len(c) >= 50]
        chosen = None
        for cloud in clouds:
            gp = self.planner.plan(cloud)
            if gp.classification.category == category:
                chosen = gp
                break
        if chosen is None:
            return TrialOutcome(False, Failure.NO_GRASP, f"no cluster classified as {category!r} among "
                                f"{len(clouds)} perceived")
        res = chosen.search
        if not res.feasible or res.q is None:
            return TrialOutcome(False, Failure.NO_GRASP, f"no feasible grasp on the {category}")
        G = res.grasp.pose
        pre, up = G.copy(), G.copy()
        pre[:3, 3] -= 0.08 * res.grasp.approach
        up[2, 3] += LIFT_M
        try:
            q_grasp = np.asarray(res.q, float)
            q_pre = self.robot.ik(pre, q_ref=q_grasp)[0]
            q_up = self.robot.ik(up, q_ref=q_grasp)[0]
        except (IKFailure, IndexError):
            return TrialOutcome(False, Failure.IK, "approach or lift pose unreachable")
        self.set_io("gripper", 0)
        out = self._run(plan(self.q, q_pre))
        if not out.success:
            return out
        self._env_geoms.discard(self.model.geom("table").id)  # the fingers may touch the table near the part
        try:
            out = self._run(straight(self.q, q_grasp, 0.8, self.names))
            if not out.success:
                return out
            self.set_io("gripper", 1)
            z0 = [float(self.data.xpos[b][2]) for b in self._obj]
            in_hand0 = [np.linalg.inv(self._pose(self._gripper)) @ self._pose(b) for b in self._obj]
            out = self._run(straight(self.q, q_up, 1.0, self.names))
        finally:
            self._env_geoms.add(self.model.geom("table").id)
        if not out.success:
            return out
        self._step_for(0.2)  # let a loose grasp show itself before it is carried
        gpos = self.data.xpos[self._gripper]
        rose = [i for i, b in enumerate(self._obj) if self.data.xpos[b][2] - z0[i] > 0.5 * LIFT_M
                and np.linalg.norm(self.data.xpos[b] - gpos) < 0.15]
        if not rose:
            return TrialOutcome(False, Failure.SLIP, f"the {category} did not rise with the gripper")
        i = rose[0]
        in_hand = np.linalg.inv(self._pose(self._gripper)) @ self._pose(self._obj[i])
        moved = float(np.linalg.norm(in_hand[:3, 3] - in_hand0[i][:3, 3]))
        if moved > SLIP_M:
            return TrialOutcome(False, Failure.SLIP, f"the {category} moved {moved * 100:.1f} cm in the hand while "
                                "lifted")
        self.held = i
        self._grip_in_hand = in_hand
        self._held_box = held_box(self._pose(self._flange), self._pose(self._obj[i]),
                                  self.placements[i].obj.mesh.bounds)
        return TrialOutcome(True, detail=f"holding object {i} ({self.categories[i]})",
                            figures={"grasp_width_m": self.gripper.max_width - 2 * float(self.data.qpos[self._fp])})

    def _clear_for_carry(self, out: TrialOutcome) -> TrialOutcome:
        """Raise the held object straight up until the carry can start ``d_min`` clear of the fixtures."""
        d_min = self.motion.scene.d_min
        q = self.q
        if self.motion.clearance(q, self.attached(), self_collision=False) >= d_min:
            return out
        T = self.robot.fk(q)
        for dz in np.arange(0.05, MAX_LIFT_M - LIFT_M + 1e-9, 0.05):
            Tz = T.copy()
            Tz[2, 3] += dz
            sols = self.robot.ik(Tz, q_ref=q)
            if not len(sols):
                break
            q_hi = np.asarray(sols[0], float)
            if self.motion.clearance(q_hi, self.attached(), self_collision=False) >= d_min:
                moved = self._run(straight(self.q, q_hi, 0.5 + 4 * dz, self.names))
                return moved if not moved.success else TrialOutcome(True, detail=out.detail, figures={
                    **out.figures, "extra_lift_m": float(dz)})
        return TrialOutcome(False, Failure.INFEASIBLE, f"the held object cannot be raised {d_min * 1000:.0f} mm clear "
                            "of the fixtures to start the carry")

    def guide(self, timeout: float) -> GuideResult:
        """Lead-through until the operator presses continue (``guide`` step): the hand pushes the gripper.

        The operator is :attr:`operator` (default: a :class:`PushOperator`, 20 N along +y for 0.5 s); its
        force acts on the gripper body in MuJoCo and is the (ideal) F/T reading the guidance controller gets.
        """
        op = self.operator or PushOperator()
        period = op.period
        obstacles = [o for o in self.motion.scene.obstacles if getattr(o, "name", None) != "floor"]
        frc = self.data.xfrc_applied

        def step(q_cmd: np.ndarray, f: np.ndarray) -> str | None:
            frc[self._gripper, :3] = f
            self._ctrl = q_cmd.copy()
            self.data.ctrl[:6] = q_cmd
            for _ in range(max(1, int(round(period / self.model.opt.timestep)))):
                mujoco.mj_step(self.model, self.data)
                hit = self._collision() if self.data.ncon else None
                if hit:
                    return hit
            return None

        try:
            return guide_with_hand(self.robot, op, timeout=timeout, period=period, read_q=lambda: self.q, step=step,
                                   obstacles=obstacles)
        finally:
            frc[self._gripper, :3] = 0.0

    def attached(self) -> list[Obstacle]:
        """The gripper and the held object (its bounding box) in the flange frame, for planning."""
        return self.tool + ([self._held_box] if self.held is not None and self._held_box is not None else [])

    def plan_move(self, q0: np.ndarray, q1: np.ndarray) -> Trajectory | None:
        """Plan a move of the arm with its gripper and held object around the fixtures (:class:`CellPlanner`).

        Carrying an object, it moves at ``CARRY_SPEED`` of the velocity limits.

        Raises:
            CollisionAtStart: The start or the goal is closer than ``d_min``.
            InfeasibleProblem: No checked motion was found.
        """
        return self.motion.plan(q0, q1, self.attached(), speed=CARRY_SPEED if self.held is not None else 1.0)

    def _pose(self, body: int) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = self.data.xmat[body].reshape(3, 3)
        T[:3, 3] = self.data.xpos[body]
        return T

    def place(self, at: tuple[float, float], plan: Planner) -> TrialOutcome:
        """Carry the held object to above ``at``, set it down, open, retreat and verify where it rests.

        Args:
            at: (x, y) target of the object's frame on the table, m.
            plan: The program's motion planner.

        Returns:
            The outcome: success when the object rests within 3 cm of ``at``; else ERROR (nothing held),
            IK, COLLISION, SLIP (dropped on the way) or MISSED.
        """
        if self.held is None or self._grip_in_hand is None:
            return TrialOutcome(False, Failure.ERROR, "place without a held object")
        i = self.held
        T_obj = self._pose(self._obj[i])
        T_des = T_obj.copy()
        T_des[:3, 3] = [at[0], at[1], self.rest_z[i] + 0.005]
        G = T_des @ np.linalg.inv(self._grip_in_hand)
        above = G.copy()
        above[2, 3] += LIFT_M
        try:
            q_above = self.robot.ik(above, q_ref=self.q)[0]
            q_down = self.robot.ik(G, q_ref=q_above)[0]
        except (IKFailure, IndexError):
            return TrialOutcome(False, Failure.IK, f"no IK solution to set the object down at {at}")
        out = self._run(plan(self.q, q_above))
        if not out.success:
            return out
        if np.linalg.norm(self.data.xpos[self._obj[i]] - self.data.xpos[self._gripper]) > 0.15:
            return TrialOutcome(False, Failure.SLIP, "the object fell from the gripper while carried")
        self._env_geoms.discard(self.model.geom("table").id)
        try:
            out = self._run(straight(self.q, q_down, 1.0, self.names))
            if not out.success:
                return out
            self.set_io("gripper", 0)
            self.held = None
            out = self._run(straight(self.q, q_above, 0.8, self.names))
        finally:
            self._env_geoms.add(self.model.geom("table").id)
        if not out.success:
            return out
        self._step_for(0.3)
        p = self.object_position(i)
        miss = float(np.hypot(p[0] - at[0], p[1] - at[1]))
        figs = {"place_error_m": miss}
        if miss > 0.03 or p[2] > self.rest_z[i] + 0.02:
            return TrialOutcome(False, Failure.MISSED, f"the object rests {miss * 100:.1f} cm from the target "
                                f"(height {p[2]:.3f} m)", figs)
        return TrialOutcome(True, figures=figs)
