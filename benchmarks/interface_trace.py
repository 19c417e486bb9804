"""Where the FANUC stream's per-target compute goes, cycle by cycle.

    python benchmarks/interface_trace.py --json [--seconds 20] [--no-planner] [--switch-interval S]

Streams as ``benchmarks/interface.py`` does (the emulator in its own process, ``FanucRobot`` with the
streaming process, a CFS planner looping in another thread, the streaming thread at SCHED_FIFO 40 in
``realtime_thread``) and splits the wall time of every ``stream()`` call (``per_cycle_us``) into:

- ``cpu``: the streaming thread on a CPU (``time.thread_time_ns``);
- ``runq``: runnable but waiting for a CPU (the run-queue delay of ``/proc/self/task/TID/schedstat``);
- ``off``: the rest, off the CPU and not runnable: waiting for the interpreter lock (nothing else in
  ``stream()`` blocks);

and by phase (the state read, the fault check, the gate, the send into the ring; the rest is the
lock, the state object and the bookkeeping). GC passes of this process are timed by ``gc.callbacks``
and attributed to the cycles they overlap. Prints the histogram of per-cycle times, the slowest
cycles with their split, and totals over the cycles above 500 µs.
"""
from __future__ import annotations

import argparse
import gc
import json
import os
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from _planner_load import planner_thread
from robointel.testing.emulator import EmulatorProcess

PERIOD = 0.008
BINS_US = (0, 100, 200, 300, 400, 500, 750, 1000, 1500, 2000, 5000, 10**9)


class _Phases:
    """Time spent in wrapped callables during the current cycle, ns, by name."""

    def __init__(self) -> None:
        self.now: dict[str, int] = {}

    def wrap(self, name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*a: Any, **k: Any) -> Any:
            t = time.perf_counter_ns()
            try:
                return fn(*a, **k)
            finally:
                self.now[name] = self.now.get(name, 0) + time.perf_counter_ns() - t
        return timed


def _schedstat(fd: int) -> tuple[int, int]:
    """(on-CPU ns, run-queue wait ns) of one thread."""
    f = os.pread(fd, 128, 0).split()
    return int(f[0]), int(f[1])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--planner", action=argparse.BooleanOptionalAction, default=True)
    ap.add_argument("--switch-interval", type=float, default=0.0005)
    ap.add_argument("--slowest", type=int, default=15)
    args = ap.parse_args()

    from robointel.interface import open_robot
    from robointel.interface.realtime import realtime_thread, sleep_until

    gc_log: list[tuple[int, int, int]] = []  # (start ns, end ns, generation)
    gc_t0 = [0]

    def on_gc(phase: str, info: dict[str, int]) -> None:
        if phase == "start":
            gc_t0[0] = time.perf_counter_ns()
        else:
            gc_log.append((gc_t0[0], time.perf_counter_ns(), int(info["generation"])))

    fake = EmulatorProcess()
    stop, counter = threading.Event(), [0]
    th = threading.Thread(target=planner_thread, args=(stop, counter), daemon=True)
    robot = open_robot(fake.url, stream_process=True)
    ph = _Phases()
    robot._read = ph.wrap("read", robot._read)
    robot._fault_of = ph.wrap("fault_check", robot._fault_of)
    robot.gate.check = ph.wrap("gate", robot.gate.check)
    robot._send = ph.wrap("send", robot._send)
    load = [os.getloadavg()[0]]
    try:
        if args.planner:
            th.start()
            while counter[0] < 5:
                time.sleep(0.05)
        q0 = robot.state().q
        K = int(round(args.seconds / PERIOD))
        k = np.arange(K)
        amp = np.radians([20, 10, 10, 30, 20, 45])
        targets = q0 + amp * np.sin(2 * np.pi * 0.25 * k[:, None] * PERIOD) * np.array([1, 1, -1, 1, 1, 1])
        rows = np.zeros((K, 5), dtype=np.int64)  # wall, cpu, runq, c0, c1 (ns)
        phases: list[dict[str, int]] = []
        gc.callbacks.append(on_gc)
        fd = os.open(f"/proc/self/task/{threading.get_native_id()}/schedstat", os.O_RDONLY)
        with realtime_thread(40, switch_interval=args.switch_interval):
            t0 = time.perf_counter() + 0.02
            for i in range(K):
                sleep_until(t0 + i * PERIOD)
                ph.now = {}
                s0 = _schedstat(fd)
                c0, cpu0 = time.perf_counter_ns(), time.thread_time_ns()
                robot.stream(targets[i])
                c1, cpu1 = time.perf_counter_ns(), time.thread_time_ns()
                s1 = _schedstat(fd)
                rows[i] = (c1 - c0, cpu1 - cpu0, s1[1] - s0[1], c0, c1)
                phases.append(ph.now)
        os.close(fd)
        gc.callbacks.remove(on_gc)
        robot.hold()
        missed = robot.driver.missed_events()
        stats = robot.timing_stats()
    finally:
        stop.set()
        if args.planner:
            th.join()
        robot.close()
        fake.close()
    load.append(os.getloadavg()[0])
    wall, cpu, runq = rows[:, 0] / 1e3, rows[:, 1] / 1e3, rows[:, 2] / 1e3
    off = np.maximum(0.0, wall - cpu - runq)
    gc_us = np.zeros(K)
    for g0, g1, _gen in gc_log:
        hit = (rows[:, 3] < g1) & (rows[:, 4] > g0)
        for j in np.flatnonzero(hit):
            gc_us[j] += (min(g1, rows[j, 4]) - max(g0, rows[j, 3])) / 1e3
    hist, _ = np.histogram(wall, bins=BINS_US)
    slow = wall > 500
    order = np.argsort(wall)[::-1][:args.slowest]
    names = ("read", "fault_check", "gate", "send")

    def split(j: int) -> dict[str, float]:
        d = {"wall": wall[j], "cpu": cpu[j], "runq": runq[j], "off_cpu_not_runnable": off[j], "gc": gc_us[j]}
        d.update({n: phases[j].get(n, 0) / 1e3 for n in names})
        return {key: round(float(v), 1) for key, v in d.items()}

    out = {
        "seconds": args.seconds, "planner": args.planner, "switch_interval_s": args.switch_interval,
        "load_avg_1min": load, "cycles": K, "planner_segments": counter[0],
        "per_cycle_us": {"median": float(np.median(wall)), "p99": float(np.percentile(wall, 99)),
                         "max": float(wall.max())},
        "cpu_us": {"median": float(np.median(cpu)), "p99": float(np.percentile(cpu, 99))},
        "histogram_us": {f"{a}-{b if b < 10**9 else 'inf'}": int(n)
                         for a, b, n in zip(BINS_US, BINS_US[1:], hist, strict=False)},
        "phase_median_us": {n: float(np.median([p.get(n, 0) for p in phases])) / 1e3 for n in names},
        "over_500us": {"cycles": int(slow.sum()), "wall_sum_us": float(wall[slow].sum()),
                       "cpu_sum_us": float(cpu[slow].sum()), "runq_sum_us": float(runq[slow].sum()),
                       "off_sum_us": float(off[slow].sum()), "gc_sum_us": float(gc_us[slow].sum())},
        "gc_passes": {g: sum(1 for e in gc_log if e[2] == g) for g in (0, 1, 2)},
        "gc_max_us": max(((e[1] - e[0]) / 1e3 for e in gc_log), default=0.0),
        "slowest": [split(int(j)) for j in order],
        "fanuc_missed": int(stats["stream_starved"] + stats["stream_late"]), "missed_events": missed,
    }
    print(json.dumps(out, indent=None if args.json else 1))


if __name__ == "__main__":
    main()
