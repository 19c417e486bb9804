"""Who holds a CPU above the bare sleeper's priority during a FANUC stream.

    python benchmarks/fanuc_cpu_holders.py --json [--seconds 60] [--no-planner] [--lookahead 0.1]

Streams as ``benchmarks/interface.py`` does (the emulator in its own process, ``FanucRobot`` with the
streaming process, a planner looping in another thread, the caller's streaming thread at SCHED_FIFO 40)
with :class:`~robointel.testing.host_probe.HostProbe`'s pinned SCHED_FIFO-55 sleepers beside it, while
``perf record -e sched:sched_switch -e sched:sched_wakeup -a -k CLOCK_MONOTONIC`` records every context
switch of the machine. For each stall of a sleeper (a wake-up more than 2 ms late) it reads from the
trace what ran on that sleeper's CPU between the sleeper's deadline and the moment it ran: each task's
time there, its thread (the streaming process's threads are named: ``main``, the airo-fanuc core, the
driver's Python threads by their ``threading`` names), and its kernel priority (``prio`` 0-98 is
SCHED_FIFO 99-prio: the core's 80 is 19, the streaming process's 60 is 39, the sleeper's 55 is 44;
100-139 is a normal task). A stall in which the CPU ran the idle task, or the sleeper was woken late
(its wake-up event after its deadline) with nothing above it running, is the host's: the virtual CPU
not run. The totals over the whole stream (each task's time on each CPU at a priority above the
sleeper's) come with it, and the streaming process's missed windows beside the stalls.
"""
from __future__ import annotations

import argparse
import collections
import json
import os
import re
import signal
import subprocess
import tempfile
import threading
import time
from typing import Any

import interface as ib
from _planner_load import planner_thread
from robointel.testing.emulator import EmulatorProcess
from robointel.testing.host_probe import HostProbe

_SWITCH = re.compile(r"\[(\d+)\]\s+(\d+\.\d+):\s+sched:sched_switch:\s+prev_comm=(.*?) prev_pid=(\d+) prev_prio=(\d+)"
                     r" prev_state=(\S+) ==> next_comm=(.*?) next_pid=(\d+) next_prio=(\d+)")
_WAKE = re.compile(r"\[(\d+)\]\s+(\d+\.\d+):\s+sched:sched_wakeup:\s+comm=(.*?) pid=(\d+) prio=(\d+)"
                   r" target_cpu=(\d+)")
SLEEPER_PRIO = 99 - 55
"""The sleeper's kernel priority (SCHED_FIFO 55)."""


def _trace(path: str) -> tuple[dict[int, list[tuple[float, int, str, int]]], dict[int, list[float]]]:
    """Per CPU, the switches in (time, next pid, next comm, next prio); per pid, its wake-up times."""
    out = subprocess.run(["perf", "script", "-i", path, "--ns", "-F", "cpu,time,event,trace"],
                         capture_output=True, text=True, check=True).stdout
    runs: dict[int, list[tuple[float, int, str, int]]] = collections.defaultdict(list)
    wakes: dict[int, list[float]] = collections.defaultdict(list)
    for line in out.splitlines():
        m = _SWITCH.search(line)
        if m:
            runs[int(m[1])].append((float(m[2]), int(m[8]), m[7], int(m[9])))
            continue
        w = _WAKE.search(line)
        if w:
            wakes[int(w[4])].append(float(w[2]))
    return runs, wakes


def _occupancy(switches: list[tuple[float, int, str, int]], a: float, b: float) -> dict[tuple[int, str, int], float]:
    """Time each (pid, comm, prio) ran on a CPU between ``a`` and ``b`` (s), from its switch list."""
    occ: dict[tuple[int, str, int], float] = collections.defaultdict(float)
    for i, (t, pid, comm, prio) in enumerate(switches):
        t_end = switches[i + 1][0] if i + 1 < len(switches) else b
        lo, hi = max(a, t), min(b, t_end)
        if hi > lo:
            occ[(pid, comm, prio)] += hi - lo
    return occ


def _names(robot: Any, fake: EmulatorProcess, probe: HostProbe) -> dict[int, str]:
    """Thread id -> role: the streaming process's threads, the emulator's, the caller's, the sleepers."""
    names: dict[int, str] = {}
    child = robot.driver._proc.pid
    py = {int(k): v for k, v in robot.driver.call("threads").items()}
    for tid in map(int, os.listdir(f"/proc/{child}/task")):
        comm = open(f"/proc/{child}/task/{tid}/comm").read().strip()
        names[tid] = f"stream child: {py.get(tid, 'native ' + comm)}" + (" (main)" if tid == child else "")
    emu = fake._proc.pid if hasattr(fake, "_proc") else None
    if emu:
        for tid in map(int, os.listdir(f"/proc/{emu}/task")):
            names[tid] = "emulator" + (" (main)" if tid == emu else "")
    me = {t.native_id: t.name for t in threading.enumerate()}
    for tid in map(int, os.listdir("/proc/self/task")):
        names[tid] = f"caller: {me.get(tid, 'native')}"
    for cpu, pid in probe.sleeper_pids().items():
        names[pid] = f"sleeper cpu{cpu}"
    return names


def _policies(pid: int) -> dict[int, str]:
    """{thread id: 'SCHED_FIFO 60'...} of a process's threads."""
    pol = {os.SCHED_OTHER: "SCHED_OTHER", os.SCHED_FIFO: "SCHED_FIFO", os.SCHED_RR: "SCHED_RR"}
    out = {}
    for tid in map(int, os.listdir(f"/proc/{pid}/task")):
        try:
            out[tid] = f"{pol.get(os.sched_getscheduler(tid), 'other')} {os.sched_getparam(tid).sched_priority}"
        except OSError:
            continue
    return out


def run(seconds: float, planner: bool, lookahead: float) -> dict[str, Any]:
    """Stream ``seconds`` on the emulator under ``perf`` and say who held each stalled sleeper's CPU."""
    from robointel.interface import open_robot

    fake = EmulatorProcess()
    stop, counter = threading.Event(), [0]
    th = threading.Thread(target=planner_thread, args=(stop, counter), daemon=True)
    tmp = tempfile.mkdtemp(prefix="fanuc_holders_")
    data = os.path.join(tmp, "perf.data")
    try:
        robot = open_robot(fake.url, stream_process=True, lookahead_s=lookahead)
        try:
            if planner:
                th.start()
                ib._wait_warm(counter)
            targets = ib._targets(robot.state().q, seconds)
            perf = subprocess.Popen(["perf", "record", "-q", "-e", "sched:sched_switch", "-e", "sched:sched_wakeup",
                                     "-a", "-k", "CLOCK_MONOTONIC", "-m", "1024", "-o", data],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
            time.sleep(1.0)
            with ib._fifo(), HostProbe() as probe:
                origin = time.monotonic()
                _, missed, *_ = ib._stream(robot.stream, targets, robot)
                robot.hold()
                names = _names(robot, fake, probe)
            perf.send_signal(signal.SIGINT)
            perf.wait(timeout=120)
            stats = robot.timing_stats()
            events = robot.driver.missed_events()
            base = robot.driver.base_ns * 1e-9
            pols = _policies(robot.driver._proc.pid)
        finally:
            stop.set()
            if planner:
                th.join()
            robot.close()
    finally:
        fake.close()
    runs, wakes = _trace(data)
    for f in os.listdir(tmp):
        os.unlink(os.path.join(tmp, f))
    os.rmdir(tmp)
    sleepers = {pid: cpu for cpu, pid in probe.sleeper_pids().items()}
    stalls_out, above = [], collections.defaultdict(float)
    for cpu, stalls in probe.stalls_per_cpu().items():
        pid = next(p for p, c in sleepers.items() if c == cpu)
        for d, late_ms in stalls:
            ran = next((t for t, p, _, _ in runs[cpu] if p == pid and t >= d), d + late_ms * 1e-3)
            woke = next((t for t in wakes.get(pid, []) if t >= d - 1e-4), None)
            occ = _occupancy(runs[cpu], d, ran)
            top = sorted(occ.items(), key=lambda kv: -kv[1])[:4]
            held = [(names.get(p, f"other: {c}"), pr) for (p, c, pr), s in occ.items()
                    if pr < SLEEPER_PRIO and woke is not None and s > 1e-3]
            late_wake = woke is None or (woke - d) * 1e3 >= late_ms - 1.0
            stalls_out.append({"cpu": cpu, "at_s": round(d - origin, 4), "late_ms": late_ms,
                               # a timer wake-up that itself came late: the vCPU was not run (the
                               # interrupt preempts any task); whatever was current is billed the gap
                               "cause": "timer wake-up late (the vCPU not run)" if late_wake else
                               ("held above 55: " + ", ".join(w for w, _ in held)) if held else "other",
                               "woken_after_deadline_ms": None if woke is None else round((woke - d) * 1e3, 3),
                               "ran": [{"who": names.get(p, f"other: {c}"), "pid": p, "prio": pr,
                                        "ms": round(s * 1e3, 3)} for (p, c, pr), s in top]})
    t0, t1 = origin, origin + seconds
    longest: dict[str, float] = collections.defaultdict(float)
    for cpu, sw in runs.items():
        for (p, c, pr), s in _occupancy(sw, t0, t1).items():
            if pr < SLEEPER_PRIO:
                above[(names.get(p, f"other: {c}"), pr, cpu)] += s
        for i, (t, p, c, pr) in enumerate(sw[:-1]):  # the longest single run on a CPU above the sleeper
            if pr < SLEEPER_PRIO and t0 <= t <= t1:
                key = f"{names.get(p, f'other: {c}')} prio {pr}"
                longest[key] = max(longest[key], sw[i + 1][0] - t)
    missed_ev = [{"kind": e[0], "at_s": round(base + e[1] - origin, 4), "late_ms": e[8]} for e in events]
    return {"seconds": seconds, "planner": planner, "lookahead_s": lookahead,
            "load_avg": probe.summary(origin)["load_avg"], "steal_share": probe.summary(origin)["steal_share"],
            "missed_windows": int(stats["stream_starved"] + stats["stream_late"]), "caller_late_cycles": missed,
            "core_skipped_windows": stats.get("skipped_tick_windows"), "missed_events": missed_ev,
            "child_threads": {names.get(t, str(t)): p for t, p in pols.items()},
            "stalls": len(stalls_out),
            "stall_causes": dict(collections.Counter(x["cause"] for x in stalls_out)),
            "stalls_on_every_cpu": probe.summary(origin)["probe_stalls_on_every_cpu"],
            "stalls_by_cpu": {c: len(v) for c, v in probe.stalls_per_cpu().items()},
            "stall_detail": sorted(stalls_out, key=lambda s: -s["late_ms"])[:40],
            "above_sleeper_longest_run_ms": {k: round(v * 1e3, 3) for k, v in
                                             sorted(longest.items(), key=lambda kv: -kv[1])},
            "above_sleeper_cpu_s": {f"{w} prio {pr} cpu{c}": round(s, 4)
                                    for (w, pr, c), s in sorted(above.items(), key=lambda kv: -kv[1])}}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--planner", action=argparse.BooleanOptionalAction, default=True)
    ap.add_argument("--lookahead", type=float, default=0.1)
    args = ap.parse_args()
    print(json.dumps(run(args.seconds, args.planner, args.lookahead), indent=None if args.json else 1))


if __name__ == "__main__":
    main()
