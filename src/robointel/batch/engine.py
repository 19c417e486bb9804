"""Run a sweep: skip what the store holds, run the rest in-process or on Ray, store rows as they finish.

The in-process engine runs the tasks one after another in this process (the default, and what CI
and ``make demo`` use). The Ray engine (:mod:`robointel.batch.ray_engine`, ``pip install
robointel[batch]``) runs them as Ray tasks on a local Ray it starts or on a cluster it joins. Both
call the same :func:`robointel.batch.execute.execute`, so they give the same outcome for the same
spec and seed.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rich.console import Console

from robointel._extras import needs_extra
from robointel.batch.execute import Fault, execute
from robointel.batch.progress import BatchProgress, Counts
from robointel.batch.registry import get_kind
from robointel.batch.spec import TaskSpec, unique
from robointel.batch.store import ResultStore
from robointel.errors import EngineUnavailable, InvalidInput, MissingExtra

__all__ = ["ENGINES", "BatchRun", "run_batch"]

ENGINES = ("inprocess", "ray")
RowCallback = Callable[[dict[str, Any]], None]


@dataclass(frozen=True)
class BatchRun:
    """What one call of :func:`run_batch` did.

    Attributes:
        counts: Final task counts (``skipped``: already stored at the start).
        wall_s: Wall-clock time of the run (s), store opening to last flush.
        engine: ``"inprocess"`` or ``"ray"``.
        workers: Worker processes (1 in-process).
        store: The result folder.
    """

    counts: Counts
    wall_s: float
    engine: str
    workers: int
    store: Path

    @property
    def throughput(self) -> float:
        """Tasks finished per second in this run."""
        return self.counts.done / self.wall_s if self.wall_s > 0 else 0.0


class _Sink:
    """Adds rows to the store, flushing every ``flush_rows`` rows or ``flush_s`` seconds, and counts."""

    def __init__(self, store: ResultStore, counts: Counts, bar: BatchProgress, flush_rows: int, flush_s: float,
                 on_row: RowCallback | None) -> None:
        self.store, self.counts, self.bar = store, counts, bar
        self.flush_rows, self.flush_s, self.on_row = flush_rows, flush_s, on_row
        self._last = time.monotonic()

    def __call__(self, row: dict[str, Any]) -> None:
        if self.store.add(row):
            self.counts.done += 1
            if not row["success"]:
                self.counts.failed += 1
            if row["reason"] in ("error", "fault"):
                self.counts.errors += 1
        if self.store.pending >= self.flush_rows or time.monotonic() - self._last >= self.flush_s:
            self.flush()
        self.bar.update()
        if self.on_row is not None:
            self.on_row(row)

    def flush(self) -> None:
        self.store.flush()
        self._last = time.monotonic()

    def running(self, n: int) -> None:
        self.counts.running = n
        self.bar.update()


def run_batch(specs: Sequence[TaskSpec], results: str | Path, *, engine: str = "inprocess", workers: int = 1,
              address: str | None = None, cpus_per_task: float = 1.0, max_retries: int = 3, flush_rows: int = 8,
              flush_s: float = 2.0, progress: bool = True, console: Console | None = None,
              on_row: RowCallback | None = None, fault: Fault | None = None, timeout_s: float | None = None,
              worker_niceness: int = 0) -> BatchRun:
    """Run every spec not yet in the result store ``results`` and store one row per (spec hash, seed).

    Interrupting (Ctrl-C, or ``on_row`` raising) flushes what finished and re-raises; running the
    same sweep again resumes: stored keys are skipped.

    Args:
        specs: The tasks (a repeated key runs once).
        results: The Parquet dataset folder (created if missing).
        engine: ``"inprocess"`` or ``"ray"``.
        workers: Ray: CPUs of the local Ray it starts (ignored with ``address``).
        address: Ray: join this cluster (``ray://HOST:PORT`` or ``auto``) instead of starting one.
        cpus_per_task: Ray: CPUs reserved per task.
        max_retries: Ray: re-runs of a task whose worker died.
        flush_rows: Flush after this many new rows.
        flush_s: ... or this many seconds since the last flush.
        progress: Draw the rich progress bar.
        console: Console of the bar.
        on_row: Called with each finished row after it is stored (may raise to stop the run).
        fault: Ray only: kill the worker of chosen tasks once (tests, benchmark).
        timeout_s: Time budget per task (s): a trial still running after it is interrupted and stored
            as a ``timeout`` failure (both engines). ``None``: no budget.
        worker_niceness: Ray, local cluster only: the scheduling niceness of the worker processes
            (Ray's own default is 15, which lets any other process on the machine slow the trials).

    Returns:
        The counts and timing of this run.

    Raises:
        InvalidInput: unknown engine, or bad numbers of workers, CPUs or retries.
        UnknownTaskKind: a spec names a kind that is not registered.
        EngineUnavailable: Ray is not installed or the cluster cannot be joined.
    """
    if engine not in ENGINES:
        raise InvalidInput(f"engine must be one of {ENGINES}, got {engine!r}", value=engine)
    if timeout_s is not None and not timeout_s > 0:
        raise InvalidInput(f"timeout_s must be > 0 seconds, got {timeout_s!r}", value=timeout_s)
    if workers < 1 or cpus_per_task <= 0 or max_retries < 0 or flush_rows < 1:
        raise InvalidInput("workers >= 1, cpus_per_task > 0, max_retries >= 0 and flush_rows >= 1 are required",
                           value={"workers": workers, "cpus_per_task": cpus_per_task, "max_retries": max_retries,
                                  "flush_rows": flush_rows})
    if fault is not None and engine != "ray":
        raise InvalidInput("fault injection kills a worker process: use it with the Ray engine only", value=fault)
    for kind in sorted({s.kind for s in specs}):
        get_kind(kind)  # an unknown kind fails here, before anything runs
    t0 = time.perf_counter()
    store = ResultStore(results)
    specs = unique(specs)
    todo = [s for s in specs if s.key not in store]
    counts = Counts(total=len(specs), skipped=len(specs) - len(todo))
    n_workers = workers if engine == "ray" else 1
    with BatchProgress(counts, f"{engine} x{n_workers}" if address is None else f"ray {address}",
                       enabled=progress, console=console) as bar:
        sink = _Sink(store, counts, bar, flush_rows, flush_s, on_row)
        try:
            if engine == "inprocess":
                for s in todo:
                    sink.running(1)
                    sink(execute(s.to_dict(), engine="inprocess", timeout_s=timeout_s))
                sink.running(0)
            else:
                try:  # the optional dependency (robointel[batch]) loads only here
                    with needs_extra("batch", "the Ray engine"):
                        from robointel.batch.ray_engine import run_on_ray
                except MissingExtra as exc:
                    raise EngineUnavailable(str(exc), value=engine) from None
                run_on_ray(todo, sink, sink.running, workers=workers, address=address, cpus_per_task=cpus_per_task,
                           max_retries=max_retries, fault=fault, timeout_s=timeout_s, worker_niceness=worker_niceness)
        finally:
            sink.flush()
    return BatchRun(counts, time.perf_counter() - t0, engine, n_workers, store.root)
