"""Wall and process CPU time per stage of a plan (``MotionPlan.timings`` and ``cpu_timings``)."""
from __future__ import annotations

import time

#: the process CPU clock of the stage times
cpu_clock = time.process_time


class StageTimes(dict):
    """Wall time per stage, ms (the dict itself), with the process CPU time per stage, ms, in ``cpu``."""

    def __init__(self) -> None:
        super().__init__()
        self.cpu: dict[str, float] = {}

    def add(self, name: str, wall0: float, cpu0: float) -> None:
        """Add the time since ``wall0`` (``time.perf_counter``) and ``cpu0`` (:func:`cpu_clock`) to ``name``."""
        self[name] = self.get(name, 0.0) + (time.perf_counter() - wall0) * 1e3
        self.cpu[name] = self.cpu.get(name, 0.0) + (cpu_clock() - cpu0) * 1e3
