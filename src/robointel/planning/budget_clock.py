"""The clock a motion plan's time budget is counted on: wall time (default) or the process's CPU time.

``plan_motion`` computes its deadline on this clock and every stage that looks at the deadline
(the tree search between kernel chunks, the collision-mesh checks every few samples) reads
:func:`now`. Wall time is what a user waits for. On a machine shared with other busy processes a
wall-time budget buys only the CPU share the process gets; ``MotionSettings(budget_clock="cpu")``
counts the process's own CPU time instead, so that a budget means the same work on a loaded machine
as on an idle one (benchmarks and tests use it; ``plan_ms`` stays wall time).
"""
from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar

from robointel.errors import InvalidInput

#: the clocks a budget may be counted on, by name
CLOCKS: dict[str, Callable[[], float]] = {"wall": time.perf_counter, "cpu": time.process_time}

_CLOCK: ContextVar[Callable[[], float]] = ContextVar("robointel_budget_clock", default=time.perf_counter)


def now() -> float:
    """The current reading of the budget clock in use, s (only differences are meaningful)."""
    return _CLOCK.get()()


@contextmanager
def budget_clock(name: str) -> Iterator[Callable[[], float]]:
    """Count deadlines on the clock ``name`` (``"wall"`` or ``"cpu"``) within the block.

    Args:
        name: ``"wall"`` (``time.perf_counter``) or ``"cpu"`` (``time.process_time``: every thread
            of this process).

    Yields:
        The clock function.

    Raises:
        InvalidInput: another name.
    """
    clock = CLOCKS.get(name)
    if clock is None:
        raise InvalidInput(f"budget_clock must be 'wall' or 'cpu', got {name!r}", value=name)
    token = _CLOCK.set(clock)
    try:
        yield clock
    finally:
        _CLOCK.reset(token)


__all__ = ["CLOCKS", "budget_clock", "now"]
