"""Run the demo stages with a progress bar each and write the HTML report."""
from __future__ import annotations

import base64
import html
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from robointel.errors import MissingExtra


@dataclass
class StageContext:
    """What a stage gets: its output folder, a progress callback and the quick flag."""

    out: Path
    quick: bool
    advance: Callable[[float, str], None]  # (fraction 0..1 done, status text)


@dataclass
class Figure:
    """One reported figure: ours beside the dissertation's (``paper`` may be None)."""

    name: str
    ours: str
    paper: str | None = None
    note: str = ""


@dataclass
class StageResult:
    """One stage of the demo report: its title, figures, images, text and run time (s)."""
    title: str
    figures: list[Figure] = field(default_factory=list)
    images: list[Path] = field(default_factory=list)
    text: str = ""
    seconds: float = 0.0
    error: str | None = None


Stage = Callable[[StageContext], StageResult]


def run_demo(stages: list[Stage], out: Path, *, quick: bool = False, console: Console | None = None) -> Path:
    """Run each stage (a rich progress bar per stage) and write ``out/index.html``.

    A stage that needs an extra which is not installed (:class:`~robointel.errors.MissingExtra`) is
    reported as skipped, with the command that installs it; the other stages run.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    console = console or Console()
    results: list[StageResult] = []
    with Progress(TextColumn("{task.description:<28}"), BarColumn(), TextColumn("{task.percentage:>3.0f}%"),
                  TextColumn("{task.fields[status]}"), TimeElapsedColumn(), console=console) as progress:
        for stage in stages:
            name = getattr(stage, "__module__", "stage").rsplit(".", 1)[-1]
            task = progress.add_task(name, total=1.0, status="")

            def advance(frac: float, status: str = "", _t: Any = task) -> None:
                progress.update(_t, completed=max(0.0, min(1.0, frac)), status=status)

            sub = out / name
            sub.mkdir(exist_ok=True)
            t0 = time.perf_counter()
            try:
                res = stage(StageContext(out=sub, quick=quick, advance=advance))
            except MissingExtra as exc:  # an optional part not installed: the other stages still run
                res = StageResult(title=name, error=f"skipped: {exc}")
            res.seconds = time.perf_counter() - t0
            progress.update(task, completed=1.0, status="skipped" if res.error and res.error.startswith("skipped")
                            else f"{res.seconds:.1f} s")
            results.append(res)
    return write_report(results, out)


def _img(path: Path) -> str:
    data = base64.b64encode(Path(path).read_bytes()).decode()
    return f'<img src="data:image/png;base64,{data}" alt="{html.escape(Path(path).name)}">'


def write_report(results: list[StageResult], out: Path) -> Path:
    """A self-contained HTML file (images inlined) with each stage's figures beside the paper's."""
    parts = ["<!doctype html><html><head><meta charset='utf-8'><title>robointel report</title><style>",
             "body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;color:#222}",
             "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:4px 10px}",
             "th{background:#f0f0f0}img{max-width:100%;margin:.5em 0;border:1px solid #ddd}",
             ".err{color:#b00}</style></head><body><h1>robointel report</h1>",
             "<p>Each stage ran on the built-in simulated workcell (FANUC LR Mate 200iD/7L in MuJoCo). "
             "Figures are measured in this run and shown beside the dissertation's (Lin, 2018).</p>"]
    for r in results:
        parts.append(f"<h2>{html.escape(r.title)}</h2><p>{r.seconds:.1f} s</p>")
        if r.error:
            parts.append(f"<p class='err'>{html.escape(r.error)}</p>")
        if r.text:
            parts.append(f"<p>{html.escape(r.text)}</p>")
        if r.figures:
            parts.append("<table><tr><th>figure</th><th>robointel (this run)</th><th>dissertation</th>"
                         "<th>note</th></tr>")
            for f in r.figures:
                parts.append(f"<tr><td>{html.escape(f.name)}</td><td>{html.escape(f.ours)}</td>"
                             f"<td>{html.escape(f.paper or '-')}</td><td>{html.escape(f.note)}</td></tr>")
            parts.append("</table>")
        parts.extend(_img(p) for p in r.images if Path(p).exists())
    parts.append("</body></html>")
    index = out / "index.html"
    index.write_text("\n".join(parts))
    return index
