"""Run a checked task program step by step on a robot cell, stopping safely at the first failure."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from robointel.errors import RobointelError
from robointel.interface.sim import SimRobot
from robointel.learning.grinding import GrindingSkill
from robointel.learning.insertion import FeltSkill, InsertionSkill
from robointel.outcome import Failure, TrialOutcome
from robointel.program.check import ProgramCheck, _Planners, check_program, plan_move, scene_key, skill_path
from robointel.program.format import SKILL_KINDS, Program, Step
from robointel.program.guide_step import GuideResult, Operator, PushOperator, run_guide
from robointel.program.skill_file import load_skill, skill_time_limit
from robointel.program.skill_steps import run_grind, run_insert
from robointel.sim import Workcell
from robointel.trajectory import Trajectory

TRACKING_LIMIT_RAD = 0.05  # largest joint tracking error a step may show before it counts as failed
BACKOFF_STEPS = 150  # control periods (1 ms) of the path the robot backs off along after a contact


class Cell(Protocol):
    """What the runner needs of a robot: its configuration, trajectory execution, holding, outputs."""

    @property
    def q(self) -> np.ndarray:
        """(n,) measured joint configuration, rad."""
        ...

    def execute(self, trajectory: Trajectory) -> tuple[TrialOutcome, np.ndarray]:
        """Track a trajectory; return its outcome and the executed joints (M, n)."""
        ...

    def hold(self, seconds: float) -> None:
        """Hold the current position for ``seconds``."""
        ...

    def stop(self, reason: str) -> None:
        """Stop and hold where the robot is, recording why."""
        ...

    def set_io(self, name: str, value: float) -> None:
        """Set a digital/analog output."""
        ...


class SimCell:
    """The MuJoCo workcell as a program cell (1 kHz joint servo, obstacle contacts checked).

    Args:
        program: The program whose scene (robot, obstacles) builds the workcell.
        q0: (n,) start configuration, rad.
        workcell: An existing :class:`robointel.sim.Workcell` to use instead (e.g. with more obstacles than
            the program's scene knows).
    """

    def __init__(self, program: Program, q0: np.ndarray, *, workcell: Workcell | None = None,
                 operator: Operator | None = None, seed: int = 0) -> None:
        guided = any(s.kind == "guide" for s in program.steps)
        self.workcell = workcell or Workcell(program.robot, obstacles=program.scene.obstacles, ft_sensor=guided,
                                             q0=q0)
        if workcell is not None:
            self.workcell.reset(q0)
        self.program = program
        self.operator = operator
        self.seed = int(seed)
        self.io: dict[str, float] = {}
        self.stopped: str | None = None
        self.stations: dict[str, object] = {}  # insert/grind stations (default: the skills' own cells)
        self.guided: list[GuideResult] = []

    def guide(self, timeout: float) -> GuideResult:
        """Lead-through on the workcell (F/T sensor) until the operator presses continue (``guide`` step).

        The operator is the one given to the cell, else a :class:`PushOperator` (20 N along +y for 0.5 s).
        """
        arm = SimRobot(self.workcell)
        op = self.operator or PushOperator(self.workcell, period=arm.period)
        if isinstance(op, PushOperator) and op.workcell is None:
            op = replace(op, workcell=self.workcell, period=arm.period)
        obstacles = [o for o in self.program.scene.obstacles if getattr(o, "name", None) != "floor"]
        res = run_guide(arm, self.program.robot, op, timeout=timeout, obstacles=obstacles)
        self.workcell.clear_wrench()
        self.guided.append(res)
        return res

    @property
    def q(self) -> np.ndarray:
        """(n,) measured joint configuration, rad."""
        return np.asarray(self.workcell.q, float).copy()

    def execute(self, trajectory: Trajectory) -> tuple[TrialOutcome, np.ndarray]:
        """Track ``trajectory`` at 1 kHz, stopping at the first contact with the environment.

        Returns:
            The outcome (COLLISION on a contact, TRACKING when the error exceeds
            ``TRACKING_LIMIT_RAD``) and the measured joints (M, n).
        """
        log = self.workcell.run_trajectory(trajectory, reset=False, record_ft=False, stop_on_contact=True)
        err = float(np.max(np.abs(log.error))) if len(log.q) else 0.0
        figures = {"tracking_max_rad": err, "duration_s": float(log.duration)}
        if np.any(log.contacts):
            k = int(np.flatnonzero(log.contacts)[0])
            touching = self.workcell.contacts()[:2]
            contact = ", ".join(f"{c.robot_body} with {c.kind} {c.other_body}" for c in touching) or "the environment"
            self.retreat(log.q_ref[max(0, k - BACKOFF_STEPS)])
            return TrialOutcome(False, Failure.COLLISION, f"contact with {contact} at t = {log.t[k] - log.t[0]:.3f} s",
                                figures), log.q
        if err > TRACKING_LIMIT_RAD:
            self.stop("tracking")
            return TrialOutcome(False, Failure.TRACKING, f"tracking error {err:.3f} rad > {TRACKING_LIMIT_RAD} rad",
                                figures), log.q
        return TrialOutcome(True, figures=figures), log.q

    def hold(self, seconds: float) -> None:
        """Hold the last reference for ``seconds``."""
        if seconds > 0:
            self.workcell.hold(seconds)

    def stop(self, reason: str) -> None:
        """Hold where the robot is now (measured position, zero velocity)."""
        self.stopped = reason
        self.workcell.track(self.q)
        self.workcell.hold(0.05)

    def retreat(self, q_safe: np.ndarray) -> None:
        """Stop after a contact: back off to ``q_safe`` (a contact-free reference already passed) and hold there."""
        self.stopped = "contact"
        self.workcell.track(np.asarray(q_safe, float))
        self.workcell.hold(0.3)

    def set_io(self, name: str, value: float) -> None:
        """Set an output (kept in :attr:`io`)."""
        self.io[name] = float(value)


@dataclass
class StepResult:
    """What one step did.

    Attributes:
        index: Step index. name: Step name. kind: Step kind.
        outcome: Its :class:`robointel.outcome.TrialOutcome`.
        seconds: Wall time of the step, s.
        executed: (M, n) measured joints while it moved (empty if it did not move).
        replanned: Whether the motion was replanned because the scene changed after the check.
    """

    index: int
    name: str
    kind: str
    outcome: TrialOutcome
    seconds: float
    executed: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    replanned: bool = False


@dataclass
class ProgramRun:
    """A program run.

    Attributes:
        steps: One :class:`StepResult` per step run, in order (stops after the first failure).
        check: The pre-run check.
        failed_step: Index of the step that failed, or None.
        interrupted: The run was stopped by the operator (Ctrl-C) at ``failed_step``.
    """

    steps: list[StepResult]
    check: ProgramCheck
    failed_step: int | None = None
    interrupted: bool = False

    @property
    def success(self) -> bool:
        """True when every step ran and succeeded."""
        return self.failed_step is None

    @property
    def outcome(self) -> TrialOutcome:
        """The run as one :class:`robointel.outcome.TrialOutcome`."""
        secs = {f"step_{r.index}_{r.name}": r.seconds for r in self.steps}
        if self.failed_step is None:
            return TrialOutcome(True, figures={"check_ms": self.check.check_ms}, timings=secs)
        r = self.steps[-1]
        return TrialOutcome(False, r.outcome.reason, f"step {r.index} ({r.name!r}, {r.kind}): {r.outcome.detail}",
                            {"check_ms": self.check.check_ms}, secs)


def run_program(program: Program, cell: Cell, *, start: int | str = 0, check: ProgramCheck | None = None,
                progress: Callable[[int, str], None] | None = None,
                on_step: Callable[[StepResult], None] | None = None) -> ProgramRun:
    """Check the program, then run it step by step on ``cell``.

    Nothing moves before the whole program (from ``start``) has passed :func:`check_program`. A motion
    is replanned from where the robot is if the scene's obstacles changed since the check. The first
    failed step stops the robot (it holds where it is) and ends the run.

    Args:
        program: The program.
        cell: The robot cell (e.g. :class:`SimCell`).
        start: First step to run, by index or name (``--from``).
        check: A check made earlier (else it is made now from the cell's configuration).
        progress: Optional callback (step index, status) before each step.
        on_step: Optional callback with each step's :class:`StepResult` as soon as the step ends (a
            recording of the run is written as it goes).

    Returns:
        The :class:`ProgramRun`. A ``KeyboardInterrupt`` (Ctrl-C) stops the robot where it is and ends
        the run with the interrupted step failed (``interrupted`` set, its motion so far in ``executed``).

    Raises:
        ProgramRejected: The pre-run check refused the program (nothing moved); a cell with a ``refuse``
            method (:class:`InterfaceCell`) refuses what it cannot run first.
    """
    i0 = program.index(start)
    refuse = getattr(cell, "refuse", None)  # the cell's own part of the check (a robot interface's outputs)
    if callable(refuse):
        refuse(program, i0)
    chk = check or check_program(program, cell.q, start=i0)
    results: list[StepResult] = []
    planners = _Planners(program.scene)

    cell_plan = getattr(cell, "plan_move", None)  # a cell with a tool plans with its tool and held object

    def plan_fn(a: np.ndarray, b: np.ndarray) -> Trajectory | None:
        if cell_plan is not None:
            return cell_plan(a, b)  # type: ignore[no-any-return]
        return plan_move(program.scene, planners, a, b)

    i, t0 = i0, time.perf_counter()
    try:
        for i in range(i0, len(program.steps)):
            step = program.steps[i]
            if progress:
                progress(i, step.name)
            t0 = time.perf_counter()
            result = _run_step(program, cell, chk, i, step, plan_fn, t0)
            results.append(result)
            if on_step is not None:
                on_step(result)
            if not result.outcome.success:
                return ProgramRun(results, chk, failed_step=i)
    except KeyboardInterrupt:  # in a step, or between two (a callback): the robot stops where it is
        cell.stop("interrupted")
        if results and results[-1].index == i:  # step i had ended: the next one is the one interrupted
            i += 1
            if i == len(program.steps):
                return ProgramRun(results, chk)
        trace = cell.pop_trace() if hasattr(cell, "pop_trace") else np.zeros((0, program.robot.nq))
        step = program.steps[i]
        result = StepResult(i, step.name, step.kind, TrialOutcome(False, Failure.ERROR, "interrupted (Ctrl-C): "
                                                                  "the robot holds where it stopped"),
                            time.perf_counter() - t0, trace)
        results.append(result)
        if on_step is not None:
            on_step(result)
        return ProgramRun(results, chk, failed_step=i, interrupted=True)
    return ProgramRun(results, chk)


def _run_step(program: Program, cell: Cell, chk: ProgramCheck, i: int, step: Step,
              plan_fn: Callable[[np.ndarray, np.ndarray], Trajectory | None], t0: float) -> StepResult:
    """Run step ``i``; its :class:`StepResult` (a failed step has stopped the robot)."""
    plan = chk.plans[i]
    executed = np.zeros((0, program.robot.nq))
    replanned = False
    if step.kind in ("move", "path"):
        traj = plan.trajectory
        try:
            if step.kind == "move" and (plan.deferred or scene_key(program.scene) != chk.scene_key):
                traj = plan_fn(cell.q, plan.q_end)
                replanned = not plan.deferred
        except RobointelError as exc:
            traj = None
            outcome = TrialOutcome(False, Failure.INFEASIBLE, f"replanning failed: {exc}")
            cell.stop("no motion")
            return StepResult(i, step.name, step.kind, outcome, time.perf_counter() - t0)
        if traj is None:
            outcome = TrialOutcome(True)
        else:
            if float(np.max(np.abs(cell.q - traj.q[0]))) > TRACKING_LIMIT_RAD:
                outcome = TrialOutcome(False, Failure.TRACKING, "the robot is not where the step starts")
                cell.stop("not at the step's start")
            else:
                outcome, executed = cell.execute(traj)
                if hasattr(cell, "pop_trace"):
                    executed = cell.pop_trace()  # on the 1 ms grid
    elif step.kind == "wait":
        cell.hold(step.args["seconds"])
        outcome = TrialOutcome(True)
    elif step.kind in ("grasp", "place"):
        act = getattr(cell, step.kind, None)
        if act is None:
            outcome = TrialOutcome(False, Failure.ERROR, f"the cell {type(cell).__name__} has no gripper and "
                                   "objects (use GraspCell)")
        else:
            arg = step.args["category"] if step.kind == "grasp" else step.args["at"]
            try:
                outcome = act(arg, plan_fn)
            except RobointelError as exc:
                outcome = TrialOutcome(False, Failure.INFEASIBLE, str(exc))
            if hasattr(cell, "pop_trace"):
                executed = cell.pop_trace()
            if not outcome.success:
                cell.stop(step.kind)
    elif step.kind == "guide":
        act = getattr(cell, "guide", None)
        if act is None:
            outcome = TrialOutcome(False, Failure.ERROR, f"the cell {type(cell).__name__} has no F/T sensor for "
                                   "lead-through (use SimCell)")
        else:
            g = act(step.args["timeout"])
            outcome, executed = g.outcome, g.lead.q
        if not outcome.success:
            cell.stop("guide")
    elif step.kind in SKILL_KINDS:
        outcome = _skill_step(program, step, cell, i)
        if not outcome.success:
            cell.stop(step.kind)
    elif step.kind == "set_io":
        outcome = TrialOutcome(True)
        try:
            for k, v in step.args["outputs"].items():
                cell.set_io(k, v)
        except RobointelError as exc:
            outcome = TrialOutcome(False, Failure.FAULT, f"setting the outputs failed: {exc}")
            cell.stop("set_io")
    else:  # pragma: no cover - the format refuses other kinds
        outcome = TrialOutcome(False, Failure.ERROR, f"unknown step kind {step.kind!r}")
    return StepResult(i, step.name, step.kind, outcome, time.perf_counter() - t0, executed, replanned)


def _skill_step(program: Program, step: Step, cell: Cell, i: int) -> TrialOutcome:
    """Run an ``insert`` or ``grind`` step at the cell's station for it (default: the skill's own cell)."""
    try:
        skill = load_skill(skill_path(program, step))
    except RobointelError as exc:
        return TrialOutcome(False, Failure.ERROR, str(exc))
    station = getattr(cell, "stations", {}).get(step.kind)
    seed = int(getattr(cell, "seed", 0)) * 1000 + i
    if step.kind == "insert":
        assert isinstance(skill, (FeltSkill, InsertionSkill))
        a = step.args
        limit = a["time_limit"] if a["time_limit"] is not None else skill_time_limit(skill)
        res = run_insert(skill, seed=seed, time_limit=limit, clearance=1e-3 * a["clearance_mm"],
                         lateral_error=1e-3 * a["lateral_error_mm"], tilt_error=np.radians(a["tilt_error_deg"]),
                         station=station)
    else:
        assert isinstance(skill, GrindingSkill)
        res = run_grind(skill, seed=seed, tolerance=step.args["tolerance"], speed=step.args["speed"], station=station)
    out = res.outcome
    return TrialOutcome(out.success, out.reason, out.detail, {**out.figures, "held_speed_rad_s": res.held_speed})
