"""Planning commands (Ch. 7): ``robointel plan scene|mbm`` (``plan motion``: :mod:`.plan_motion`) and the demo stage.

``plan scene``, the FRMP: scene -> CFS path per segment (obstacles and self-collision) -> temporal
optimization -> trajectory file, with a plot of the joint profiles and a 3D picture of the tool path among
the obstacles, and the verdict ``--execute`` gives (:func:`robointel.commands.verdict.execute_verdict`).
``plan mbm``: MotionBenchMaker problems start to goal with :func:`robointel.planning.plan_motion`.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import numpy.typing as npt
import typer
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from rich.console import Console
from rich.progress import Progress
from rich.table import Table
from typer.core import TyperGroup

from robointel.commands.failure import fail
from robointel.commands.robot_run import run_on_robot
from robointel.commands.verdict import execute_verdict
from robointel.errors import InvalidInput, RobointelError
from robointel.geometry import Box, Sphere
from robointel.io.mbm import load_mbm_problems
from robointel.io.trajectory import save_trajectory
from robointel.planning import Environment, MotionPlan, MotionSettings, plan_motion
from robointel.planning.frmp import FRMPResult, make_planners, plan_scene, planner_settings
from robointel.planning.frmp import execute as run_in_sim
from robointel.planning.replan import receding_horizon
from robointel.planning.scene import load_scene
from robointel.report.demo import Figure, StageContext, StageResult
from robointel.robot import Robot
from robointel.sim import Workcell

DEFAULT_D_MIN = MotionSettings().d_min
"""``--d-min`` of ``plan mbm`` and ``plan motion``: :class:`MotionSettings`'s own default (one value for both)."""


def plot_joint_profiles(result: FRMPResult, path: Path) -> Path:
    """Plot the joint profiles of the FRMP trajectory against the fixed-dt schedule.

    Joint positions, velocities and accelerations of the FRMP trajectory (solid) and of the
    fixed-dt schedule through the same path (dashed), with the limits.

    Args:
        result: The FRMP plan of a scene.
        path: PNG file to write.

    Returns:
        ``path``.
    """
    matplotlib.use("Agg")
    scene = result.scene
    fr = result.trajectory.resample(0.005)
    fx = result.fixed.resample(0.005)
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=False)
    names = scene.robot.joint_names
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for j in range(scene.robot.nq):
        c = colors[j % len(colors)]
        axes[0].plot(fr.t, np.degrees(fr.q[:, j]), color=c, label=names[j])
        axes[0].plot(fx.t, np.degrees(fx.q[:, j]), color=c, ls="--", lw=0.8)
        axes[1].plot(fr.t, fr.qd[:, j] / scene.vmax[j], color=c)
        axes[2].plot(fr.t, fr.qdd[:, j] / scene.amax[j], color=c)
    for ax in axes[1:]:
        ax.axhline(1, color="k", lw=0.6)
        ax.axhline(-1, color="k", lw=0.6)
    stops = np.cumsum([0.0] + [t.duration for t in result.temporal])
    for ax in axes:
        for s in stops:
            ax.axvline(s, color="0.8", lw=0.6, zorder=0)
    axes[0].set_ylabel("q [deg]")
    axes[0].legend(ncol=6, fontsize=7, loc="upper right")
    axes[0].set_title(f"{scene.name}: FRMP {result.operational_time_frmp:.2f} s (solid) vs fixed dt "
                      f"{result.operational_time_fixed:.2f} s (dashed)")
    axes[1].set_ylabel("qd / vmax")
    axes[2].set_ylabel("qdd / amax")
    axes[2].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def _box_faces(box: Box) -> list[list[npt.NDArray[np.float64]]]:
    """Return the six quadrilateral faces of ``box`` as lists of four (3,) corner points, m."""
    c, h, R = np.asarray(box.center), np.asarray(box.size) / 2, np.asarray(box.rotation)
    s = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    V = c + (s * h) @ R.T
    idx = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]]
    return [[V[i] for i in f] for f in idx]


def plot_path_3d(result: FRMPResult, path: Path) -> Path:
    """Draw a 3D picture of the tool path among the obstacles.

    The tool path of the FRMP trajectory, the straight joint-space reference (grey), the waypoints
    and the obstacles.

    Args:
        result: The FRMP plan of a scene.
        path: PNG file to write.

    Returns:
        ``path``.
    """
    matplotlib.use("Agg")
    scene = result.scene
    robot = scene.robot
    dense = result.trajectory.resample(0.02)
    P = np.array([robot.fk(q)[:3, 3] for q in dense.q])
    ref_points: list[npt.NDArray[np.float64]] = []
    for a, b, N in zip(scene.waypoints[:-1], scene.waypoints[1:], scene.steps):
        for s in np.linspace(0, 1, 4 * N + 1):
            ref_points.append(robot.fk(a + s * (b - a))[:3, 3])
    ref = np.array(ref_points)
    fig = plt.figure(figsize=(8, 7))
    ax = fig.add_subplot(111, projection="3d")
    ax.plot(*ref.T, color="0.6", ls="--", lw=1, label="straight joint-space reference")
    ax.plot(*P.T, color="C0", lw=2, label="FRMP tool path")
    W = np.array([robot.fk(q)[:3, 3] for q in scene.waypoints])
    ax.scatter(*W.T, color="C3", s=30, depthshade=False)
    for name, w in zip(scene.waypoint_names, W):
        ax.text(*w, f" {name}", fontsize=8)
    for o in scene.obstacles:
        if isinstance(o, Box):
            ax.add_collection3d(Poly3DCollection(_box_faces(o), alpha=0.25, facecolor="C1", edgecolor="k", lw=0.4))
        elif isinstance(o, Sphere):
            u, v = np.mgrid[0:2 * np.pi:16j, 0:np.pi:8j]
            r, c = o.radius, o.center
            ax.plot_wireframe(c[0] + r * np.cos(u) * np.sin(v), c[1] + r * np.sin(u) * np.sin(v),
                              c[2] + r * np.cos(v), color="C1", lw=0.4)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    lo = np.minimum(P.min(0), ref.min(0)) - 0.1
    hi = np.maximum(P.max(0), ref.max(0)) + 0.1
    m = (hi - lo).max() / 2
    mid = (hi + lo) / 2
    ax.set_xlim(mid[0] - m, mid[0] + m)
    ax.set_ylim(mid[1] - m, mid[1] + m)
    ax.set_zlim(max(0.0, mid[2] - m), mid[2] + m)
    ax.view_init(elev=28, azim=-60)
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(f"{scene.name}: tool path, min clearance {result.check.min_clearance * 1000:.1f} mm "
                 f"(d_min {scene.d_min * 1000:.0f} mm)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plan_mbm(problems: Path | None, robot_urdf: Path | None, *, family: str | None = None, index: int | None = None,
             per_family: int | None = None, out: Path | None = None, time_budget_s: float = 1.0,
             d_min: float = DEFAULT_D_MIN, budget_clock: str = "wall",
             console: Console | None = None) -> list[MotionPlan]:
    """``robointel plan mbm PROBLEMS.json --urdf URDF``: plan the valid MBM problems start to goal.

    Each selected problem is read by :func:`robointel.io.mbm.load_mbm_problems`, planned by
    :func:`robointel.planning.plan_motion` (its success means the 1 ms dense check passed) and
    listed in a table. The SRDF (same stem as the URDF) and the sphere decomposition
    ``<stem>_spherized.urdf`` beside the URDF are used when present.

    Args:
        problems: the MBM ``problems.json``.
        robot_urdf: the robot's URDF.
        family: only this family (None: all).
        index: only the problem with this index.
        per_family: the first this many valid problems of each family.
        out: when given, each trajectory is saved as ``<out stem>_<family>_<index>.npz``.
        time_budget_s: search budget per problem, s.
        d_min: required clearance, m (``MotionSettings.d_min`` by default; the dense check accepts
            clearance >= d_min - 1 mm).
        budget_clock: ``"wall"`` or ``"cpu"``: the clock the budget is counted on
            (:attr:`robointel.planning.MotionSettings.budget_clock`).
        console: a rich console for the table and the progress bar.

    Returns:
        The :class:`robointel.planning.MotionPlan` of every problem, in order.

    Raises:
        typer.Exit: code 2 on bad input (message printed), code 1 when a problem failed.
    """
    console = console or Console()
    try:
        if problems is None or robot_urdf is None:
            raise InvalidInput("give the MBM problems.json and --urdf URDF")
        pset = load_mbm_problems(problems)
        selected = pset.select(families=[family] if family else None, index=index, per_family=per_family)
        if not selected:
            raise InvalidInput(f"{problems}: no valid problem matches family={family!r} index={index!r}",
                               value=(family, index))
        robot = Robot.load(robot_urdf)
        urdf = Path(robot_urdf)
        srdf = urdf.with_suffix(".srdf")
        spheres = urdf.with_name(f"{urdf.stem}_spherized.urdf")
        plans = []
        with Progress(console=console, transient=True) as bar:
            task = bar.add_task("planning", total=len(selected))
            for p in selected:
                env = Environment(robot, p.obstacles, srdf=srdf if srdf.exists() else None,
                                  spheres=spheres if spheres.exists() else None)
                plans.append(plan_motion(robot, env, p.start, p.goals,
                                         settings=MotionSettings(d_min=d_min, time_budget_s=time_budget_s,
                                                                 budget_clock=budget_clock)))
                bar.advance(task)
    except RobointelError as exc:
        fail(exc)
    t = Table(title=f"{problems}: {len(selected)} problems, robot {urdf.name}")
    for c in ("problem", "success", "plan (ms)", "duration (s)", "min clearance (mm)", "reason"):
        t.add_column(c, justify="right")
    for p, r in zip(selected, plans):
        dur = f"{r.trajectory.duration:.2f}" if r.trajectory is not None else "-"
        t.add_row(p.name, "yes" if r.success else "[red]no[/red]", f"{r.plan_ms:.1f}", dur,
                  f"{1e3 * r.min_clearance_m:.1f}", r.reason)
        if out is not None and r.trajectory is not None:
            out.parent.mkdir(parents=True, exist_ok=True)
            save_trajectory(r.trajectory, out.with_name(f"{out.stem}_{p.family}_{p.index}.npz"))
    console.print(t)
    ok = sum(r.success for r in plans)
    console.print(f"{ok}/{len(plans)} planned and passed the 1 ms dense check")
    if ok < len(plans):
        raise typer.Exit(1)
    return plans


class _PlanGroup(TyperGroup):
    """``robointel plan``: ``plan SCENE`` (no subcommand named) is ``plan scene SCENE``."""

    def resolve_command(self, ctx: Any, args: list[str]) -> Any:
        if args and args[0] not in self.commands and not args[0].startswith("-"):
            args = ["scene", *args]
        return super().resolve_command(ctx, args)


plan_app = typer.Typer(cls=_PlanGroup, no_args_is_help=True, help=(
    "Plan motions. scene: a scene's waypoints by CFS + temporal optimization (the FRMP, self-collision included); "
    "motion: start to goal for any URDF (plan_motion); mbm: MotionBenchMaker problems. Each reports the verdict "
    "--execute will give. `robointel plan SCENE` is `robointel plan scene SCENE`."))
"""The ``plan`` group (``plan motion`` is added by :mod:`robointel.commands.plan_motion`)."""
console = Console()


@plan_app.command("scene")
def plan_scene_cmd(scene: str = typer.Argument(..., help="scene YAML file, or a built-in scene name (table71)"),
                   out: Path = typer.Option(Path("traj.npz"), help="trajectory file (.npz or .json)"),
                   plots: bool = typer.Option(True, help="write <out>_profiles.png and <out>_path3d.png"),
                   execute: bool = typer.Option(False, "--execute", help="run the trajectory: in the MuJoCo workcell "
                                                "(--robot sim) or on the robot at --robot"),
                   robot: str = typer.Option("sim", help="with --execute: the robot URL: 'sim', 'sim?process=1' or "
                                             "'fanuc://HOST[:RMI_PORT][?sm_port=N]'"),
                   record: Path = typer.Option(None, help="with --execute: record the run as a ROS 2 bag (.mcap)"),
                   ) -> None:
    """Plan a scene's waypoints with the FRMP (CFS path with self-collision + temporal optimization).

    Prints the plan, its dense check and the verdict --execute will give; exit code 1 when --execute would
    refuse the trajectory.
    """
    try:
        sc = load_scene(scene)
        with console.status("planning"):
            res = plan_scene(sc)
        out.parent.mkdir(parents=True, exist_ok=True)
        save_trajectory(res.trajectory, out)
    except RobointelError as exc:
        fail(exc)
    t = Table(title=f"{sc.name}: {len(sc.steps)} segments, {sc.total_steps} steps, "
                    f"d_min {sc.d_min * 1000:.0f} mm")
    for c in ("segment", "blocked", "CFS [ms]", "iterations", "status", "min dist [mm]", "temporal [ms]",
              "time [s]"):
        t.add_column(c, justify="right")
    for i, (s, tr) in enumerate(zip(res.segments, res.temporal)):
        t.add_row(f"{sc.waypoint_names[i]} -> {sc.waypoint_names[i + 1]}", "yes" if s.blocked else "",
                  f"{res.cfs_ms[i]:.1f}", str(s.iterations), s.status, f"{s.min_distance * 1000:.1f}",
                  f"{res.temporal_ms[i]:.1f}", f"{tr.duration:.2f}")
    console.print(t)
    chk = res.check
    console.print(f"operational time {res.operational_time_fixed:.2f} s (fixed dt) -> "
                  f"[bold]{res.operational_time_frmp:.2f} s[/bold] (FRMP); 1 ms resample: min clearance "
                  f"{chk.min_clearance * 1000:.1f} mm, self-collision pairs {chk.min_self_clearance * 1000:.1f} mm "
                  f"apart, limit violations {chk.limit_violations}")
    if plots:
        stem = out.with_suffix("")
        a = plot_joint_profiles(res, Path(f"{stem}_profiles.png"))
        b = plot_path_3d(res, Path(f"{stem}_path3d.png"))
        console.print(f"plots: {a}, {b}")
    why = execute_verdict(sc.robot, sc.obstacles, res.trajectory)
    if execute:
        if why:
            fail(why)
        if robot != "sim" or record is not None:  # the robot interface
            try:
                wc = {"workcell": Workcell(sc.robot, obstacles=sc.obstacles)} if robot == "sim" else {}
                run_on_robot(res.trajectory, robot, record, console, sim_kwargs=wc)
            except RobointelError as exc:
                fail(exc)
        else:
            with console.status("tracking in MuJoCo"):
                ex = run_in_sim(res)
            console.print(f"MuJoCo: RMS tracking error {np.degrees(ex.rms_error_rad):.4f} deg, max "
                          f"{np.degrees(ex.max_error_rad):.4f} deg, TCP {ex.max_tcp_error_m * 1000:.2f} mm, "
                          f"obstacle contacts {ex.obstacle_contacts}")
            if ex.collided:
                typer.echo(f"error: the robot touched an obstacle in MuJoCo: {ex.outcome.detail}", err=True)
                raise typer.Exit(1)
    console.print(f"trajectory: [bold]{out}[/bold]")
    print_verdict(why)
    if why and not execute:
        raise typer.Exit(1)


def print_verdict(why: str) -> None:
    """Print the verdict of ``--execute`` on one line (stdout): accepted, or why it refuses."""
    if why:
        typer.echo(f"verdict: --execute refuses this trajectory: {why}")
    else:
        typer.echo("verdict: --execute accepts this trajectory (clear of the obstacles, the table and itself on a "
                   "10 ms resample; within the joint limits on the 8 ms controller resample)")


@plan_app.command("mbm")
def plan_mbm_cmd(problems: Path = typer.Argument(..., help="MotionBenchMaker problems.json"),
                 urdf: Path = typer.Option(None, "--urdf", help="the robot's URDF (SRDF beside it)"),
                 family: str = typer.Option(None, "--family", help="only this scene family"),
                 index: int = typer.Option(None, "--index", help="only the problem with this index"),
                 per_family: int = typer.Option(None, "--per-family", help="first N valid problems per family"),
                 time_budget: float = typer.Option(1.0, "--time-budget", help="search budget per problem, s"),
                 d_min: float = typer.Option(DEFAULT_D_MIN, "--d-min", help="clearance, m (the dense check allows "
                                             "d_min - 1 mm; the default is MotionSettings.d_min)"),
                 out: Path = typer.Option(None, help="save each trajectory as <out stem>_<family>_<index>.npz"),
                 budget_clock: str = typer.Option("wall", "--budget-clock", help="count the budget in wall time or "
                                                  "in the process's CPU time ('cpu')"),
                 ) -> None:
    """Plan MotionBenchMaker problems start to goal with plan_motion and check each on a 1 ms resample."""
    plan_mbm(problems, urdf, family=family, index=index, per_family=per_family, out=out, time_budget_s=time_budget,
             d_min=d_min, budget_clock=budget_clock, console=console)


def register(app: typer.Typer) -> None:
    """Add the ``plan`` group (``plan scene``, ``plan mbm``) to ``app``.

    Args:
        app: The top-level typer application.
    """
    app.add_typer(plan_app, name="plan")


def demo_stage(ctx: StageContext) -> StageResult:
    """Plan the Table 7.1 workcell with the FRMP, run it in MuJoCo, re-plan around a moving hand.

    Args:
        ctx: The demo stage context (output folder, quick flag, progress).

    Returns:
        The stage's figures, images and text.
    """
    ctx.advance(0.02, "loading the Table 7.1 scene")
    scene = load_scene("table71")
    planners = make_planners(scene)
    if not ctx.quick:
        plan_scene(scene, planners=planners)  # warm-up (compiled kernels, caches)
    reps = 1 if ctx.quick else 3
    runs = []
    for k in range(reps):
        ctx.advance(0.1 + 0.3 * k / reps, f"FRMP run {k + 1}/{reps}")
        for pl in planners.values():
            pl.reset_warm_start()
        runs.append(plan_scene(scene, planners=planners))
    res = runs[-1]
    cfs_ms = np.median([r.cfs_ms for r in runs], axis=0)
    tmp_ms = np.median([r.temporal_ms for r in runs], axis=0)
    ctx.advance(0.45, "plots")
    img1 = plot_joint_profiles(res, ctx.out / "frmp_profiles.png")
    img2 = plot_path_3d(res, ctx.out / "frmp_path3d.png")
    save_trajectory(res.trajectory, ctx.out / "table71_frmp.npz")
    ctx.advance(0.6, "tracking in MuJoCo")
    ex = run_in_sim(res)
    ctx.advance(0.8, "replanning around a moving hand")
    stop, s0 = np.array([0.62, 0.16, 0.30]), np.array([0.62, 0.16, 0.75])
    st = planner_settings(scene)
    st.max_iter = 10
    t0 = time.perf_counter()
    rp = receding_horizon(scene.robot, scene.obstacles, Sphere(s0, 0.06, name="hand"),
                          lambda t: s0 + (stop - s0) * min(1.0, t / 1.5), scene.waypoints[0], scene.waypoints[1],
                          N=scene.steps[0], dt=scene.dt, ticks=8 if ctx.quick else 20, settings=st,
                          vmax=scene.vmax, amax=scene.amax)
    del t0
    bl = [i for i, b in enumerate(res.blocked) if b]
    figs = []
    paper_cfs = ["0.894 s / 2 it", "0.840 s / 5 it"]
    for n_, i in enumerate(bl):
        figs.append(Figure(f"CFS, blocked segment {i + 1} ({scene.waypoint_names[i]} -> {scene.waypoint_names[i + 1]})",
                           f"{cfs_ms[i]:.1f} ms / {res.cfs_iterations[i]} it",
                           paper_cfs[n_] if n_ < 2 else None, "median, shared 2-core machine"))
    figs += [
        Figure("CFS, whole 95-step plan (5 segments)", f"{cfs_ms.sum():.1f} ms", None,
               "free segments converge in 1 iteration"),
        Figure("SQP on the blocked segments", "see benchmarks/frmp.py", "46.8 s / 94 it, 48.9 s / 96 it",
               "SLSQP takes seconds per segment: measured in the benchmark, not in the demo"),
        Figure("temporal optimization per segment (median)", f"{np.median(tmp_ms):.1f} ms "
               f"(max {tmp_ms.max():.1f} ms)", "31 ms", "CFS on the time steps, DAQP QPs"),
        Figure("operational time, fixed dt -> FRMP", f"{res.operational_time_fixed:.2f} s -> "
               f"{res.operational_time_frmp:.2f} s", "15.00 s -> 6.63 s",
               f"limits: {scene.vmax[0] / scene.robot.velocity_limit[0]:.0%} of joint speed"),
        Figure("min clearance on a 1 ms resample", f"{res.check.min_clearance * 1000:.1f} mm",
               None, f"d_min = {scene.d_min * 1000:.0f} mm"),
        Figure("limit violations on a 1 ms resample", str(res.check.limit_violations), None,
               "position, velocity, acceleration"),
        Figure("MuJoCo tracking error (RMS / max)", f"{np.degrees(ex.rms_error_rad):.4f} / "
               f"{np.degrees(ex.max_error_rad):.4f} deg", None, f"obstacle contacts: {ex.obstacle_contacts}"),
        Figure("replanning rate with a moving hand", f"{rp.hz:.0f} Hz", None,
               f"warm-started receding horizon, {int(rp.feasible.sum())}/{len(rp.feasible)} plans clear"),
    ]
    ctx.advance(1.0, "done")
    text = ("The FRMP plans the Table 7.1 workcell (six stop-by waypoints, 95 steps, two boxes blocking "
            "segments 3 and 4) by CFS per segment, re-times each segment by CFS temporal optimization, checks "
            "clearance and joint limits on a 1 ms resample and tracks the result in MuJoCo.")
    return StageResult(title="Planning (Ch. 7): CFS + temporal optimization (FRMP)", figures=figs,
                       images=[img1, img2], text=text)
