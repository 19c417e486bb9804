"""The Ray engine: trials as Ray tasks on a local Ray or a cluster (``pip install 'robointel[batch]'``).

Each task reserves ``cpus_per_task`` CPUs and runs :func:`robointel.batch.execute.execute` with
one thread per numerical library (the worker environment sets ``OMP_NUM_THREADS=1`` and friends
before numpy loads). A task whose worker process dies (killed, out of memory, node lost) is re-run
by Ray up to ``max_retries`` times; trials are pure functions of their spec, so a re-run is
harmless, and the driver stores the one result Ray returns. A task that still has no result after
its retries becomes a ``fault`` row with Ray's error text.

A local Ray binds the machine's routable address; on a machine where that must not happen (tests,
CI) run the driver inside a loopback-only network namespace (``unshare --net``, ``ip link set lo up``).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from typing import Any

import ray
from ray.exceptions import RayError

from robointel.batch.execute import THREAD_ENV, Fault, execute, failure_row
from robointel.batch.registry import get_kind
from robointel.batch.spec import TaskSpec
from robointel.errors import EngineUnavailable, InvalidInput
from robointel.outcome import Failure

__all__ = ["longest_first", "run_on_ray", "start_ray"]

JOIN_ATTEMPTS = 3  # tries to join a cluster through Ray Client (ray://) before giving up

_REMOTE: list[Any] = []  # the remote execute, made once per driver process (its definition is exported once)


def _remote_execute() -> Any:
    """``ray.remote(execute)``, one per process: each sweep sets its options on the same remote function."""
    if not _REMOTE:
        _REMOTE.append(ray.remote(execute))
    return _REMOTE[0]


def _expected_s(spec: TaskSpec) -> float:
    """The spec's expected duration (s), a scheduling hint: 1 s when its kind has none or cannot tell."""
    try:
        return get_kind(spec.kind).expected_s(spec)
    except Exception:  # a hint never stops a sweep: a bad spec fails in its own task, with its own row
        return 1.0


def longest_first(todo: Sequence[TaskSpec]) -> list[TaskSpec]:
    """The tasks in the order they are started: longest expected first (ties keep their order).

    Longest-processing-time-first list scheduling: the sweep ends with the short tasks, which fill
    the workers' last gaps, instead of one worker running a long trial while the others are idle.
    """
    return sorted(todo, key=lambda s: -_expected_s(s))


def start_ray(*, workers: int, address: str | None, worker_niceness: int = 0) -> bool:
    """Start a local Ray with ``workers`` CPUs, or join ``address``; return True if this call started it.

    A local Ray's worker processes run at ``worker_niceness`` (Ray's default, 15, lets any other
    process on the machine, the driver included, take the CPU from the trials). A joined cluster
    keeps its own setting.

    Raises:
        EngineUnavailable: joining the cluster or starting Ray failed.
    """
    if ray.is_initialized():
        return False
    env = {"env_vars": dict(THREAD_ENV)}
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    if not address:  # read by the raylet this call starts
        os.environ["RAY_worker_niceness"] = str(int(worker_niceness))
    attempts = JOIN_ATTEMPTS if address and address.startswith("ray://") else 1
    for attempt in range(attempts):
        try:
            if address:
                ray.init(address=address, runtime_env=env, log_to_driver=False)
            else:
                ray.init(address="local", num_cpus=workers, include_dashboard=False, runtime_env=env,
                         log_to_driver=False)
            return True
        except (ConnectionError, RuntimeError, ValueError) as exc:
            # a Ray Client server starts its per-client server lazily; on a loaded head that can time out,
            # or the fresh server process can die at once (Ray forks it while gRPC threads run: "Initialization
            # failure from server ... ZombieProcess", docs/design/batch.md): the join is tried again
            if attempt + 1 < attempts and ("client server failed" in str(exc)
                                           or "Initialization failure from server" in str(exc)):
                time.sleep(2.0)
                continue
            where = address or "a local Ray"
            raise EngineUnavailable(f"could not start or join {where}: {exc}", value=address) from None
    return True


def run_on_ray(todo: Sequence[TaskSpec], on_row: Callable[[dict[str, Any]], None],
               on_running: Callable[[int], None], *, workers: int, address: str | None, cpus_per_task: float,
               max_retries: int, fault: Fault | None = None, timeout_s: float | None = None,
               worker_niceness: int = 0) -> None:
    """Run ``todo`` as Ray tasks and hand each finished row to ``on_row`` (in completion order).

    The tasks start longest expected first (:func:`longest_first`). At most twice the cluster's task
    slots are in flight, so a sweep of any size streams.
    On an exception (e.g. KeyboardInterrupt) the pending tasks are cancelled and it propagates;
    a Ray started here is shut down on the way out.

    Raises:
        EngineUnavailable: see :func:`start_ray`.
        InvalidInput: ``cpus_per_task`` exceeds the cluster's CPUs.
    """
    started = start_ray(workers=workers, address=address, worker_niceness=worker_niceness)
    try:
        cpus = float(ray.cluster_resources().get("CPU", 0.0))
        if cpus_per_task > cpus:
            raise InvalidInput(f"cpus_per_task {cpus_per_task} exceeds the cluster's {cpus:g} CPUs: no task could "
                               "ever start", value=cpus_per_task)
        slots = max(1, int(cpus // cpus_per_task))
        remote = _remote_execute().options(num_cpus=cpus_per_task, max_retries=max_retries, retry_exceptions=False)
        queue = longest_first(todo)[::-1]
        pending: dict[Any, TaskSpec] = {}
        try:
            while queue or pending:
                while queue and len(pending) < 2 * slots:
                    s = queue.pop()
                    pending[remote.remote(s.to_dict(), fault, "ray", timeout_s)] = s
                on_running(min(len(pending), slots))
                ready, _ = ray.wait(list(pending), num_returns=1, timeout=0.5)
                for ref in ready:
                    s = pending.pop(ref)
                    try:
                        row = ray.get(ref)
                    except RayError as exc:
                        row = failure_row(s, Failure.FAULT, f"no result after {max_retries} retries: "
                                          f"{type(exc).__name__}", str(exc), engine="ray")
                    on_row(row)
            on_running(0)
        except BaseException:
            for ref in pending:
                ray.cancel(ref, force=True)
            raise
    finally:
        if started:
            ray.shutdown()
