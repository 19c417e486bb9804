"""Task-program commands: ``robointel run PROGRAM.yaml`` (check, then run step by step) and the demo stage."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from robointel.errors import InvalidInput, RobointelError
from robointel.program import GraspCell, ProgramRejected, SimCell, check_program, load_program, run_program
from robointel.report.demo import Figure, StageContext, StageResult
from robointel.report.program import plot_run, write_program_report

console = Console()


def run(program: str = typer.Argument(..., help="program YAML file, or a built-in program: example, pick_place"),
        robot: str = typer.Option("sim", "--robot", help="'sim' (the MuJoCo workcell)"),
        start: str = typer.Option("0", "--from", help="first step to run (index or name)"),
        report: Path = typer.Option(Path("robointel-program-report"), help="report folder"),
        seed: int = typer.Option(0, help="seed of the simulated cell (object placements, sensor noise)"),
        check_only: bool = typer.Option(False, "--check", help="only check the program, do not run it")) -> None:
    """Check a task program as a whole, then run it step by step and write an HTML report."""
    try:
        if robot != "sim":
            raise InvalidInput(f"--robot {robot!r}: this version runs programs on 'sim' only", value=robot)
        prog = load_program(program)
        i0 = prog.index(start)
        cell_q = prog.initial_configuration(i0)
        with Progress(TextColumn("{task.description:<32}"), BarColumn(), TextColumn("{task.fields[status]}"),
                      TimeElapsedColumn(), console=console) as bar:
            task = bar.add_task("check", total=1.0, status="")
            chk = check_program(prog, cell_q, start=i0,
                                progress=lambda f, s: bar.update(task, completed=f, status=s))
            bar.update(task, completed=1.0, status=f"{chk.check_ms:.0f} ms")
            if check_only:
                console.print(f"program {prog.name!r}: {len(prog.steps) - i0} steps checked in {chk.check_ms:.0f} ms")
                return
            task2 = bar.add_task("run", total=len(prog.steps) - i0, status="")
            cell = GraspCell(prog, cell_q, seed=seed) if prog.objects else SimCell(prog, cell_q)
            res = run_program(prog, cell, start=i0, check=chk,
                              progress=lambda i, s: bar.update(task2, completed=i - i0, status=s))
            bar.update(task2, completed=len(res.steps), status="done" if res.success else "failed")
    except ProgramRejected as exc:
        console.print(f"[red]refused before moving:[/red] {exc}")
        raise typer.Exit(2) from None
    except RobointelError as exc:
        console.print(f"[red]error:[/red] {exc}")
        raise typer.Exit(2) from None
    index = write_program_report(prog, res, report)
    for r in res.steps:
        mark = "ok" if r.outcome.success else f"[red]{r.outcome.reason.value}[/red] {r.outcome.detail}"
        console.print(f"{r.index:>3} {r.name:<24} {r.kind:<7} {r.seconds * 1e3:8.1f} ms  {mark}")
    console.print(f"report: [bold]{index}[/bold]")
    if not res.success:
        console.print(f"[red]step {res.failed_step} ({res.steps[-1].name!r}) failed:[/red] {res.outcome.detail}; "
                      "the robot holds where it stopped")
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    """Add ``robointel run`` to the CLI."""
    app.command("run")(run)


def demo_stage(ctx: StageContext) -> StageResult:
    """The built-in example program on the simulated cell: checked, then run; its joint plot."""
    prog = load_program("example")
    q0 = prog.initial_configuration()
    ctx.advance(0.05, "check")
    chk = check_program(prog, q0, progress=lambda f, s: ctx.advance(0.05 + 0.6 * f, s))
    ctx.advance(0.7, "run")
    res = run_program(prog, SimCell(prog, q0), check=chk)
    png = plot_run(prog, res, ctx.out / "program_joints.png")
    motion = sum(p.trajectory.duration for p in chk.plans if p.trajectory is not None)
    figs = [Figure("task program", f"{len(res.steps)} steps, {'all ok' if res.success else res.outcome.detail}"),
            Figure("pre-run check (plan + dense check of every motion)", f"{chk.check_ms:.0f} ms"),
            Figure("motion time", f"{motion:.2f} s")]
    return StageResult("Task program (move, path, wait, set_io on the Table 7.1 cell)", figs, [png],
                       text="robointel run example: the whole program is checked before the robot moves.")
