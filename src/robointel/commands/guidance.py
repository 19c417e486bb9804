"""``robointel guide``: the Ch. 4 guidance scenarios, and the guidance stage of ``robointel demo``.

A simulated operator pulls the handle of the LR Mate in the MuJoCo workcell along a path that would
hit one of the Table 4.1 cylinders; the guidance controller (relaxed QP (4.11) with the sigmoid
blend (4.12)-(4.13) by default) keeps the arm off the obstacle while resisting the operator as
little as possible. Writes the four panels of Fig. 4.6b and the figures as JSON.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import typer
from rich.console import Console
from rich.progress import Progress
from rich.table import Table

from robointel.commands.failure import fail
from robointel.commands.robot_run import guide_on_robot, run_on_robot
from robointel.errors import RobointelError
from robointel.report.demo import Figure, StageContext, StageResult
from robointel.robot import Robot
from robointel.sim import Workcell
from robointel.teach.guidance import METHODS
from robointel.teach.keypoints import plot_reproduction, reproduce_path
from robointel.teach.scenarios import ScenarioResult, plot_scenario, run_scenario, scenario

METHOD_HELP = ("qp: relaxed QP (4.11); equality: (4.10); repulsive: repulsive vector (4.1); "
               "nullspace: task-priority null space (4.2)-(4.3)")


def register(app: typer.Typer) -> None:
    """Add the ``guide`` and ``keypoints`` commands to ``app``.

    Args:
        app: The top-level typer application.
    """

    @app.command()
    def guide(scenario: int = typer.Option(2, "--scenario", "-s", help="Table 4.1 scenario: 1, 2 or 3"),
              method: str = typer.Option("qp", "--method", "-m", help=METHOD_HELP),
              out: Path = typer.Option(Path("robointel-guide"), help="output folder for the plot and JSON"),
              duration: float = typer.Option(None, help="simulated seconds (default: the whole operator path)"),
              physics: bool = typer.Option(True, help="MuJoCo with the F/T sensor in the loop (else kinematic)"),
              robot: str = typer.Option("sim", help="'sim' (the scenario), 'sim?process=1' or 'fanuc://HOST': "
                                                          "guide the arm by hand"),
              record: Path = typer.Option(None, help="with --robot fanuc://...: record the run as a ROS 2 bag (.mcap)"),
              ft: str = typer.Option(None, "--ft", help="with --robot fanuc://...: the wrist F/T sensor, "
                                                        "netft://HOST[:PORT][?cpf=COUNTS&cpt=COUNTS] (ATI RDT)"),
              ) -> None:
        """Run a guidance scenario with a simulated operator and write Fig. 4.6b-style plots."""
        console = Console()
        if scenario not in (1, 2, 3):
            fail(f"--scenario must be 1, 2 or 3 (Table 4.1), got {scenario}")
        if duration is not None and not (np.isfinite(duration) and duration > 0):
            fail(f"--duration must be a positive number of simulated seconds, got {duration}")
        if robot != "sim":  # lead-through on a real arm through the robot interface
            try:
                guide_on_robot(robot, record, duration or 30.0, method, console, ft=ft)
            except RobointelError as exc:
                fail(exc)
            return
        if method not in METHODS:
            fail(f"--method must be one of {', '.join(METHODS)}, got {method!r}")
        try:
            with Progress(console=console) as prog:
                task = prog.add_task(f"scenario {scenario} / {method}", total=1.0)
                res = run_scenario(scenario, method, duration=duration, physics=physics,
                                   progress=lambda f: prog.update(task, completed=f))
                prog.update(task, completed=1.0)
        except RobointelError as exc:
            fail(exc)
        out.mkdir(parents=True, exist_ok=True)
        png = plot_scenario(res, out / f"guidance_s{scenario}_{method}.png")
        m = res.metrics()
        (out / f"guidance_s{scenario}_{method}.json").write_text(json.dumps({"scenario": scenario, "method": method,
                                                                             **m, **res.extra}, indent=2))
        t = Table(title=f"scenario {scenario}, method {method} ({'MuJoCo' if physics else 'kinematic'})")
        t.add_column("figure")
        t.add_column("value", justify="right")
        for k in ("min_distance_m", "max_penetration_m", "mean_velocity_deviation", "max_velocity_deviation",
                  "mean_angular_deviation", "min_approach_rate_active", "step_us_median", "step_us_p99",
                  "step_cpu_us_median", "step_cpu_us_p99", "held_steps"):
            t.add_row(k, f"{m[k]:.4g}")
        console.print(t)
        console.print(f"plot: [bold]{png}[/bold]")

    @app.command()
    def keypoints(scenario_id: int = typer.Option(2, "--scenario", "-s", help="Table 4.1 scenario whose guided path "
                                                                               "is reproduced: 1, 2 or 3"),
                  method: str = typer.Option("qp", "--method", "-m", help=METHOD_HELP),
                  duration: float = typer.Option(None, help="guide for this many seconds (default: the whole path)"),
                  tolerance: float = typer.Option(0.01, help="key-point (RDP) tolerance, m"),
                  speed: float = typer.Option(0.15, help="TCP speed of the reproduction, m/s"),
                  out: Path = typer.Option(Path("robointel-keypoints"), help="output folder for the plot"),
                  robot: str = typer.Option("sim", help="execute on 'sim', 'sim?process=1' or 'fanuc://HOST[:RMI_PORT][?sm_port=N]'"),
                  record: Path = typer.Option(None, help="record the execution as a ROS 2 bag (.mcap)")) -> None:
        """Reproduce a guided path from its key points (Figs. 3.11-3.12) and execute it on the robot.

        The path is guided kinematically (the scenario's simulated operator, guidance ``method``),
        reduced to key points, blended into a joint trajectory and executed through the robot
        interface (the arm first moves to the path's start).
        """
        console = Console()
        if scenario_id not in (1, 2, 3):
            fail(f"--scenario must be 1, 2 or 3 (Table 4.1), got {scenario_id}")
        if method not in METHODS:
            fail(f"--method must be one of {', '.join(METHODS)}, got {method!r}")
        for name, v in (("--tolerance", tolerance), ("--speed", speed)) + ((("--duration", duration),)
                                                                          if duration is not None else ()):
            if not (np.isfinite(v) and v > 0):
                fail(f"{name} must be a positive number, got {v}")
        try:
            with console.status(f"guiding scenario {scenario_id} ({method}, kinematic)"):
                res = run_scenario(scenario_id, method, duration=duration, physics=False)
            lr = Robot.load("lrmate200id7l")
            rot = np.array([lr.fk(q)[:3, :3] for q in res.q])
            rep = reproduce_path(lr, res.t, res.tcp, res.q[0], rotations=rot, tolerance=tolerance, speed=speed)
            console.print(f"{len(rep.keypoints)} key points from {len(res.t)} samples; reproduced path within "
                          f"{rep.path_error * 1e3:.1f} mm of the guided one; {rep.trajectory.duration:.2f} s")
            wc = {"workcell": Workcell(lr, obstacles=[scenario(scenario_id).obstacle], ft_sensor=False)}
            ex = run_on_robot(rep.trajectory, robot, record, console, sim_kwargs=wc)
        except RobointelError as exc:
            fail(exc)
        out.mkdir(parents=True, exist_ok=True)
        tcp = np.array([lr.fk(q)[:3, 3] for q in ex.q])
        img = plot_reproduction(res.tcp, rep, out / f"keypoints_s{scenario_id}.png", executed=tcp)
        console.print(f"plot: [bold]{img}[/bold]")


def _reproduce(res: ScenarioResult, out: Path) -> tuple[list[Figure], Path]:
    """Key points of a guided TCP path -> blended trajectory -> joint reference, tracked in MuJoCo."""
    robot = Robot.load("lrmate200id7l")
    rot = np.array([robot.fk(q)[:3, :3] for q in res.q])
    rep = reproduce_path(robot, res.t, res.tcp, res.q[0], rotations=rot, tolerance=0.01, speed=0.15)
    wc = Workcell(robot, obstacles=[scenario(res.scenario).obstacle], ft_sensor=False)
    log = wc.run_trajectory(rep.trajectory.t, rep.trajectory.q, rep.trajectory.qd, record_ft=False)
    tcp = np.array([robot.fk(q)[:3, 3] for q in log.q[::10]])
    ref = np.array([robot.fk(q)[:3, 3] for q in log.q_ref[::10]])
    track = float(np.max(np.linalg.norm(tcp - ref, axis=1)))
    img = plot_reproduction(res.tcp, rep, out / "guidance_keypoints.png", executed=tcp)
    d = log.min_distance
    figs = [Figure("key points of the guided path", f"{len(rep.keypoints)} (from {len(res.t)} samples)", None,
                   "start, dwell against the bar, retreat"),
            Figure("reproduced path vs guided (max)", f"{rep.path_error * 1e3:.1f} mm", None,
                   "RDP tolerance 10 mm, quintic blends"),
            Figure("executed in MuJoCo: max TCP tracking error / min obstacle distance",
                   f"{track * 1e3:.2f} mm / {d * 1e3:.1f} mm", None, "joint controller of Fig. 2.3")]
    return figs, img


def demo_stage(ctx: StageContext) -> StageResult:
    """Run the demo's guidance stage: scenario II with the QP method in MuJoCo.

    The operator pushes into the upper bar on purpose; the repulsive-vector baseline runs beside it
    unless ``ctx.quick``.

    Args:
        ctx: The demo stage context (output folder, quick flag, progress).

    Returns:
        The stage's figures, images and text.
    """
    dur = 3.5 if ctx.quick else None
    ctx.advance(0.02, "scenario II, relaxed QP (MuJoCo)")
    qp = run_scenario(2, "qp", duration=dur, progress=lambda f: ctx.advance(0.02 + 0.5 * f, "scenario II, QP"))
    m = qp.metrics()
    images = [plot_scenario(qp, ctx.out / "guidance_s2_qp.png")]
    figs = [
        Figure("min robot-obstacle distance (collision geometry)", f"{m['min_distance_m'] * 1e3:.1f} mm",
               "> 0 (no collision)", "operator pushes into the bar on purpose"),
        Figure("max penetration", f"{m['max_penetration_m'] * 1e3:.1f} mm", "0"),
        Figure("mean / max ||V_cmd - V_lead||", f"{m['mean_velocity_deviation']:.3f} / "
               f"{m['max_velocity_deviation']:.3f} m/s", None, "translation; lead saturated at 0.5 m/s"),
        Figure("min V_cmd . u_rep while avoiding", f"{m['min_approach_rate_active'] * 1e3:.1f} mm/s", None,
               "closest point's approach rate, blended (4.12)"),
        Figure("control step (kinematics, distances, QP, blend)",
               f"{m['step_us_median']:.0f} us median wall; CPU time {m['step_cpu_us_median']:.0f} us median, "
               f"{m['step_cpu_us_p99']:.0f} us p99", "1 kHz loop (1000 us)",
               f"wall p99 {m['step_us_p99']:.0f} us: preemption on a shared machine"),
        Figure("blend parameters", "alpha = 6, d0 = 0.15 m", "alpha = 6, d0 = 0.15 m", "(4.13), corrected"),
        Figure("compliance gain K_d", "0.07 m/(N s)", "0.07 m/(N s)", "(3.11)"),
    ]
    if "identified_mass" in qp.extra:
        figs.append(Figure("payload identified (3.14)-(3.19)", f"{qp.extra['identified_mass']:.4f} kg", None,
                           "true 0.6 kg, with F/T bias and noise"))
    # the guided path, reproduced from its key points (Figs. 3.11-3.12) and executed in MuJoCo
    ctx.advance(0.5, "key-point reproduction")
    try:
        figs_k, img = _reproduce(qp, ctx.out)
        figs += figs_k
        images.append(img)
    except RobointelError as exc:
        figs.append(Figure("key-point reproduction", f"failed: {exc}", None))
    if not ctx.quick:
        ctx.advance(0.55, "scenario II, repulsive baseline")
        rep = run_scenario(2, "repulsive", progress=lambda f: ctx.advance(0.55 + 0.4 * f, "scenario II, repulsive"))
        r = rep.metrics()
        images.append(plot_scenario(rep, ctx.out / "guidance_s2_repulsive.png"))
        figs.append(Figure("repulsive baseline (4.1): min distance / mean deviation",
                           f"{r['min_distance_m'] * 1e3:.1f} mm / {r['mean_velocity_deviation']:.3f} m/s", None,
                           "same operator"))
    ctx.advance(1.0, "done")
    text = ("A simulated operator pulls the handle (wrench applied in MuJoCo, read back by the F/T sensor with "
            "bias and noise, compensated by the identified payload) up into the upper front bar of Table 4.1 "
            "(scenario II) and then retreats. The relaxed QP (4.11) with one row per obstacle keeps the arm "
            "off the bar. Dissertation column: the parameters it states and its claim (no collision); its "
            "other results are plots (Fig. 4.6), so those cells are left blank. The guided path is then "
            "reproduced from its key points (Figs. 3.11-3.12) and executed in MuJoCo.")
    return StageResult("Guidance with collision avoidance (Ch. 4)", figures=figs, images=images, text=text)
