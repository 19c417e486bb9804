"""What the host did while a stream ran: load, hypervisor steal per CPU, and the stalls a bare sleeper saw.

A window a streaming process misses is either its own doing (a long physics step, a collection, a
page fault) or the machine's (the virtual CPU taken by the hypervisor: *steal*; another real-time
task). :class:`HostProbe` tells them apart from outside the streaming code: beside the stream it
runs, on each CPU, a child process pinned there (this file as a script, standard library only) that
does nothing but sleep to a deadline every :data:`PROBE_PERIOD_S` at SCHED_FIFO :data:`PROBE_PRIORITY`
(when the policy is granted) and notes each wake-up later than :data:`STALL_MS`; the first also
samples the load average and ``/proc/stat``'s steal per CPU every :data:`SAMPLE_S`. A missed window at
the instant a sleeper also woke late is a host stall, not the streaming code; a stall of every CPU's
sleeper at once is one no process of this machine could have escaped by running elsewhere.

Times are CLOCK_MONOTONIC seconds (``time.monotonic()``), the clock of the streaming processes'
``base_ns``.
"""
from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

PROBE_PERIOD_S = 0.002
"""The sleeper's period, s (500 wake-ups a second: ~1 % of one CPU)."""
PROBE_PRIORITY = 55
"""SCHED_FIFO priority of the sleeper (below the streaming processes' 60, above a caller's 40)."""
STALL_MS = 2.0
"""A wake-up this much past its deadline is a stall, ms."""
SAMPLE_S = 0.5
"""How often the load and ``/proc/stat`` are sampled, s."""
MAX_STALLS = 4096
"""Stalls remembered (the count goes on)."""


def cpu_times() -> dict[str, tuple[int, int]]:
    """``/proc/stat`` per CPU (and ``cpu`` for all): (steal, total) in clock ticks."""
    out: dict[str, tuple[int, int]] = {}
    with open("/proc/stat") as f:
        for line in f:
            if not line.startswith("cpu"):
                break
            name, *vals = line.split()
            v = [int(x) for x in vals[:8]]  # user nice system idle iowait irq softirq steal
            out[name] = (v[7] if len(v) > 7 else 0, sum(v))
    return out


def steal_share(a: dict[str, tuple[int, int]], b: dict[str, tuple[int, int]]) -> dict[str, float]:
    """The share of each CPU's time the hypervisor took between two :func:`cpu_times` samples (0..1)."""
    out = {}
    for k, (s1, t1) in b.items():
        s0, t0 = a.get(k, (s1, t1))
        out[k] = round((s1 - s0) / (t1 - t0), 4) if t1 > t0 else 0.0
    return out


def _probe(seconds_max: float, cpu: int, sample: bool) -> None:
    """The sleeper (this file as a script) on ``cpu``: run until stdin closes or ``seconds_max``; print JSON."""
    import select
    import threading

    if cpu >= 0:
        with contextlib.suppress(OSError):
            os.sched_setaffinity(0, {cpu})
    fifo = True
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(PROBE_PRIORITY))
    except OSError:
        fifo = False
    done = threading.Event()

    def watch() -> None:
        select.select([sys.stdin], [], [], seconds_max)
        done.set()

    threading.Thread(target=watch, daemon=True).start()
    stalls: list[tuple[float, float]] = []
    samples: list[tuple[float, float, dict[str, float]]] = []
    n_stalls, wakes, late_sum, late_max = 0, 0, 0.0, 0.0
    start = time.monotonic()
    prev_cpu, next_sample = cpu_times(), start + SAMPLE_S
    deadline = start + PROBE_PERIOD_S
    while not done.is_set():
        rem = deadline - time.monotonic()
        if rem > 0:
            time.sleep(rem)
        now = time.monotonic()
        late = (now - deadline) * 1e3
        wakes += 1
        late_sum += late
        late_max = max(late_max, late)
        if late > STALL_MS:
            n_stalls += 1
            if len(stalls) < MAX_STALLS:
                stalls.append((round(deadline, 6), round(late, 3)))
        deadline += PROBE_PERIOD_S * max(1, int((now - deadline) / PROBE_PERIOD_S) + 1)
        if sample and now >= next_sample:
            times = cpu_times()
            samples.append((round(now, 3), os.getloadavg()[0], steal_share(prev_cpu, times)))
            prev_cpu, next_sample = times, now + SAMPLE_S
    print(json.dumps({"cpu": cpu, "fifo": fifo, "start": start, "end": time.monotonic(), "wakes": wakes,
                      "late_mean_ms": late_sum / max(wakes, 1), "late_max_ms": late_max, "stalls_total": n_stalls,
                      "stalls": stalls, "samples": samples}))


class HostProbe:
    """The host's figures over a stream (a context manager; :meth:`summary` after the ``with``).

    ``with HostProbe() as hp: ...`` starts the sleeper and reads ``/proc/stat`` and the load; the exit
    stops it and reads them again.

    Args:
        seconds_max: the sleeper ends by itself after this long, s (a caller that dies leaves none).
    """

    def __init__(self, seconds_max: float = 3600.0) -> None:
        self.seconds_max = float(seconds_max)
        self.result: dict[str, Any] = {}
        self._procs: list[subprocess.Popen[str]] = []

    def __enter__(self) -> HostProbe:
        self._cpu0, self._load0, self.t_start = cpu_times(), os.getloadavg(), time.monotonic()
        for i, cpu in enumerate(sorted(os.sched_getaffinity(0))):
            self._procs.append(subprocess.Popen([sys.executable, str(Path(__file__)), str(self.seconds_max), str(cpu),
                                                 str(int(i == 0))], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                                text=True))
        return self

    def __exit__(self, *exc: object) -> None:
        cpu1, load1, self.t_end = cpu_times(), os.getloadavg(), time.monotonic()
        raws: list[dict[str, Any]] = []
        for p in self._procs:
            try:
                out, _ = p.communicate(input="", timeout=60.0)
                raws.append(json.loads(out) if out.strip() else {})
            except (subprocess.TimeoutExpired, json.JSONDecodeError):
                p.kill()
                p.wait()
        steal = steal_share(self._cpu0, cpu1)
        samples = [s for r in raws for s in r.get("samples", [])]
        per_cpu = {f"cpu{r.get('cpu')}": [(float(t), float(ms)) for t, ms in r.get("stalls", [])] for r in raws}
        stalls = sorted(x for v in per_cpu.values() for x in v)
        wakes = sum(r.get("wakes", 0) for r in raws)
        self.result = {
            "cpus": os.cpu_count(), "load_avg": [list(self._load0), list(load1)],
            "steal_share": steal.pop("cpu", 0.0), "steal_share_per_cpu": steal,
            "steal_share_max_per_sample": max((s[2].get("cpu", 0.0) for s in samples), default=0.0),
            "sample_s": SAMPLE_S, "probe_fifo": all(r.get("fifo") for r in raws) if raws else None,
            "probe_period_ms": PROBE_PERIOD_S * 1e3, "probe_sleepers": len(raws),
            "probe_late_mean_ms": sum(r.get("late_mean_ms", 0.0) * r.get("wakes", 0) for r in raws) / max(wakes, 1),
            "probe_late_max_ms": max((r.get("late_max_ms", 0.0) for r in raws), default=None),
            "probe_stalls": sum(r.get("stalls_total", 0) for r in raws),
            "probe_stalls_per_cpu": {k: len(v) for k, v in per_cpu.items()},
            "probe_stalls_on_every_cpu": _on_every(list(per_cpu.values())), "stall_threshold_ms": STALL_MS,
            "_stalls": stalls, "_stalls_per_cpu": per_cpu,
        }

    def stalls(self) -> list[tuple[float, float]]:
        """Every sleeper's stalls, by time: (deadline, CLOCK_MONOTONIC s; how late, ms)."""
        return [(float(t), float(ms)) for t, ms in self.result.get("_stalls", [])]

    def stalls_per_cpu(self) -> dict[int, list[tuple[float, float]]]:
        """Each CPU's sleeper's stalls: {CPU number: [(deadline, CLOCK_MONOTONIC s; how late, ms)]}."""
        return {int(k[3:]): [(float(t), float(ms)) for t, ms in v]
                for k, v in self.result.get("_stalls_per_cpu", {}).items() if k[3:].isdigit()}

    def sleeper_pids(self) -> dict[int, int]:
        """{CPU number: process id} of the sleepers (empty before the ``with``)."""
        return {cpu: p.pid for cpu, p in zip(sorted(os.sched_getaffinity(0)), self._procs, strict=False)}

    def coincident(self, times: Sequence[float], window_s: float = 0.02) -> int:
        """How many of ``times`` (CLOCK_MONOTONIC s) fall within ``window_s`` of a stall of the sleeper.

        A stall covers [deadline, deadline + lateness]; a window missed in it or ``window_s`` around it
        counts.
        """
        spans = [(t - window_s, t + ms * 1e-3 + window_s) for t, ms in self.stalls()]
        return sum(1 for x in times if any(a <= x <= b for a, b in spans))

    def summary(self, origin: float | None = None) -> dict[str, Any]:
        """The figures, JSON-ready; stall times as seconds after ``origin`` (default: the probe's start).

        Keys: ``cpus``, ``load_avg`` ([1, 5, 15 min] at start and end), ``steal_share`` (all CPUs over
        the run, 0..1), ``steal_share_per_cpu``, ``steal_share_max_per_sample`` (the worst
        :data:`SAMPLE_S` interval), ``probe_fifo`` (the sleeper got SCHED_FIFO), ``probe_late_mean_ms``,
        ``probe_late_max_ms``, ``probe_stalls`` (wake-ups later than ``stall_threshold_ms``, every CPU's
        sleeper), ``probe_stalls_per_cpu``, ``probe_stalls_on_every_cpu`` (stalls of the first CPU's sleeper
        that overlap a stall of every other one's), ``probe_stall_at_s`` (the first 50: [s after origin,
        ms late]).
        """
        o = self.t_start if origin is None else origin
        out = {k: v for k, v in self.result.items() if not k.startswith("_")}
        out["probe_stall_at_s"] = [[round(t - o, 3), ms] for t, ms in self.stalls()[:50]]
        return out


def _on_every(per_cpu: list[list[tuple[float, float]]]) -> int:
    """How many stalls of the first list overlap a stall in every other list ((start s, ms) spans)."""
    if len(per_cpu) < 2:
        return len(per_cpu[0]) if per_cpu else 0
    first, rest = per_cpu[0], per_cpu[1:]

    def overlaps(a: tuple[float, float], others: list[tuple[float, float]]) -> bool:
        return any(b[0] <= a[0] + a[1] * 1e-3 and a[0] <= b[0] + b[1] * 1e-3 for b in others)

    return sum(1 for a in first if all(overlaps(a, o) for o in rest))


if __name__ == "__main__":
    with contextlib.suppress(KeyboardInterrupt):
        _probe(float(sys.argv[1]) if len(sys.argv) > 1 else 3600.0, int(sys.argv[2]) if len(sys.argv) > 2 else -1,
               len(sys.argv) <= 3 or sys.argv[3] == "1")
