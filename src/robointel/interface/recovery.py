"""Recovery of a stopped controller: the recovery ladder retried until a status shows no fault, within a deadline."""
from __future__ import annotations

import time
from collections.abc import Callable

SETTLE_S = 0.5
"""How long one recovery attempt waits for a status without the fault, s."""


def recover_until_clear(ladder: Callable[[], bool], fault: Callable[[], str | None], *, period: float,
                        timeout_s: float, settle_s: float = SETTLE_S) -> str | None:
    """Run ``ladder`` until ``fault()`` reports nothing after a successful run, for up to ``timeout_s``.

    The status that shows a cleared fault can come a few controller periods after the ladder returns
    (more on a loaded host), and a ladder can end early while the controller is still settling: both
    are retried until the deadline (no attempt starts after it; a ladder under way ends first). Nothing
    is commanded here.

    Args:
        ladder: one run of the controller's recovery ladder; True when it reached streaming.
        fault: why the latest status shows the robot stopped, or None.
        period: the controller period (the status poll), s.
        timeout_s: the deadline from the first attempt, s.
        settle_s: how long one attempt polls the status before the ladder runs again, s.

    Returns:
        None once recovered, else the last reason the robot stayed stopped.
    """
    deadline = time.perf_counter() + timeout_s
    why = "the recovery ladder did not reach streaming"
    while True:
        ok = ladder()
        settle = min(deadline, time.perf_counter() + settle_s)
        while True:
            now_why = fault()
            if ok and now_why is None:
                return None
            why = now_why or why
            if time.perf_counter() >= settle:
                break
            time.sleep(period)
        if time.perf_counter() >= deadline:
            return why
