"""Task-program commands: ``robointel run PROGRAM.yaml`` (check, then run step by step) and the demo stage."""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np
import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from robointel.commands.failure import fail
from robointel.errors import InvalidInput, RobointelError
from robointel.interface import open_robot
from robointel.interface.open import parse_robot_url
from robointel.io.mcap_log import McapRecorder
from robointel.program import Cell, GraspCell, ProgramRejected, SimCell, check_program, load_program, run_program
from robointel.program.format import builtin_programs
from robointel.program.interface_cell import InterfaceCell, interface_refusal, output_refusal
from robointel.program.teaching import program_from_teleop
from robointel.report.demo import Figure, StageContext, StageResult
from robointel.report.program import StepRecorder, plot_run, write_program_report

console = Console()


def run(program: str = typer.Argument(..., help="program YAML file (format: docs/guides/programs.md), or a built-in "
                                     f"program: {', '.join(builtin_programs())}"),
        robot: str = typer.Option("sim", "--robot", help="'sim' (the simulated cell), 'sim?process=1' or fanuc://HOST[:PORT][?sm_port=N]"),
        start: str = typer.Option("0", "--from", help="first step to run (index or name)"),
        record: Path = typer.Option(None, "--record", help="record the run as a ROS 2 bag (.mcap)"),
        report: Path = typer.Option(Path("robointel-program-report"), help="report folder"),
        seed: int = typer.Option(0, help="seed of the simulated cell (object placements, sensor noise)"),
        check_only: bool = typer.Option(False, "--check", help="only check the program, do not run it")) -> None:
    """Check a task program as a whole, then run it step by step and write an HTML report.

    The pre-run check plans every motion and refuses a program that cannot run (a target out of reach or in
    collision, a part off the table or inside a fixture, a missing skill file), naming the step and the key,
    before anything moves. Every argument is checked before the robot is connected or a file is created.
    ``--record`` writes the run as it goes; Ctrl-C stops the robot where it is, closes the recording with
    everything so far and writes the report of the steps run (exit code 130).
    """
    rec = None
    try:
        prog = load_program(program)
        i0 = prog.index(start)
        if robot != "sim":
            parse_robot_url(robot)
        if report.exists() and not report.is_dir():
            raise InvalidInput(f"--report {report} exists and is not a folder", value=str(report))
        if record is not None:
            rec = McapRecorder(record, list(prog.robot.joint_names))  # checks the path; the file comes later
        with contextlib.ExitStack() as stack:
            if robot == "sim":
                cell_q = prog.initial_configuration(i0)
                arm = None
            else:
                interface_refusal(prog, i0)
                arm = stack.enter_context(open_robot(robot, recorder=rec))
                output_refusal(prog, arm, i0)
                cell_q = np.asarray(arm.state().q, float)
            with Progress(TextColumn("{task.description:<32}"), BarColumn(), TextColumn("{task.fields[status]}"),
                          TimeElapsedColumn(), console=console) as bar:
                task = bar.add_task("check", total=1.0, status="")
                chk = check_program(prog, cell_q, start=i0,
                                    progress=lambda f, s: bar.update(task, completed=f, status=s))
                bar.update(task, completed=1.0, status=f"{chk.check_ms:.0f} ms")
                if check_only:
                    console.print(f"program {prog.name!r}: {len(prog.steps) - i0} steps checked in "
                                  f"{chk.check_ms:.0f} ms")
                    return
                task2 = bar.add_task("run", total=len(prog.steps) - i0, status="")
                cell: Cell
                if arm is not None:
                    cell = InterfaceCell(arm)
                elif prog.objects:
                    cell = GraspCell(prog, cell_q, seed=seed)
                else:
                    cell = SimCell(prog, cell_q, seed=seed)
                if rec is not None:
                    rec.start()  # the file exists from the first step on
                live = StepRecorder(rec, chk) if rec is not None and arm is None else None  # sim: step by step
                res = run_program(prog, cell, start=i0, check=chk, on_step=live,
                                  progress=lambda i, s: bar.update(task2, completed=i - i0, status=s))
                bar.update(task2, completed=len(res.steps), status="done" if res.success else "failed")
    except KeyboardInterrupt:  # before any step ran (loading, connecting, the check): nothing moved
        console.print("[red]interrupted before the run started[/red]: nothing moved")
        raise typer.Exit(130) from None
    except ProgramRejected as exc:
        typer.echo("refused before moving: " + " ".join(str(exc).split()), err=True)
        raise typer.Exit(2) from None
    except RobointelError as exc:
        fail(exc)
    finally:
        if rec is not None:
            rec.close()
    index = write_program_report(prog, res, report)
    for r in res.steps:
        mark = "ok" if r.outcome.success else f"[red]{r.outcome.reason.value}[/red] {r.outcome.detail}"
        console.print(f"{r.index:>3} {r.name:<24} {r.kind:<7} {r.seconds * 1e3:8.1f} ms  {mark}")
    console.print(f"report: [bold]{index}[/bold]" + (f"; recorded: [bold]{record}[/bold]" if record else ""))
    if res.interrupted:
        console.print(f"[red]interrupted at step {res.failed_step} ({res.steps[-1].name!r})[/red]: the robot holds "
                      "where it stopped")
        raise typer.Exit(130)
    if not res.success:
        console.print(f"[red]step {res.failed_step} ({res.steps[-1].name!r}) failed:[/red] {res.outcome.detail}; "
                      "the robot holds where it stopped")
        raise typer.Exit(1)


def from_teleop(teleop: Path = typer.Argument(..., help="the program file the teleoperation page saved"),
                out: Path = typer.Argument(..., help="the task program (YAML) to write"),
                name: str = typer.Option(None, help="program name (default: the file's stem)")) -> None:
    """Turn a teleoperated program (recorded waypoints) into a task program: one move step per waypoint."""
    try:
        prog = program_from_teleop(teleop, name=name)
    except RobointelError as exc:
        fail(exc)
    prog.save(out)
    console.print(f"wrote {out}: {len(prog.steps)} move steps over {len(prog.waypoints)} waypoints; "
                  f"run it with `robointel run {out}`")


def register(app: typer.Typer) -> None:
    """Add ``robointel run`` and ``robointel program-from-teleop`` to the CLI."""
    app.command("run")(run)
    app.command("program-from-teleop")(from_teleop)


def demo_stage(ctx: StageContext) -> StageResult:
    """Run the demo's task-program stage: the ``moves`` program and the example cell (with its insertion).

    Args:
        ctx: The demo stage context (output folder, quick flag, progress).

    Returns:
        The stage's figures (steps, pre-run check time, motion time, the example's outcome, its insertion)
        and plots.
    """
    prog = load_program("moves")
    q0 = prog.initial_configuration()
    ctx.advance(0.05, "check")
    chk = check_program(prog, q0, progress=lambda f, s: ctx.advance(0.05 + 0.2 * f, s))
    ctx.advance(0.25, "run")
    res = run_program(prog, SimCell(prog, q0), check=chk)
    png = plot_run(prog, res, ctx.out / "program_joints.png")
    motion = sum(p.trajectory.duration for p in chk.plans if p.trajectory is not None)
    figs = [Figure("task program 'moves' (move, path, wait, set_io; Table 7.1 cell)",
                   f"{len(res.steps)} steps, {'all ok' if res.success else res.outcome.detail}"),
            Figure("pre-run check (plan + dense check of every motion)", f"{chk.check_ms:.0f} ms"),
            Figure("motion time", f"{motion:.2f} s")]
    ctx.advance(0.3, "example cell")
    pp = load_program("example")
    q1 = pp.initial_configuration()
    cell = GraspCell(pp, q1, seed=3)
    t_sim = float(cell.data.time)
    run = run_program(pp, cell, progress=lambda i, s: ctx.advance(0.3 + 0.65 * i / len(pp.steps), s))
    images = [png, plot_run(pp, run, ctx.out / "example_joints.png")]
    by_name = {r.name: r for r in run.steps}
    placed = by_name.get("place_part")
    place = placed.outcome.figures.get("place_error_m") if placed is not None else None
    ins = by_name.get("insert_peg")
    figs += [Figure("task program 'example' (perceive, grasp, carry around fixtures, place, home, insert)",
                    "all steps ok" if run.success else run.outcome.detail,
                    note=f"part placed {place * 1000:.1f} mm from its target" if place is not None else ""),
             Figure("pick-and-place cycle (simulated time)", f"{float(cell.data.time) - t_sim:.1f} s")]
    if ins is not None:
        f = ins.outcome.figures
        figs.append(Figure("insertion with the learned skill (0.1 mm fit, +-0.5 mm, <= 0.25 deg)",
                           f"{'seated' if ins.outcome.success else ins.outcome.reason.value} in "
                           f"{f.get('time_s', 0.0):.1f} s", note=f"start tilt {f.get('start_tilt_deg', 0.0):.2f} deg, "
                           f"lateral {f.get('start_lateral_mm', 0.0):.2f} mm, peak force "
                           f"{f.get('max_force_n', 0.0):.0f} N"))
    return StageResult("Task programs (robointel run)", figs, images,
                       text="robointel run moves / example: the whole program is checked before the robot "
                            "moves; a failed step stops the robot and is named.")
