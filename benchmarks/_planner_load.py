"""The planner load of the interface benchmarks: a thread planning the table71 FRMP segments in turn."""
from __future__ import annotations

import threading


def planner_thread(stop: threading.Event, counter: list[int]) -> None:
    """Plan the built-in table71 scene's segments one after another until ``stop`` is set.

    Args:
        stop: set to end the thread.
        counter: ``counter[0]`` counts the planned segments.
    """
    from robointel.planning import make_planners
    from robointel.planning.scene import load_scene

    sc = load_scene("table71")
    planners = make_planners(sc)
    i = 0
    while not stop.is_set():
        seg = i % len(sc.steps)
        planners[sc.steps[seg]].plan_segment(sc.waypoints[seg], sc.waypoints[seg + 1])
        counter[0] += 1
        i += 1
