"""``robointel plan motion``: start to goal for any URDF with :func:`robointel.planning.plan_motion`.

The arm stands on the workcell's table (its URDF root on the table top, z = 0); the environment is the table,
the floor and the obstacles of ``--obstacles`` (a YAML list of shapes, or a scene file's ``obstacles``).
``--start`` and ``--goal`` are joint values (``q:`` rad, the default, or ``q_deg:``) or a TCP pose
(``pose:x,y,z,roll,pitch,yaw`` in m and deg, solved by IK: every solution is a goal). The verdict printed
is the one ``--execute`` gives (:mod:`robointel.commands.verdict`).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import typer
import yaml
from rich.console import Console

from robointel.commands.failure import fail
from robointel.commands.planning import DEFAULT_D_MIN, plan_app, print_verdict
from robointel.commands.robot_run import run_on_robot
from robointel.commands.verdict import execute_verdict, guard_environment
from robointel.errors import InvalidInput, RobointelError
from robointel.geometry import obstacle_from_dict
from robointel.geometry.rotations import rpy_to_matrix
from robointel.geometry.table import ENVIRONMENT_NAMES
from robointel.io.trajectory import save_trajectory
from robointel.planning import Environment, MotionSettings, plan_motion
from robointel.robot import Robot
from robointel.sim import Workcell

console = Console()
TARGET_HELP = ("joint values, rad ('q:0,-1.2,1.0,0,0.5,0' or just the numbers), in deg ('q_deg:0,-70,60,0,30,0'), "
               "or a TCP pose 'pose:x,y,z,roll,pitch,yaw' (m, deg; its IK solutions are the goals)")


def parse_target(text: str, robot: Robot, what: str) -> npt.NDArray[np.float64]:
    """A ``--start`` / ``--goal`` value: (n,) joints in rad, or a (4, 4) TCP pose.

    Args:
        text: ``q:...`` / bare numbers (rad), ``q_deg:...`` (deg) or ``pose:x,y,z,roll,pitch,yaw`` (m, deg).
        robot: The arm (its joint count).
        what: The option's name, for messages.

    Returns:
        (n,) rad, or (4, 4) for a pose.

    Raises:
        InvalidInput: not one of the forms, a wrong count, or a number that is not finite.
    """
    kind, _, body = text.strip().rpartition(":")
    kind = kind.strip().lower() or "q"
    if kind not in ("q", "q_deg", "pose"):
        raise InvalidInput(f"{what} {text!r}: use q:..., q_deg:... or pose:x,y,z,roll,pitch,yaw", value=text)
    try:
        v = np.array([float(x) for x in body.replace(" ", "").split(",") if x], dtype=float)
    except ValueError:
        raise InvalidInput(f"{what} {text!r}: not a comma-separated list of numbers", value=text) from None
    need = 6 if kind == "pose" else robot.nq
    if v.shape != (need,) or not np.all(np.isfinite(v)):
        parts = "x, y, z in m, roll, pitch, yaw in deg" if kind == "pose" else f"one per joint of {robot.name}"
        raise InvalidInput(f"{what} {text!r}: needs {need} finite numbers ({parts})", value=text)
    if kind == "pose":
        T = np.eye(4)
        T[:3, :3] = rpy_to_matrix(np.radians(v[3:]))
        T[:3, 3] = v[:3]
        return T
    return np.radians(v) if kind == "q_deg" else v


def load_obstacles(path: Path | None) -> list[Any]:
    """Obstacles from a YAML list of shapes or a scene file's ``obstacles`` (the table and floor left out)."""
    if path is None:
        return []
    try:
        data = yaml.safe_load(Path(path).read_text())
    except yaml.YAMLError as exc:
        raise InvalidInput(f"{path}: not YAML: {exc}", value=str(path)) from None
    items = data.get("obstacles", []) if isinstance(data, dict) else data
    if not isinstance(items, list):
        raise InvalidInput(f"{path}: expected a list of obstacles (or a mapping with 'obstacles')", value=str(path))
    return [o for o in (obstacle_from_dict(d) for d in items) if getattr(o, "name", None) not in ENVIRONMENT_NAMES]


@plan_app.command("motion")
def plan_motion_cmd(urdf: str = typer.Option(..., "--urdf", help="the arm: a URDF path, or lrmate200id7l, ur5, panda "
                                             "(SRDF beside a URDF is used)"),
                    start: str = typer.Option(..., help="start: " + TARGET_HELP.split(", or a TCP")[0]),
                    goal: str = typer.Option(..., help="goal: " + TARGET_HELP),
                    obstacles: Path = typer.Option(None, help="YAML list of obstacles (or a scene file): box, "
                                                   "sphere, capsule, cylinder, pointcloud"),
                    time_budget: float = typer.Option(1.0, "--time-budget", help="planning budget, s"),
                    d_min: float = typer.Option(DEFAULT_D_MIN, "--d-min", help="clearance to the environment and "
                                                "between links, m (the default is MotionSettings.d_min)"),
                    out: Path = typer.Option(Path("traj.npz"), help="trajectory file (.npz or .json)"),
                    execute: bool = typer.Option(False, "--execute", help="run it: in the MuJoCo workcell (--robot "
                                                 "sim) or on the robot at --robot"),
                    robot: str = typer.Option("sim", help="with --execute: the robot URL: 'sim', 'sim?process=1' or "
                                              "'fanuc://HOST[:RMI_PORT][?sm_port=N]'"),
                    record: Path = typer.Option(None, help="with --execute: record the run as a ROS 2 bag (.mcap)"),
                    ) -> None:
    """Plan start to goal for any URDF (plan_motion: exact meshes, self-collision), on the workcell's table.

    Prints the plan and the verdict --execute will give; exit code 1 when planning failed or --execute would
    refuse the trajectory. View it with `robointel view TRAJ --robot URDF`.
    """
    if not (np.isfinite(time_budget) and time_budget > 0):
        fail(f"--time-budget must be > 0 s, got {time_budget!r}")
    if not (np.isfinite(d_min) and d_min >= 0):
        fail(f"--d-min must be >= 0 m, got {d_min!r}")
    try:
        arm = Robot.load(urdf)
        q0 = parse_target(start, arm, "--start")
        if q0.shape != (arm.nq,):
            raise InvalidInput(f"--start must be joint values (q: or q_deg:), got {start!r}", value=start)
        g = parse_target(goal, arm, "--goal")
        obs = load_obstacles(obstacles)
        srdf = Path(urdf).with_suffix(".srdf")
        env = Environment(arm, guard_environment(obs), srdf=srdf if srdf.is_file() else None)
        with console.status(f"planning ({time_budget:g} s budget)"):
            plan = plan_motion(arm, env, q0, g, settings=MotionSettings(d_min=d_min, time_budget_s=time_budget))
    except RobointelError as exc:
        fail(exc)
    if plan.trajectory is None or not plan.success:
        console.print(f"no motion found in {plan.plan_ms:.0f} ms: {plan.reason}")
        raise typer.Exit(1)
    tr = plan.trajectory
    out.parent.mkdir(parents=True, exist_ok=True)
    save_trajectory(tr, out)
    console.print(f"{arm.name}: planned in {plan.plan_ms:.0f} ms, {tr.duration:.2f} s of motion through "
                  f"{len(plan.path) if plan.path is not None else 0} waypoints; dense check: min clearance "
                  f"{plan.min_clearance_m * 1e3:.1f} mm")
    why = execute_verdict(arm, obs, tr)
    if execute:
        if why:
            fail(why)
        try:
            if robot == "sim" and record is None:
                _track(arm, obs, tr)
            else:
                wc = {"workcell": Workcell(arm, obstacles=obs)} if robot == "sim" else {}
                run_on_robot(tr, robot, record, console, sim_kwargs=wc)
        except RobointelError as exc:
            fail(exc)
    console.print(f"trajectory: [bold]{out}[/bold]")
    print_verdict(why)
    if why and not execute:
        raise typer.Exit(1)


def _track(arm: Robot, obstacles: list[Any], tr: Any) -> None:
    """Track ``tr`` in the MuJoCo workcell of ``arm``; exit 1 when the robot touched an obstacle."""
    wc = Workcell(arm, obstacles=obstacles, ft_sensor=False)
    with console.status("tracking in MuJoCo"):
        log = wc.run_trajectory(tr, record_ft=False)
    err = np.asarray(log.error)
    touched = bool(log.min_distance < 0 or np.any(np.asarray(log.contacts) > 0))
    console.print(f"MuJoCo: RMS tracking error {np.degrees(np.sqrt(np.mean(err ** 2))):.4f} deg, max "
                  f"{np.degrees(np.max(np.abs(err))):.4f} deg, min obstacle distance {log.min_distance * 1e3:.1f} mm")
    if touched:
        typer.echo("error: the robot touched an obstacle in MuJoCo", err=True)
        raise typer.Exit(1)
