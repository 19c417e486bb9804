"""Learned skills and grasps on a robot: ``robointel skill grind`` and ``robointel grasp execute``.

``skill insert`` is in :mod:`robointel.commands.insertion` (it runs a skill file at the learning benchmark's
task); the helpers here (robot URL, recorder, wrench source) serve it too. Each learns (or plans) as the
Ch. 5-6 commands do, then runs on the robot interface,
``--robot sim`` (the MuJoCo workcell; ``sim?process=1``: the paced workcell in a streaming process, not for
grasps) or ``--robot fanuc://HOST`` (Stream Motion + RMI), with
``--record run.mcap`` writing the run as a ROS 2 bag. On a FANUC controller without force telemetry
``--wrench virtual`` stands a simulated contact in for the F/T sensor (for the controller emulator).
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

from robointel.commands.failure import fail
from robointel.control.payload import PayloadCompensation
from robointel.errors import RobointelError
from robointel.interface import RobotState, open_robot
from robointel.interface.backend import Backend
from robointel.interface.gripper import FanucGripper, JawGeometry, SimGripper
from robointel.interface.open import ROBOT_FORMS, parse_robot_url
from robointel.interface.sim import SimRobot
from robointel.interface.wrench_source import StateWrench, VirtualWall, WrenchSource
from robointel.io.mcap_log import McapRecorder
from robointel.skills.cells import (
    R_DOWN,
    PegTool,
    PlateTask,
    ik_near,
    plate_workcell,
    stylus,
)
from robointel.skills.grasp_execution import GraspMotion, execute_grasp, joint_move
from robointel.skills.grinding import run_grinding

console = Console()
skill_app = typer.Typer(no_args_is_help=True, help="Run learned skills: insert (a skill file from `learn "
                        "insertion`; 20 um on sim by default), grind (--robot sim|sim?process=1|fanuc://HOST).")

ROBOT_HELP = ROBOT_FORMS
RECORD_HELP = "record the run as a ROS 2 bag (.mcap)"
STALL_HELP = "fanuc: stop the robot when the skill gives no target for this long, ms"
_CELLS = "robointel.skills.cells"
WRENCH_HELP = "'sensor' (the robot's F/T reading) or 'virtual' (a simulated contact, for the controller emulator)"


def _check_url(robot: str) -> str:
    """Refuse a robot URL that :func:`~robointel.interface.open_robot` cannot open, before any learning.

    Returns:
        ``"sim"`` (the workcell in this process), ``"stream"`` (``sim?process=1``) or ``"fanuc"``.
    """
    try:
        u = parse_robot_url(robot)
    except RobointelError as exc:
        fail(exc)
    return "fanuc" if u.kind == "fanuc" else "stream" if u.stream_process else "sim"


@contextmanager
def _progress(label: str, total: int) -> Iterator[Callable[[int, RobotState], None]]:
    with Progress(TextColumn(label), BarColumn(), TimeRemainingColumn(), console=console) as bar:
        task = bar.add_task(label, total=total)
        yield lambda k, st: bar.update(task, completed=min(k + 1, total))


def _go_to(arm: Backend, robot: Any, q: np.ndarray) -> None:
    """Move a real arm to ``q`` (rad) with a jerk-limited joint motion at 20 % of the limits."""
    st = arm.state()
    q_now = st.q_cmd if st.q_cmd is not None else st.q
    if np.max(np.abs(q - q_now)) > 1e-4:
        arm.execute(joint_move(robot, q_now, q, arm.period, speed=0.2))


def _open(robot: str, rec: McapRecorder | None, stall_ms: float, **kw: Any) -> Backend:
    """Open a FANUC robot (or the sim's streaming process) whose stall watchdog allows ``stall_ms`` without a target."""
    if not (np.isfinite(stall_ms) and stall_ms >= 8.0):
        raise typer.BadParameter(f"--stall-ms must be >= 8 (one period), got {stall_ms}")
    return open_robot(robot, recorder=rec, stall_periods=int(np.ceil(stall_ms / 8.0)), **kw)


def _recorder(record: Path | None, robot: Any) -> McapRecorder | None:
    return McapRecorder(record, list(robot.joint_names)) if record is not None else None


def _source(wrench: str, robot: Any, tool: PegTool, wall: tuple[np.ndarray, float] | None) -> WrenchSource:
    if wrench == "sensor":
        return StateWrench(robot, PayloadCompensation(tool.mass, np.asarray(tool.payload().com)))
    if wrench == "virtual" and wall is not None:
        return VirtualWall(robot, wall[0], (0.0, 0.0, 1.0), stiffness=wall[1], damping=30.0, noise=0.05)
    raise typer.BadParameter(f"--wrench must be 'sensor' or 'virtual', got {wrench!r}")


@skill_app.command("grind")
def grind(robot: str = typer.Option("sim", help=ROBOT_HELP), record: Path = typer.Option(None, help=RECORD_HELP),
          demos: int = typer.Option(2, min=1, help="HDD grinding demonstrations"),
          wrench: str = typer.Option("sensor", help=WRENCH_HELP), seed: int = typer.Option(0),
          speed: float = typer.Option(0.03, help="path speed, m/s"),
          stall_ms: float = typer.Option(80.0, help=STALL_HELP)) -> None:
    """Learn where to press hard from grinding demonstrations, then grind the plate's diagonal on the robot.

    The learned force map (Fig. 5.13) is the set-point of an axial admittance over streamed positions.
    """
    from robointel.learning import grinding as gr

    kind = _check_url(robot)
    try:
        plate = gr.Plate()
        rng = np.random.default_rng(seed)
        with Progress(TextColumn("demonstrations"), BarColumn(), console=console) as bar:
            t = bar.add_task("demos", total=demos + 1)
            ds = []
            for _ in range(demos):
                ds.append(gr.demonstrate_grinding(plate, rng))
                bar.advance(t)
            skill = gr.GrindingSkill(plate).fit(ds)
            bar.advance(t)
        task, tool = PlateTask(plate.center, plate.top, plate.size), stylus()
        c = np.array(plate.center)
        half = 0.5 * np.array(plate.size) - 0.02
        a, b = np.r_[c - half, plate.top + tool.radius + 5e-4], np.r_[c + half, plate.top + tool.radius]
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R_DOWN, a
        wc, arm_robot = plate_workcell(task, tool)
        q0 = ik_near(arm_robot, T)
        rec = _recorder(record, arm_robot)
        try:
            if kind == "stream":  # the same cell, built in the streaming process
                arm: Backend = _open(robot, rec, stall_ms, q0=q0, workcell_factory=f"{_CELLS}:plate_workcell",
                            factory_args=(task, tool))
            elif kind == "sim":
                wc.reset(q0)
                wc.hold(0.2)
                arm = SimRobot(wc, recorder=rec)
            else:
                arm = _open(robot, rec, stall_ms)
            with arm:
                _go_to(arm, arm_robot, q0)
                surface = np.r_[c, plate.top + tool.radius]
                src = _source(wrench, arm_robot, tool, (surface, 3000.0))
                L = float(np.linalg.norm(b[:2] - a[:2]))
                with _progress("grinding", int((1.0 + L / speed) / arm.period) + 1) as tick:
                    res = run_grinding(arm, arm_robot, lambda p: float(skill.predict((p[:2] - c)[None])[0]), a, b,
                                       source=src, speed=speed, on_cycle=tick)
        finally:
            if rec is not None:
                rec.close()
        intended = plate.force_profile(res.position[:, :2] - c)
        console.print(f"grinding on {robot.split('?')[0]}: {res.outcome.detail or 'path completed'}; force RMS "
                      f"error / peak: {100 * res.rms_rel():.1f} % vs the learned set-point, "
                      f"{100 * res.rms_rel(intended):.1f} % vs the demonstrator's intended force"
                      + (f"; recorded to {record}" if record is not None else ""))
    except RobointelError as exc:
        fail(exc)


def grasp_execute(category: str = typer.Option("box", help="category of the random target"),
                  seed: int = typer.Option(0), robot: str = typer.Option("sim", help=ROBOT_HELP),
                  record: Path = typer.Option(None, help=RECORD_HELP)) -> None:
    """Perceive a held-out object, plan a grasp and execute it on the robot.

    Classify, transfer (6.14)-(6.16), search (6.21); then open, approach, descend, close, lift 10 cm
    (sim: the object on the table).
    """
    from robointel.commands.grasp import _one_target
    from robointel.learning.grasp import GraspPlanner
    from robointel.learning.grasp.trial import Q_PARK
    from robointel.sim import Workcell
    from robointel.sim.mjcf import Payload, SimObject

    if _check_url(robot) == "stream":
        fail("grasp execute runs on 'sim' or 'fanuc://...': the sim's streaming process has no gripper")
    try:
        with Progress(TextColumn("{task.description}"), BarColumn(), console=console) as bar:
            step = bar.add_task("perceive and plan", total=2)
            _, obj, place, cloud, templates = _one_target("demo", category, seed, None)
            planner = GraspPlanner(templates)
            plan = planner.plan(cloud, exclude=(obj.name,))
            if not plan.feasible:
                fail(f"no feasible grasp on {obj.name}")
            bar.update(step, advance=1, description=f"execute on {robot.split('?')[0]}")
            g = plan.gripper
            arm_robot = planner.robot_for(g)
            jaws = JawGeometry(g.max_width, g.finger_length, g.finger_breadth, g.finger_thickness, g.tip_depth)
            motion = GraspMotion(plan.search.grasp.pose, g.max_width, q_grasp=plan.search.q)
            rec = _recorder(record, arm_robot)
            try:
                if robot == "sim":
                    wc = Workcell(objects=[SimObject(obj.name, obj.mesh, obj.mass, pose=place.pose)],
                                  payload=Payload(g.mass, (g.flange_offset, 0.0, 0.0)))
                    wc.reset(Q_PARK)
                    wc.hold(0.3)
                    z0 = float(wc.body_pose(obj.name)[2, 3])
                    sim = SimRobot(wc, recorder=rec)
                    try:
                        run = execute_grasp(sim, SimGripper(sim, arm_robot, jaws), arm_robot, motion)
                        sim.idle(0.5)
                    finally:
                        sim.close()
                    lifted = float(wc.body_pose(obj.name)[2, 3]) - z0
                    ok = run.success and lifted > 0.8 * motion.lift
                    detail = f"object lifted {lifted * 1e3:.0f} mm"
                else:
                    with open_robot(robot, recorder=rec, gripper=True) as arm:
                        run = execute_grasp(arm, FanucGripper(arm), arm_robot, motion)
                    ok, detail = run.success, "gripper commanded over RMI"
            finally:
                if rec is not None:
                    rec.close()
            bar.update(step, advance=1)
        console.print(f"{obj.name} -> {plan.classification.category} with the {g.name} gripper: "
                      f"{'picked' if ok else 'FAILED'} ({run.outcome.detail or run.outcome.reason.value}; {detail})"
                      + (f"; recorded to {record}" if record is not None else ""))
        if not ok:
            raise typer.Exit(1)
    except RobointelError as exc:
        fail(exc)


def register(app: typer.Typer) -> None:
    """Add ``skill grind`` and ``grasp execute`` to the application (``skill insert``: :mod:`.insertion`).

    Args:
        app: The top-level typer application (the ``grasp`` group is registered before this module).
    """
    from robointel.commands.grasp import grasp_app

    grasp_app.command("execute")(grasp_execute)
    app.add_typer(skill_app, name="skill")
