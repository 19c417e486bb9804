"""The pre-run check of a task program, before the robot moves.

Every target is resolved, reachable, within limits and collision-free; every motion is planned and
checked on a dense resample.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from robointel.errors import CollisionAtStart, DataMissing, IKFailure, InfeasibleProblem, InvalidInput, RobointelError
from robointel.io.reference import data_path
from robointel.learning.grasp import ParallelGripper
from robointel.learning.grasp.objects import ObjectModel
from robointel.learning.grasp.pipeline import lrmate_with_gripper
from robointel.planning.frmp import check_trajectory, plan_scene, planner_settings
from robointel.planning.scene import Scene
from robointel.planning.waypoints import TrajectoryPlanner
from robointel.program.format import SKILL_KINDS, Program, Step, Target
from robointel.program.motion import CellPlanner, gripper_geometry
from robointel.program.placement_check import DEFAULT_HALF, DEFAULT_HEIGHT, object_model, spot_problem
from robointel.program.skill_file import load_skill, skill_kind
from robointel.robot import Robot
from robointel.teach.keypoints import blended_trajectory, joint_velocity_reference
from robointel.trajectory import Trajectory

CLEARANCE_TOLERANCE = 0.001  # m below d_min that a dense 1 ms check still accepts


class ProgramRejected(InvalidInput):
    """The pre-run check refused a program; ``.value`` holds ``{"step": index, "name": name}``."""


@dataclass
class StepPlan:
    """What the check prepared for one step.

    Attributes:
        q_start: (n,) configuration at the step's start, rad.
        q_end: (n,) configuration at its end, rad.
        trajectory: The joint trajectory it executes (None for steps that do not move).
        min_clearance_m: Smallest sphere-obstacle clearance on the 1 ms resample (m; inf if none).
        plan_ms: Planning time of this step, ms.
        deferred: The motion is planned when the step runs (it starts after a grasp or place, from a
            configuration only known then); its target was checked.
    """

    q_start: np.ndarray
    q_end: np.ndarray
    trajectory: Trajectory | None = None
    min_clearance_m: float = float("inf")
    plan_ms: float = 0.0
    deferred: bool = False


@dataclass
class ProgramCheck:
    """The result of :func:`check_program`: one :class:`StepPlan` per step, in order.

    Attributes:
        plans: The step plans.
        check_ms: Wall time of the whole check, ms.
        scene_key: Fingerprint of the obstacles the plans were checked against.
    """

    plans: list[StepPlan] = field(default_factory=list)
    check_ms: float = 0.0
    scene_key: str = ""


def scene_key(scene: Scene) -> str:
    """A fingerprint of the scene's obstacles (a changed scene has another key)."""
    return repr([o.to_dict() for o in scene.obstacles])


def _reject(step: Step, i: int, why: str) -> ProgramRejected:
    return ProgramRejected(f"step {i} ({step.name!r}, {step.kind}): {why}", value={"step": i, "name": step.name})


class _Planners:
    """One CFS planner per step count, reused across moves (warm OSQP/DAQP workspaces)."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.settings = planner_settings(scene)
        self._cache: dict[tuple[int, float], TrajectoryPlanner] = {}

    def checker(self) -> TrajectoryPlanner:
        return self.get(2, 0.1)

    def get(self, n_steps: int, dt: float) -> TrajectoryPlanner:
        key = (n_steps, round(dt, 6))
        if key not in self._cache:
            s = self.scene
            self._cache[key] = TrajectoryPlanner(s.robot, s.obstacles, N=n_steps, dt=dt, vmax=s.vmax, amax=s.amax,
                                                 settings=self.settings)
        return self._cache[key]


def resolve_target(program: Program, target: Target, q_prev: np.ndarray) -> np.ndarray:
    """The joint configuration a move target means, starting from ``q_prev``.

    Args:
        program: The program (its waypoints and robot).
        target: The move target.
        q_prev: (n,) configuration before the move, rad; a pose target takes the IK solution closest to it.

    Returns:
        (n,) joint configuration, rad.

    Raises:
        InvalidInput: Unknown waypoint name.
        IKFailure: A pose no IK solution within the limits reaches.
    """
    robot = program.robot
    if target.waypoint is not None:
        if target.waypoint not in program.waypoints:
            raise InvalidInput(f"unknown waypoint {target.waypoint!r}; known: {sorted(program.waypoints)}",
                               value=target.waypoint)
        return np.asarray(program.waypoints[target.waypoint], float)
    if target.q is not None:
        return np.asarray(target.q, float)
    assert target.pose is not None
    if robot.has_closed_form_ik:
        sols = robot.ik(target.pose, q_ref=q_prev)
    else:
        sols = [robot.ik_numeric(target.pose, q0=q_prev)]
    if not len(sols):
        raise IKFailure("no IK solution within the joint limits reaches the pose", value=target.pose)
    return np.asarray(min(sols, key=lambda s: float(np.sum((np.asarray(s) - q_prev) ** 2))), float)


def plan_move(scene: Scene, planners: _Planners, q0: np.ndarray, q1: np.ndarray) -> Trajectory | None:
    """Plan a stop-to-stop motion from ``q0`` to ``q1`` around the scene's obstacles (CFS + temporal optimization).

    The step count follows the joint distance (10-40 steps) and the initial step the limits, so the
    user never picks an operational time; temporal optimization then makes it time-optimal.

    Args:
        scene: The program's scene (obstacles, limits, d_min).
        planners: Cached planners of the scene.
        q0: (n,) start, rad.
        q1: (n,) goal, rad.

    Returns:
        The trajectory, or None when the two configurations coincide.
    """
    dq = np.abs(q1 - q0)
    if float(dq.max()) < 1e-9:
        return None
    n_steps = int(np.clip(np.ceil(10 + 30 * dq.max() / np.pi), 10, 40))
    t_min = float(np.max(dq / scene.vmax + 2 * np.sqrt(dq / scene.amax)))
    dt = max(0.02, 1.5 * t_min / n_steps)
    sub = replace(scene, waypoints=np.array([q0, q1]), waypoint_names=["start", "goal"], steps=[n_steps], dt=dt)
    res = plan_scene(sub, planners={n_steps: planners.get(n_steps, dt)})
    chk = res.check
    if chk.limit_violations or chk.min_clearance < scene.d_min - CLEARANCE_TOLERANCE:
        raise InfeasibleProblem(f"no motion found that keeps {scene.d_min * 1000:.0f} mm from the obstacles within the "
                                f"limits (best: {chk.min_clearance * 1000:.1f} mm from {chk.worst_obstacle!r} with "
                                f"{chk.worst_link!r}, {chk.limit_violations} limit violations)", value=res)
    return res.trajectory


def plan_path(program: Program, step: Step, q0: np.ndarray) -> Trajectory:
    """The joint trajectory of a ``path`` step: the TCP through its key points from where the robot is.

    Args:
        program: The program.
        step: The ``path`` step (points (K, 3) m, speed m/s).
        q0: (n,) configuration at the step's start, rad; its TCP is prepended as the first point.

    Returns:
        The joint trajectory sampled every 10 ms.
    """
    robot = program.robot
    P = np.asarray(step.args["points"], float)
    p0 = robot.fk(q0)[:3, 3]
    if np.linalg.norm(P[0] - p0) > 1e-4:
        P = np.vstack([p0, P])
    keep = np.r_[True, np.linalg.norm(np.diff(P, axis=0), axis=1) > 1e-6]
    tr = blended_trajectory(P[keep], speed=step.args["speed"], blend_time=0.3)
    t, Q, dQ = joint_velocity_reference(robot, q0, tr, dt=0.002)
    sel = np.r_[0:len(t):5, len(t) - 1] if (len(t) - 1) % 5 else np.r_[0:len(t):5]
    t, Q, dQ = t[sel], Q[sel], dQ[sel]
    dQ[0] = dQ[-1] = 0.0
    ddQ = np.gradient(dQ, t, axis=0)
    return Trajectory(t, Q, dQ, ddQ, list(robot.joint_names), {"step": step.name, "kind": "path"})


@lru_cache(maxsize=1)
def _gripper_robot() -> Robot:
    """The LR Mate with the 48 mm gripper's grasp frame as its tool (loaded once)."""
    return lrmate_with_gripper()  # type: ignore[no-any-return]


def check_place_reachable(at: tuple[float, float]) -> None:
    """Check that the gripper reaches down to the table at ``at`` (a top-down grasp 5 cm above it).

    Args:
        at: (x, y) place target on the table, m.

    Raises:
        IKFailure: It does not.
    """
    gripper_robot = _gripper_robot()
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # approach (grasp z) pointing down
    T[:3, 3] = [at[0], at[1], 0.05]
    if not len(gripper_robot.ik(T)):
        raise IKFailure(f"the gripper cannot reach down to the table at {list(at)} m", value=at)


def _resolve_move(program: Program, target: Target, q_prev: np.ndarray) -> np.ndarray:
    """:func:`resolve_target`, an unreachable pose named with its key and its distance from the base."""
    try:
        return resolve_target(program, target, q_prev)
    except IKFailure:
        if target.pose is None:
            raise
        xyz = np.asarray(target.pose, float)[:3, 3]
        far = float(np.linalg.norm(xyz))
        raise IKFailure(f"key 'pose' xyz {np.round(xyz, 3).tolist()} m ({far:.2f} m from the robot's base) is "
                        "outside the workspace: no IK solution within the joint limits reaches it",
                        value=xyz.tolist()) from None


def _extent(model: ObjectModel) -> tuple[tuple[float, float], float]:
    """Footprint half extents (m, about the object's frame) and height (m) of an object model."""
    b = np.asarray(model.mesh.bounds, float)
    half = np.maximum(np.abs(b[0, :2]), np.abs(b[1, :2]))
    return (float(half[0]), float(half[1])), float(b[1, 2])


def _check_objects(program: Program) -> dict[str, ObjectModel]:
    """Refuse an object placed off the table, in a fixture, unseen or out of reach; its model per category.

    Returns:
        The first object model of each category (the part a ``grasp`` of that category picks, for ``place``).

    Raises:
        ProgramRejected: naming the step that grasps the object (or the object) and the key ``at``.
    """
    models: dict[str, ObjectModel] = {}
    for k, o in enumerate(program.objects):
        if o.at is None and o.category in models:
            continue
        try:
            model = object_model(o, k)
        except RobointelError as exc:
            raise ProgramRejected(f"object {k} ({o.category}): {exc}", value={"object": k}) from None
        models.setdefault(o.category, model)
        if o.at is None:  # a random placement: drawn inside the cell's pick area
            continue
        half, height = _extent(model)
        why = spot_problem(o.at[0], o.at[1], yaw=o.yaw or 0.0, half=half, height=height,
                           obstacles=program.scene.obstacles, reachable=check_place_reachable)
        if why:
            where = f"object {k} ({o.category}), key 'at' {list(o.at)} m: the part is {why}"
            i = next((j for j, st in enumerate(program.steps) if st.kind == "grasp"
                      and st.args["category"] == o.category), None)
            if i is None:
                raise ProgramRejected(where, value={"object": k})
            raise _reject(program.steps[i], i, where)
    return models


def skill_path(program: Program, step: Step) -> Path:
    """The skill file of an ``insert`` or ``grind`` step, relative paths resolved against the program's folder."""
    p = Path(step.args["skill"])
    if not p.is_absolute() and program.source is not None and not p.exists():
        p = program.source.parent / p
    return p


def check_program(program: Program, q_start: np.ndarray, *, start: int = 0,
                  progress: Callable[[float, str], None] | None = None) -> ProgramCheck:
    """Check a whole program before the robot moves (and plan its motions).

    Every target is resolved (IK for poses), checked against the joint limits and the scene's
    obstacles (spheres of the robot's collision model, clearance ``d_min``), every motion is
    planned and its trajectory checked on a 1 ms resample (clearance >= d_min - 1 mm, position,
    velocity and acceleration limits).

    Args:
        program: The program.
        q_start: (n,) the robot's configuration now, rad.
        start: Index of the first step to run (``--from``); earlier steps are not checked.
        progress: Optional callback (fraction done, status).

    Returns:
        The :class:`ProgramCheck` with a plan per step (steps before ``start`` hold empty plans).

    Raises:
        ProgramRejected: A step cannot run; the message names the step and why (or an object whose YCB
            scan is not available).
    """
    t0 = time.perf_counter()
    scene = program.scene
    robot = program.robot
    q = robot.check_q(q_start, "q_start", limits=True).copy()
    for k, o in enumerate(program.objects):
        if o.ycb is not None:
            try:
                data_path("objects", "ycb", o.ycb, "mesh.ply")
            except DataMissing as exc:
                raise ProgramRejected(f"object {k} ({o.category}): the YCB scan {o.ycb!r} is not available: {exc}",
                                      value={"object": k, "ycb": o.ycb}) from None
    held = _check_objects(program)
    planners = _Planners(scene)
    checker = planners.checker()
    plans: list[StepPlan] = [StepPlan(q, q) for _ in range(start)]
    # a program with objects runs on the gripper cell: its moves are planned with the gripper on the flange
    tool = gripper_geometry(ParallelGripper()) if program.objects else []
    cell_planner = CellPlanner(scene) if tool else None
    known = True  # the configuration at the step's start is known (no grasp/place before it)
    holding: str | None = None  # the category of the part in the gripper
    for i in range(start, len(program.steps)):
        step = program.steps[i]
        if progress:
            progress((i - start) / max(1, len(program.steps) - start), f"checking {step.name}")
        t1 = time.perf_counter()
        plan = StepPlan(q.copy(), q.copy())
        try:
            if step.kind == "move":
                q1 = _resolve_move(program, step.args["target"], q)
                checker.check_waypoints(np.array([q1]), [f"the target of step {i} ({step.name!r})"])
                if cell_planner is not None and cell_planner.clearance(q1, tool, self_collision=False) < scene.d_min:
                    raise InvalidInput(f"the gripper comes within {scene.d_min * 1000:.0f} mm of an obstacle at the "
                                       "target")
                if known:
                    plan.trajectory = (cell_planner.plan(q, q1, tool) if cell_planner is not None
                                       else plan_move(scene, planners, q, q1))
                else:
                    plan.deferred = True
                plan.q_end = q1
                known = True
            elif step.kind == "path":
                if not known:
                    raise InvalidInput("a path step must follow a move (it starts where the robot is)")
                plan.trajectory = plan_path(program, step, q)
                plan.q_end = plan.trajectory.q[-1].copy()
            elif step.kind in ("grasp", "place", "guide"):
                if step.kind == "grasp":
                    holding = step.args["category"]
                if step.kind == "place":
                    x, y = step.args["at"]
                    model = held.get(holding) if holding is not None else None
                    half, height = _extent(model) if model is not None else (DEFAULT_HALF, DEFAULT_HEIGHT)
                    why = spot_problem(x, y, half=half, height=height, obstacles=scene.obstacles,
                                       reachable=check_place_reachable)
                    if why:
                        raise InvalidInput(f"key 'at' {[x, y]} m: the place spot is {why}")
                    holding = None
                known = False
            elif step.kind in SKILL_KINDS:
                skill = load_skill(skill_path(program, step))
                if skill_kind(skill) != SKILL_KINDS[step.kind]:
                    raise InvalidInput(f"skill file {step.args['skill']!r} holds a {skill_kind(skill)} skill, not "
                                       f"{SKILL_KINDS[step.kind]}")
        except (IKFailure, CollisionAtStart, InfeasibleProblem, InvalidInput) as exc:
            raise _reject(step, i, str(exc)) from None
        except RobointelError as exc:
            raise _reject(step, i, f"{type(exc).__name__}: {exc}") from None
        if plan.trajectory is not None:
            chk = check_trajectory(plan.trajectory, robot, scene.obstacles, scene.vmax * (1 + 1e-6),
                                   scene.amax * (1e6 if step.kind == "path" else 1 + 1e-6))
            plan.min_clearance_m = chk.min_clearance
            if chk.limit_violations:
                raise _reject(step, i, f"the motion leaves the joint limits at {chk.limit_violations} of "
                                       f"{chk.samples} samples (largest speed ratio {chk.max_velocity_ratio:.2f})")
            if chk.min_clearance < scene.d_min - CLEARANCE_TOLERANCE:
                raise _reject(step, i, f"the motion comes {chk.min_clearance * 1000:.1f} mm from obstacle "
                                       f"{chk.worst_obstacle!r} with link {chk.worst_link!r} (required "
                                       f"{scene.d_min * 1000:.1f} mm)")
        plan.plan_ms = (time.perf_counter() - t1) * 1e3
        plans.append(plan)
        q = plan.q_end.copy()
    if progress:
        progress(1.0, "checked")
    return ProgramCheck(plans=plans, check_ms=(time.perf_counter() - t0) * 1e3, scene_key=scene_key(scene))
