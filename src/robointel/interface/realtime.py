"""Real-time hygiene for the thread that streams to a robot: priority, the interpreter lock, the GC.

A Python thread that must send one target per 8 ms period shares the interpreter lock with every
other thread of its process. Three things make it late, in the order they matter on a loaded machine:

1. **Priority inversion on the interpreter lock.** Another thread (a planner) takes the lock and is
   then preempted by the scheduler for another process; the streaming thread wakes on time but
   waits for the lock until that thread runs again (one scheduling latency, ~15 ms at load 12 on 2
   cores). The cure is to keep every thread of the control process from being preempted by other
   processes: the process runs under a real-time policy (``chrt -r 5 robointel ...``, as a
   robot PC runs its control process) and the streaming thread above it (:func:`realtime_thread`).
2. **Garbage collection.** A full collection in any thread holds the lock for tens of ms when the
   heap is large; :func:`realtime_thread` freezes the heap built so far (``gc.freeze``), so
   collections during the stream only scan what the stream's own era allocated.
3. **Lock hand-over.** The lock is handed over at most every ``sys.getswitchinterval()`` s (5 ms by
   default); :func:`realtime_thread` lowers it to 0.5 ms while streaming.

The waiting itself (:func:`sleep_until`) sleeps through the period and spins the last few hundred
microseconds without giving the lock away.
"""
from __future__ import annotations

import contextlib
import gc
import os
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass

from robointel.errors import InvalidInput

SPIN_S = 0.0003
"""The last part of a wait spent spinning (holding the interpreter lock) rather than sleeping, s."""

SWITCH_INTERVAL_S = 0.0005
"""The interpreter-lock switch interval while a real-time section runs, s."""


def sleep_until(deadline: float) -> None:
    """Sleep until ``time.perf_counter() >= deadline``; spin the last :data:`SPIN_S` s.

    The spin does not release the interpreter lock (a ``time.sleep(0)`` spin would hand it to
    another thread at every turn and wait up to a switch interval to get it back).

    Args:
        deadline: ``time.perf_counter()`` value to wait for, s.
    """
    rem = deadline - time.perf_counter()
    if rem > SPIN_S:
        time.sleep(rem - SPIN_S)
    while time.perf_counter() < deadline:
        pass


@dataclass
class RealtimeStatus:
    """What :func:`realtime_thread` obtained.

    Attributes:
        policy: ``"SCHED_FIFO"`` when the real-time policy was granted, else ``"SCHED_OTHER"``.
        priority: the FIFO priority (0 when not granted).
        process_policy: the scheduling policy of the process's other threads (``"SCHED_RR"`` under
            ``chrt -r``), as found on entry.
        gc_frozen: objects this section moved to the permanent generation (0 when nested).
    """

    policy: str
    priority: int
    process_policy: str
    gc_frozen: int


_POLICY_NAMES = {os.SCHED_OTHER: "SCHED_OTHER", os.SCHED_FIFO: "SCHED_FIFO", os.SCHED_RR: "SCHED_RR",
                 getattr(os, "SCHED_BATCH", -1): "SCHED_BATCH", getattr(os, "SCHED_IDLE", -2): "SCHED_IDLE"}


@contextlib.contextmanager
def realtime_thread(priority: int = 40, *, fifo: bool = True, freeze_gc: bool = True,
                    switch_interval: float = SWITCH_INTERVAL_S) -> Iterator[RealtimeStatus]:
    """Run the calling thread as a real-time streaming thread for the ``with`` block.

    On entry: ``SCHED_FIFO`` at ``priority`` for the calling thread (when the process has
    ``CAP_SYS_NICE``; otherwise it stays as it was and the status says so), ``gc.freeze()``, and the
    interpreter-lock switch interval set to ``switch_interval``. Everything is restored on exit
    (the frozen objects are released with ``gc.unfreeze()``). Sections nest: an inner one leaves
    the heap to the outer one.

    Args:
        priority: ``SCHED_FIFO`` priority, 1..98 (the airo-fanuc core thread runs at 80, above it).
        fifo: ask for ``SCHED_FIFO`` (False: keep the thread's policy, do the rest).
        freeze_gc: freeze the heap built so far.
        switch_interval: interpreter-lock switch interval while inside, s.

    Yields:
        The :class:`RealtimeStatus`.

    Raises:
        InvalidInput: priority outside 1..98 or a switch interval outside (0, 0.1] s.
    """
    if not 1 <= int(priority) <= 98:
        raise InvalidInput(f"real-time priority must be in 1..98, got {priority}", value=priority)
    if not 0 < switch_interval <= 0.1:
        raise InvalidInput(f"switch interval must be in (0, 0.1] s, got {switch_interval}", value=switch_interval)
    old_policy, old_param = os.sched_getscheduler(0), os.sched_getparam(0)
    granted = False
    if fifo:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(int(priority)))
            granted = True
        except (PermissionError, OSError):
            pass
    old_switch = sys.getswitchinterval()
    sys.setswitchinterval(switch_interval)
    frozen = 0
    freeze_gc = freeze_gc and gc.get_freeze_count() == 0  # an enclosing section already froze the heap
    if freeze_gc:
        gc.freeze()  # O(1): no collection first, so entering never pauses a running stream
        frozen = gc.get_freeze_count()
    try:
        yield RealtimeStatus("SCHED_FIFO" if granted else _POLICY_NAMES.get(old_policy, str(old_policy)),
                             int(priority) if granted else 0, _POLICY_NAMES.get(old_policy, str(old_policy)),
                             frozen)
    finally:
        if freeze_gc:
            gc.unfreeze()
        sys.setswitchinterval(old_switch)
        if granted:
            with contextlib.suppress(PermissionError, OSError):
                os.sched_setscheduler(0, old_policy, old_param)
