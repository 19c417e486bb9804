"""Run one task in the current process and turn whatever happens into one result row.

:func:`execute` is what both engines call (in the driver, or inside a Ray worker). It pins the
numerical libraries to one thread (BLAS/OpenMP through threadpoolctl, numba; MuJoCo steps on the
calling thread), runs the kind's pure trial function and returns a flat row: the spec, the
:class:`TrialOutcome` record, and where and how long it ran. A trial that raises becomes a failed
row (``Failure.ERROR``, or the matching reason for robointel errors) with the traceback kept.
"""

from __future__ import annotations

import os
import signal
import socket
import threading
import time
import traceback
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numba
from threadpoolctl import ThreadpoolController

from robointel.batch.registry import get_kind
from robointel.batch.spec import TaskSpec
from robointel.errors import CollisionAtStart, IKFailure, InfeasibleProblem, LimitViolation, SafetyStop
from robointel.outcome import Failure, TrialOutcome

__all__ = ["THREAD_ENV", "Fault", "TaskTimeout", "execute", "failure_row"]

#: Environment of a worker process: one thread for every numerical library (set before they load).
THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
              "NUMBA_NUM_THREADS": "1", "VECLIB_MAXIMUM_THREADS": "1"}

_CONTROLLERS: dict[str, ThreadpoolController] = {}  # per kind: the thread pools loaded once its module is


def _pools(kind: str) -> ThreadpoolController:
    """The BLAS/OpenMP thread pools of this process after ``kind``'s module loaded (inspected once)."""
    if kind not in _CONTROLLERS:
        _CONTROLLERS[kind] = ThreadpoolController()
    return _CONTROLLERS[kind]


_ERRORS = ((CollisionAtStart, Failure.COLLISION), (InfeasibleProblem, Failure.INFEASIBLE),
           (IKFailure, Failure.IK), (LimitViolation, Failure.LIMIT), (SafetyStop, Failure.FAULT))


@dataclass(frozen=True)
class Fault:
    """Fault injection for tests and the benchmark: kill a worker once.

    The worker running one of ``keys`` is killed (SIGKILL) ``after_s`` seconds into its first
    attempt; the attempt is remembered by a marker file in ``marker_dir``
    (shared by all workers of this machine), so the retry runs normally.

    Attributes:
        keys: ``"spec_hash:seed"`` of the tasks whose worker dies.
        marker_dir: Folder for the first-attempt markers.
        after_s: Seconds into the trial (s).
    """

    keys: tuple[str, ...]
    marker_dir: str
    after_s: float = 0.2

    def arm(self, spec: TaskSpec) -> threading.Timer | None:
        """Start the kill timer if ``spec`` is a target on its first attempt; return the timer."""
        key = f"{spec.spec_hash}:{spec.seed}"
        if key not in self.keys:
            return None
        marker = Path(self.marker_dir) / key.replace(":", "_")
        try:
            fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            return None  # a retry: run normally
        os.write(fd, str(os.getpid()).encode())
        os.close(fd)
        timer = threading.Timer(self.after_s, os.kill, (os.getpid(), signal.SIGKILL))
        timer.daemon = True
        timer.start()
        return timer


def _base(spec: TaskSpec, category: str) -> dict[str, Any]:
    return {"spec_hash": spec.spec_hash, "seed": spec.seed, "kind": spec.kind, "category": category,
            "spec": spec.to_dict()}


def failure_row(spec: TaskSpec, reason: Failure, detail: str, tb: str = "", *, engine: str = "") -> dict[str, Any]:
    """A failed row for a task that produced no outcome (e.g. its worker died on every attempt)."""
    try:
        category = spec.category or get_kind(spec.kind).category(spec)
    except Exception:  # an unknown kind still gets its row
        category = spec.category or spec.kind
    row = _base(spec, category)
    row.update(TrialOutcome(False, reason, detail).to_record())
    row.update({"traceback": tb, "worker": "", "engine": engine, "wall_s": 0.0, "cpu_s": 0.0,
                "finished_at": datetime.now(UTC)})
    return row


class TaskTimeout(Exception):  # noqa: N818 - raised by the alarm, recorded as Failure.TIMEOUT
    """The task ran past its time budget (raised inside the trial by the interval timer)."""


def _on_alarm(signum: int, frame: object) -> None:
    raise TaskTimeout


@contextmanager
def _deadline(timeout_s: float | None) -> Iterator[None]:
    """Raise :class:`TaskTimeout` in this (main) thread once ``timeout_s`` seconds have passed.

    The timer is the process's real-time interval timer (``SIGALRM``): a trial stuck in Python code,
    or in a C call that returns (a MuJoCo step, a solver iteration), is interrupted at the next
    bytecode. Off the main thread (no signals there) the budget is not enforced.
    """
    if timeout_s is None or threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGALRM, _on_alarm)
    signal.setitimer(signal.ITIMER_REAL, timeout_s)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)


def execute(spec_dict: dict[str, Any], fault: Fault | None = None, engine: str = "inprocess",
            timeout_s: float | None = None) -> dict[str, Any]:
    """Run one task (a :meth:`TaskSpec.to_dict`) with one thread per numerical library.

    Args:
        spec_dict: The task spec as plain data.
        fault: Optional fault injection (tests and benchmarks only).
        engine: Name recorded in the row.
        timeout_s: Time budget of the trial (s); past it the trial is interrupted and the row is a
            ``Failure.TIMEOUT`` failure. ``None``: no budget. Enforced when the task runs on the
            process's main thread (the in-process engine's driver, a Ray worker).

    Returns:
        The result row: ``spec_hash``, ``seed``, ``kind``, ``category``, ``spec``, the outcome record
        (``success``, ``reason``, ``detail``, ``figures``, ``timings``), ``traceback`` (empty unless
        the trial raised), ``worker`` (host:pid), ``engine``, ``wall_s``, ``cpu_s`` (CPU time of the
        worker process during the task) and ``finished_at`` (UTC).
    """
    spec = TaskSpec.from_dict(spec_dict)
    t0, c0 = time.perf_counter(), time.process_time()
    timer = fault.arm(spec) if fault else None
    tb = ""
    category = spec.category or spec.kind
    try:
        kind = get_kind(spec.kind)
        category = spec.category or kind.category(spec)
        numba_threads = numba.get_num_threads()
        numba.set_num_threads(1)
        try:
            with _pools(spec.kind).limit(limits=1), _deadline(timeout_s):
                outcome = kind.run(spec)
        finally:
            numba.set_num_threads(numba_threads)
        if not isinstance(outcome, TrialOutcome):
            raise TypeError(f"trial kind {spec.kind!r} returned {type(outcome).__name__}, not a TrialOutcome")
    except TaskTimeout:
        tb = traceback.format_exc()
        outcome = TrialOutcome(False, Failure.TIMEOUT, f"no result within the task's budget of {timeout_s:g} s")
    except Exception as exc:
        tb = traceback.format_exc()
        reason = next((f for cls, f in _ERRORS if isinstance(exc, cls)), Failure.ERROR)
        outcome = TrialOutcome(False, reason, f"{type(exc).__name__}: {exc}")
    finally:
        if timer is not None:
            timer.cancel()
    row = _base(spec, category)
    row.update(outcome.to_record())
    row.update({"traceback": tb, "worker": f"{socket.gethostname()}:{os.getpid()}", "engine": engine,
                "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
                "finished_at": datetime.now(UTC)})
    return row
