"""Waiting on the state a test's property needs, not on a fixed time (a slow, loaded CI host stretches every
fixed sleep: the emulator's plant steps once per tick it gets to run, the watchdog wakes when scheduled)."""
import time
from collections.abc import Callable

import numpy as np


def wait_until(condition: Callable[[], bool], timeout: float = 15.0, poll: float = 0.01) -> bool:
    """Poll ``condition`` until it holds (True) or ``timeout`` s have passed (False; it is checked once more)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(poll)
    return bool(condition())


def settled(read: Callable[[], np.ndarray], tol: float, still_s: float, timeout: float = 15.0,
            poll: float = 0.01) -> np.ndarray:
    """``read()`` once it has stayed within ``tol`` (max abs) of one value for ``still_s`` s, or at ``timeout``.

    The caller asserts on what it returns; reaching the timeout returns the last reading as it is.
    """
    ref, since = np.asarray(read(), dtype=float), time.monotonic()
    deadline = since + timeout
    while time.monotonic() < deadline:
        time.sleep(poll)
        x = np.asarray(read(), dtype=float)
        if np.max(np.abs(x - ref)) > tol:
            ref, since = x, time.monotonic()
        elif time.monotonic() - since >= still_s:
            return x
    return np.asarray(read(), dtype=float)
