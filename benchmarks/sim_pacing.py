"""Where the paced sim stream's late cycles go: waking late vs a slow ``stream()``.

    PYTHONPATH=src:benchmarks python benchmarks/sim_pacing.py [--seconds 20] [--profile] [--stream-process]

The stream of ``benchmarks/interface.py`` (``SimRobot(paced=True, stall_periods=10)``, the same
targets, ``sleep_until`` pacing in a ``realtime_thread(40)`` section, the table71 planner thread
beside it), with each cycle split into its *wake* delay (the time past the period's start at which
the streaming thread got the interpreter lock back after its sleep) and its *send* time (the
``stream()`` call). A cycle is missed when wake + send exceeds the period, as in ``interface.py``.

``--profile`` also records, in the planner thread, every stretch of more than 4 ms between two
profiler events (calls and returns, C calls included): one C call that held the interpreter lock
that long (or during which the thread holding it was off the CPU). The hook slows the planner.
Run under ``chrt -r 5`` to put the planner thread at a real-time priority too.

``--stream-process`` streams to ``open_robot("sim", stream_process=True)`` instead (the workcell stepped
in a process of its own from a look-ahead ring, ``--lookahead`` s): ``missed_cycles`` is then the child's
starved + late windows, and ``caller_late_cycles`` the cycles whose wake + send exceeded the period (what
``missed_cycles`` counts for the in-process sim; with the look-ahead they cost no window). With it, ``child``
holds the child's own figures (how long after each tick its loop read it, the windows whose physics took
more than 2 ms, ``--lock-memory``: ``mlockall`` in the child) and ``late_events`` its late windows, each
with ``in_host_stall`` (within 20 ms of a stall of the host probe's bare sleeper, ``host``: see
:class:`~robointel.testing.host_probe.HostProbe`).
"""
from __future__ import annotations

import argparse
import json
import os
import threading
import time
from collections import Counter

import numpy as np

import interface as bench
from _planner_load import planner_thread
from robointel.interface import open_robot
from robointel.interface.realtime import realtime_thread, sleep_until
from robointel.interface.sim import SimRobot
from robointel.testing.host_probe import HostProbe

GAP_S = 0.004


def _gap_hook(gaps: list) -> object:
    last = [0.0, ""]

    def hook(frame, event, arg):  # noqa: ANN001, ANN202
        t = time.perf_counter()
        what = getattr(arg, "__qualname__", "") if event.startswith("c_") else ""
        name = f"{event}:{what}:{frame.f_code.co_name}@{os.path.basename(frame.f_code.co_filename)}:{frame.f_lineno}"
        if last[0] and t - last[0] > GAP_S:
            gaps.append((last[0], t - last[0], last[1]))
        last[0], last[1] = t, name

    return hook


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--profile", action="store_true", help="record the planner thread's long C calls")
    ap.add_argument("--stream-process", action="store_true", help="the sim's streaming process (SimStreamRobot)")
    ap.add_argument("--lookahead", type=float, default=0.1, help="its look-ahead, s")
    ap.add_argument("--lock-memory", action="store_true", help="the streaming process locks its memory (mlockall)")
    args = ap.parse_args()
    gaps: list = []
    if args.profile:
        threading.setprofile(_gap_hook(gaps))
    robot = (open_robot("sim", stream_process=True, stall_periods=10, lookahead_s=args.lookahead,
                        lock_memory=args.lock_memory)
             if args.stream_process else SimRobot(paced=True, stall_periods=10))
    stop, counter = threading.Event(), [0]
    th = threading.Thread(target=planner_thread, args=(stop, counter), daemon=True)
    th.start()
    bench._wait_warm(counter)
    threading.setprofile(None)
    targets = bench._targets(robot.state().q, args.seconds)
    K = len(targets)
    wake, send = np.zeros(K), np.zeros(K)
    load0 = os.getloadavg()[0]
    try:
        with realtime_thread(40) as rt, HostProbe() as probe:
            origin = time.monotonic()
            t0 = time.perf_counter() + 0.02
            for k in range(K):
                sleep_until(t0 + k * bench.PERIOD)
                c0 = time.perf_counter()
                robot.stream(targets[k])
                c1 = time.perf_counter()
                wake[k], send[k] = c0 - (t0 + k * bench.PERIOD), c1 - c0
        robot.hold()
        if args.stream_process:  # count the windows of the targets still queued too
            deadline = time.monotonic() + 30.0
            while not robot.driver.held() and time.monotonic() < deadline:
                time.sleep(0.01)
        child = robot.timing_stats() if args.stream_process else {}
        events = robot.driver.missed_events() if args.stream_process else []
        base = robot.driver.base_ns * 1e-9 if args.stream_process else 0.0
    finally:
        stop.set()
        th.join()
        robot.close()
    late = wake + send > bench.PERIOD

    def pct(x: np.ndarray) -> list[float]:
        return [round(float(v), 3) for v in np.percentile(x * 1e3, [50, 90, 99, 100])]

    during = [g for g in gaps if g[0] > t0]
    out = {"cycles": K, "missed_cycles": int(late.sum()), "policy": rt.policy, "stream_process": args.stream_process,
           "process_policy": rt.process_policy, "wake_ms_p50_p90_p99_max": pct(wake),
           "send_ms_p50_p90_p99_max": pct(send),
           "missed_wake_ms": np.round(wake[late] * 1e3, 1).tolist(),
           "missed_send_ms": np.round(send[late] * 1e3, 1).tolist(),
           "planner_segments_meanwhile": counter[0], "load_avg_1min": [load0, os.getloadavg()[0]],
           "host": probe.summary(origin)}
    if args.stream_process:
        out["caller_late_cycles"] = out["missed_cycles"]
        out["missed_cycles"] = int(child["stream_starved"] + child["stream_late"])
        out["child"] = {k: child[k] for k in ("stream_windows", "stream_fresh", "stream_starved", "stream_late",
                                              "stream_core_late", "step_max_ms", "catch_up_max_windows",
                                              "gc_max_ms", "lookahead_s", "wake_after_tick_ms", "memory_locked")}
        slow = child["slow_steps"]
        out["child"]["slow_steps"] = {"count": len(slow), "in_host_stall": probe.coincident([x[0] for x in slow]),
                                      "wall_cpu_ms": [x[1:] for x in slow[:30]]}
        out["late_events"] = [{"at_s": round(base + e[1] - origin, 3), "late_ms": e[8], "gap_ms": e[3], "cpu_ms": e[4],
                               "runq_ms": e[5], "faults": e[9], "preemptions": e[10],
                               "in_host_stall": probe.coincident([base + e[1]])} for e in events if e[0] == "late"]
    if args.profile:
        out["planner_gaps_over_4ms"] = len(during)
        out["planner_gap_ms_max"] = round(max((g[1] for g in during), default=0.0) * 1e3, 1)
        out["planner_gap_sites"] = Counter(g[2] for g in during).most_common(6)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
