"""Timing helper shared by the benchmark scripts (run as ``python benchmarks/NAME.py``)."""
from __future__ import annotations

import time

import numpy as np


def median_us(fn, reps: int = 2000, inner: int = 10) -> float:
    """Median wall time of ``fn()`` in µs over ``reps // inner`` batches of ``inner`` calls (one warm-up)."""
    fn()
    times = []
    for _ in range(max(1, reps // inner)):
        t = time.perf_counter()
        for _ in range(inner):
            fn()
        times.append((time.perf_counter() - t) / inner)
    return float(np.median(times) * 1e6)
