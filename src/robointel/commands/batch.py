"""Batch evaluation: ``robointel batch run|report|kinds``.

``run SPEC.yaml`` runs a sweep in-process (default), on a local Ray (``--workers N``, N > 1) or on a
cluster (``--address ray://HOST:PORT``), streaming rows into a resumable Parquet dataset;
``report RESULTS/`` prints success rates with Wilson intervals per kind and category and writes a plot.
Each command imports :mod:`robointel.batch` when it runs (its Parquet store needs the ``batch`` extra).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from robointel.commands.failure import fail
from robointel.errors import RobointelError

console = Console()
batch_app = typer.Typer(no_args_is_help=True, help="Trials as tasks, in-process or on Ray, with a resumable store.")


@batch_app.command("run")
def run(spec: Annotated[Path, typer.Argument(help="sweep YAML (tasks: [{kind, seeds, params, grid, category}])")],
        out: Annotated[Path | None, typer.Option("--out", "-o",
                                                 help="result folder (default: SPEC's name + '-results')")] = None,
        workers: Annotated[int, typer.Option(help="> 1: start a local Ray with this many CPUs")] = 1,
        address: Annotated[str | None, typer.Option(help="join a Ray cluster (ray://HOST:PORT or 'auto')")] = None,
        engine: Annotated[str | None, typer.Option(
            help="'inprocess' or 'ray' (default: ray when --workers > 1 or --address)")] = None,
        cpus_per_task: Annotated[float, typer.Option(help="Ray: CPUs reserved per task")] = 1.0,
        max_retries: Annotated[int, typer.Option(help="Ray: re-runs of a task whose worker died")] = 3,
        flush_rows: Annotated[int, typer.Option(help="write a Parquet file every this many rows (or 2 s)")] = 8,
        timeout: Annotated[float | None, typer.Option(
            help="time budget per task, s: a trial past it is stored as a 'timeout' failure")] = None,
        worker_niceness: Annotated[int, typer.Option(
            help="local Ray: niceness of the worker processes (Ray's own default is 15)")] = 0,
        ) -> None:
    """Run a sweep; already stored (spec hash, seed) rows are skipped, so running it again resumes."""
    try:
        from robointel.batch import load_sweep, run_batch

        specs = load_sweep(spec)
        eng = engine or ("ray" if workers > 1 or address else "inprocess")
        folder = out or spec.with_name(spec.stem + "-results")
        r = run_batch(specs, folder, engine=eng, workers=workers, address=address, cpus_per_task=cpus_per_task,
                      max_retries=max_retries, flush_rows=flush_rows, console=console, timeout_s=timeout,
                      worker_niceness=worker_niceness)
    except RobointelError as exc:
        fail(exc)
    except KeyboardInterrupt:
        console.print("[yellow]interrupted[/yellow]: finished rows are stored; run the same command to resume")
        raise typer.Exit(130) from None
    c = r.counts
    console.print(f"{c.done} run ({c.failed} failed, {c.errors} errors), {c.skipped} already stored, "
                  f"{r.wall_s:.1f} s, {r.throughput:.2f} tasks/s -> [bold]{r.store}[/bold]")


@batch_app.command("report")
def report(results: Annotated[Path, typer.Argument(help="result folder")],
           plot: Annotated[Path | None, typer.Option(help="plot file (default: RESULTS/success.png)")] = None,
           confidence: Annotated[float, typer.Option(help="confidence level of the Wilson intervals")] = 0.95,
           ) -> None:
    """Success rates with Wilson confidence intervals per kind and category, and a plot."""
    try:
        from robointel.batch import plot_summary, summarize

        if not results.is_dir():
            raise typer.BadParameter(f"{results} is not a result folder")
        groups = summarize(results, confidence)
        t = Table(title=f"{results}: success rates ({100 * confidence:.0f}% Wilson intervals)")
        for c in ("kind", "category", "success", "rate", "interval", "failures", "median task [s]"):
            t.add_column(c, justify="right")
        for g in groups:
            why = ", ".join(f"{k} {v}" for k, v in g.reasons.items()) or "-"
            t.add_row(g.kind, g.category, f"{g.successes}/{g.trials}", f"{100 * g.rate:.1f}%",
                      f"{100 * g.low:.1f}-{100 * g.high:.1f}%", why, f"{g.median_wall_s:.2f}")
        console.print(t)
        path = plot_summary(groups, plot or results / "success.png")
    except RobointelError as exc:
        fail(exc)
    console.print(f"plot: [bold]{path}[/bold]")


@batch_app.command("kinds")
def list_kinds() -> None:
    """List the trial kinds a sweep can use."""
    from robointel.batch import kinds

    t = Table(title="trial kinds")
    t.add_column("kind")
    t.add_column("trial")
    for name, k in kinds().items():
        t.add_row(name, k.summary)
    console.print(t)


def register(app: typer.Typer) -> None:
    """Add ``robointel batch`` to the main command."""
    app.add_typer(batch_app, name="batch")
