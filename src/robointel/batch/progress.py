"""Progress of a batch: counts of done, failed and running tasks, with a rich bar and an ETA."""

from __future__ import annotations

from dataclasses import dataclass
from types import TracebackType

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

__all__ = ["BatchProgress", "Counts"]


@dataclass
class Counts:
    """Task counts of one batch run.

    Attributes:
        total: Tasks of the sweep.
        skipped: Already in the store when the run started (resume).
        done: Finished in this run (successes and failures).
        failed: Finished in this run without success (trial failures and errors).
        errors: Finished with an exception or a dead worker (``error``/``fault`` rows).
        running: Submitted and not finished.
    """

    total: int = 0
    skipped: int = 0
    done: int = 0
    failed: int = 0
    errors: int = 0
    running: int = 0


class BatchProgress:
    """A rich progress bar over a batch (a no-op when ``enabled`` is False).

    Args:
        counts: The counts it shows (updated by the engine).
        description: Label of the bar.
        enabled: Draw the bar.
        console: Where to draw (default: a new stderr console).
    """

    def __init__(self, counts: Counts, description: str = "batch", *, enabled: bool = True,
                 console: Console | None = None) -> None:
        self.counts = counts
        self.enabled = enabled
        self._progress = Progress(
            TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
            TextColumn("[green]done {task.fields[done]}[/] [red]failed {task.fields[failed]}[/] "
                       "[cyan]running {task.fields[running]}[/] [dim]skipped {task.fields[skipped]}[/]"),
            TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(),
            console=console or Console(stderr=True), disable=not enabled, transient=False)
        self._task: TaskID | None = None
        self._description = description

    def __enter__(self) -> BatchProgress:
        self._progress.__enter__()
        c = self.counts
        self._task = self._progress.add_task(self._description, total=c.total - c.skipped, done=0, failed=0,
                                             running=0, skipped=c.skipped)
        return self

    def update(self) -> None:
        """Redraw from :attr:`counts`."""
        if self._task is None:
            return
        c = self.counts
        self._progress.update(self._task, completed=c.done, done=c.done, failed=c.failed, running=c.running,
                              skipped=c.skipped)

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.update()
        self._progress.__exit__(exc_type, exc, tb)
