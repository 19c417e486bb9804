"""The streaming process's player: the ring's targets, interpolated and submitted at the controller's ticks.

:class:`Player` runs in the streaming process (:mod:`robointel.interface.stream_child`'s loop, for the
FANUC driver and the sim's child alike). The caller writes targets into the ring
(:mod:`robointel.interface.stream_layout`), each stamped with its arrival and the time it is to be
played (its *slot*: arrival + the look-ahead, then one period apart). At each core tick (``cmd_tick``)
the player interpolates them at the next tick's time and submits the result (``servo_j``). A window is
*fresh* (a target was there), *starved* (the caller was late by more than the look-ahead), *late*
(the process submitted after the tick) or *core-late* (the core sent the tick late while the process
polled for it, counted apart). A *direct* target (slot = arrival: look-ahead 0, a force loop) is
submitted as soon as the caller's eventfd wakes the process, the newest first. State and counters
return in the seqlock block. Like the streaming process's script, this module imports only the
standard library, numpy and ``airo_fanuc``.
"""
from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import numpy.typing as npt
from airo_fanuc.exceptions import FanucError

from robointel.interface.stream_layout import (
    H_CUT,
    H_HOLD,
    H_HOLD_GEN,
    H_READ,
    H_VERSION,
    H_WRITE,
    NDOF,
    RING,
    RING_OFF,
    SLOT_WIDTH,
    STATE_INDEX,
)

CORE_LATE_MARGIN_S, CATCH_UP_S = 0.0002, 0.001
"""A tick not there this long after it was due, and the next within CATCH_UP_S of that poll: core-late, s."""
EVENTS = 512  # missed windows remembered for the ``missed_events`` request
_SNAP_SCALARS = ("cmd_tick", "mode", "fault", "e_stopped", "in_error", "tp_enabled", "motion_possible",
                 "wrench_valid", "active_motion_id", "active_motion_status")


class Player:
    """Plays the targets of the ring at the controller's ticks (runs in the streaming process).

    Args:
        buf: the (SHM_DOUBLES,) shared array.
        base_ns: CLOCK_MONOTONIC origin of every time in ``buf``, ns.
        period: controller period, s.
        stall_periods: stop the robot after this many consecutive starved windows.
        driver: the ``FanucDriver`` (anything with ``servo_j``, ``hold``, ``stop_j``, ``core``).
        refusals: what the driver's ``servo_j`` raises when it refuses a target (the segment is dropped).
    """

    def __init__(self, buf: npt.NDArray[np.float64], base_ns: int, period: float, stall_periods: int,
                 driver: Any, refusals: tuple[type[Exception], ...] = (FanucError,)) -> None:
        self.buf, self.base_ns, self.period, self.refusals = buf, int(base_ns), float(period), refusals
        self.stall_periods, self.driver = int(stall_periods), driver
        self.pending: list[tuple[int, float, float, npt.NDArray[np.float64]]] = []
        self.active = self.direct = False  # a queued (look-ahead) / a direct segment plays
        self.hold_gen, self.last_tick, self.last_tick_s = 0, -1, 0.0
        self.empty_poll_s = -math.inf  # the last wake-up that found no new tick
        self.wake_s = self.prev_wake_s = 0.0  # this wake-up's time and the previous one's
        self.sched: tuple[int, ...] = (0, 0, 0, 0, 0)  # on a CPU, runnable (ns), runs, page faults, preemptions
        self.prev_sched: tuple[int, ...] = self.sched
        self.waited_s = 0.0  # the poll timeout asked for before this wake-up
        self.consec_starved = self._read_upto = 0
        self._last_arrival = -math.inf
        self.events: list[tuple[str, float, int, float, float, float, int, float, float, int, int]] = []
        self.counters = {"windows": 0, "fresh": 0, "starved": 0, "late": 0, "submits": 0, "last_submit_s": 0.0,
                         "stalled": 0, "stall_gap_s": 0.0, "refused": 0, "core_late": 0, "direct_submits": 0,
                         "direct_latency_max_s": 0.0, "direct_latency_sum_s": 0.0, "gc_max_s": 0.0, "holds": 0}

    def rel(self, ns: int) -> float:
        """Seconds after the base."""
        return (int(ns) - self.base_ns) * 1e-9

    # ------------------------------------------------------------------ shared memory
    def publish(self, snap: dict[str, Any], running: bool) -> None:
        """Write the core's snapshot and the counters into the seqlock block."""
        b, ix = self.buf, STATE_INDEX
        b[H_VERSION] += 1  # odd: writing
        b[ix["published_s"]] = self.rel(time.monotonic_ns())
        b[ix["rx_s"]] = self.rel(int(snap.get("rx_mono_ns", 0)))
        b[ix["tick_s"]] = self.rel(int(snap.get("tick_mono_ns", 0)))
        for k in _SNAP_SCALARS:
            b[ix[k]] = float(snap.get(k, 0))
        b[ix["running"]] = float(running)
        for k in ("q_meas", "qd_est", "q_cmd"):
            b[ix[k]] = snap.get(k, [0.0] * NDOF)
        b[ix["wrench"]] = [float(snap.get(k, 0.0)) for k in ("fx", "fy", "fz", "mx", "my", "mz")]
        for k, v in self.counters.items():
            b[ix[k]] = v
        b[H_READ] = float(self._read_upto)
        b[H_VERSION] += 1  # even: consistent

    def consume(self) -> None:
        """Move the targets the caller wrote since the last call into ``pending`` (dropping cut ones)."""
        b = self.buf
        w, cut = int(b[H_WRITE]), int(b[H_CUT])
        for idx in range(max(self._read_upto, cut), w):
            o = RING_OFF + (idx % RING) * SLOT_WIDTH
            self.pending.append((idx, float(b[o]), float(b[o + 1]), np.array(b[o + 2:o + SLOT_WIDTH])))
        self._read_upto = max(self._read_upto, w)
        if cut > 0 and self.pending and self.pending[0][0] < cut:
            self.pending = [p for p in self.pending if p[0] >= cut]

    def discard(self) -> None:
        """Drop every pending target and end the segment (a stop, a fault, a trajectory)."""
        self.consume()
        self.pending.clear()
        self.active = self.direct = False
        self.consec_starved = 0

    def _event(self, kind: str, t: float, tick: int, late_s: float) -> None:
        """Remember a missed window, how late (``RingProcess.missed_events``), what this thread did over the gap."""
        (c0, r0, n0, f0, p0), (c1, r1, n1, f1, p1) = self.prev_sched, self.sched
        self.events.append((kind, t, tick, round((self.wake_s - self.prev_wake_s) * 1e3, 3),
                            round((c1 - c0) * 1e-6, 3), round((r1 - r0) * 1e-6, 3), n1 - n0,
                            round(self.waited_s * 1e3, 3), round(late_s * 1e3, 3), f1 - f0, p1 - p0))
        del self.events[:-EVENTS]

    # ------------------------------------------------------------------ one controller window
    def serve(self, snap: dict[str, Any]) -> None:
        """Called once per new core tick: submit the interpolated target for the next tick."""
        tick = int(snap["cmd_tick"])
        self.consume()
        if _faulted(snap):
            if self.active or self.direct or self.pending:
                self.discard()
                self.driver.stop_j()
            self._seen(tick, snap)
            return
        if self.direct or (not self.active and self.pending and _is_direct(self.pending[0])):
            self._direct_tick(snap, tick)
            self.serve_direct(snap)
            return
        tau = self.rel(int(snap["tick_mono_ns"])) + self.period  # the next tick's time
        gen, hold_at = int(self.buf[H_HOLD_GEN]), int(self.buf[H_HOLD])
        hold = gen > self.hold_gen  # a hold after the target hold_at - 1 is pending
        seg_end = hold_at - 1 if hold else math.inf
        seg = [p for p in self.pending if p[0] <= seg_end and not _is_direct(p)]
        if not self.active:
            if seg and seg[0][1] <= tau + 1e-9:
                self.active = True
                self.last_tick = tick - 1
            elif hold and not seg:
                self._hold(gen, hold_at)
            if not self.active:
                self._seen(tick, snap)
                return
        c = self.counters
        self._count_skipped(tick, snap)
        if not seg:  # the segment ended with a hold
            self._hold(gen, hold_at)
            return
        while len(seg) >= 2 and seg[1][1] <= tau + 1e-9:
            seg.pop(0)
            self.pending.pop(0)
        a = seg[0]
        if len(seg) >= 2:
            b_ = seg[1]
            s = min(1.0, max(0.0, (tau - a[1]) / (b_[1] - a[1])))
            q = a[3] + (b_[3] - a[3]) * s
        elif a[1] >= tau - 1e-9:
            q = a[3]
        elif hold:  # the last target before a hold has been played
            self._hold(gen, hold_at)
            return
        else:  # starved: the caller has not delivered the target for this window
            c["windows"] += 1
            c["starved"] += 1
            self._event("starved", tau, tick, tau - a[1])
            self._starved(1, tau - a[1])
            return  # the servo keeps heading for the last target
        c["windows"] += 1
        c["fresh"] += 1
        self.consec_starved = 0
        self._submit(q, tick)

    def _seen(self, tick: int, snap: dict[str, Any]) -> None:
        self.last_tick, self.last_tick_s = tick, self.rel(int(snap["tick_mono_ns"]))

    def _count_skipped(self, tick: int, snap: dict[str, Any]) -> None:
        """Count the windows between the last tick served and ``tick`` (slept through, or core-late)."""
        c = self.counters
        gap = tick - self.last_tick - 1
        if gap > 0 and self.last_tick >= 0:
            # tick j was due at last_tick_s + j periods: when a poll after that found it missing and the
            # tick now seen came within CATCH_UP_S of that poll, the core sent both in one burst
            due = [self.last_tick_s + j * self.period for j in range(1, gap + 1)]
            burst = self.rel(int(snap["tick_mono_ns"])) - self.empty_poll_s <= CATCH_UP_S
            core = sum(1 for d in due if self.empty_poll_s > d + CORE_LATE_MARGIN_S) if burst else 0
            c["core_late"] += core
            c["late"] += gap - core
            c["windows"] += gap
            late = self.wake_s - due[0] - self.period  # the first window skipped ended a period after its tick
            self._event("late" if gap > core else "core_late", self.rel(int(snap["tick_mono_ns"])), tick, late)
        self._seen(tick, snap)

    def _starved(self, n: int, gap_s: float) -> None:
        self.consec_starved += n
        if self.consec_starved >= self.stall_periods:
            self.driver.stop_j()
            self.counters["stalled"], self.counters["stall_gap_s"] = 1, gap_s
            self.discard()

    def _hold(self, gen: int, hold_at: int) -> None:
        self.pending = [p for p in self.pending if p[0] >= hold_at]
        self.hold_gen = self.counters["holds"] = gen  # published: the caller's hold has been played
        self.active = self.direct = False
        self.consec_starved = 0
        self.driver.hold()

    # ------------------------------------------------------------------ the direct stream
    def _direct_tick(self, snap: dict[str, Any], tick: int) -> None:
        """Count the window that ended at ``tick`` of a direct stream (before submitting what arrived)."""
        if not self.direct:
            self._seen(tick, snap)
            return
        c = self.counters
        t_tick = self.rel(int(snap["tick_mono_ns"]))
        prev_s = self.last_tick_s
        self._count_skipped(tick, snap)
        c["windows"] += 1
        if c["last_submit_s"] > prev_s:
            c["fresh"] += 1
            self.consec_starved = 0
        elif any(p[2] <= t_tick for p in self.pending if _is_direct(p)):
            c["late"] += 1  # a target had arrived: this process submitted it after the tick
            self._event("late", t_tick, tick, self.wake_s - t_tick)
        else:
            c["starved"] += 1
            self._event("starved", t_tick, tick, t_tick - self._last_arrival)
            self._starved(1, t_tick - self._last_arrival)

    def serve_direct(self, snap: dict[str, Any]) -> None:
        """Submit the newest direct target that arrived (called at every wake-up); hold at a hold mark."""
        if self.active or not self.pending and not self.direct:
            return
        if _faulted(snap):
            return  # the tick's serve stops the robot
        gen, hold_at = int(self.buf[H_HOLD_GEN]), int(self.buf[H_HOLD])
        hold = gen > self.hold_gen
        if hold and self.pending and self.pending[0][0] >= hold_at and not self.direct:
            self.hold_gen = self.counters["holds"] = gen  # a hold before this segment: nothing of it to play
            hold = False
        run = []
        for p in self.pending:
            if not _is_direct(p) or (hold and p[0] >= hold_at):
                break
            run.append(p)
        if run:
            del self.pending[:len(run)]
            newest = run[-1]
            self.direct = True
            self._last_arrival = newest[2]
            self._submit(newest[3], int(snap["cmd_tick"]), arrival=newest[2])
        if hold and self.direct and not any(p[0] < hold_at for p in self.pending):
            self._hold(gen, hold_at)

    def _submit(self, q: npt.NDArray[np.float64], tick: int, arrival: float | None = None) -> None:
        c = self.counters
        try:
            self.driver.servo_j(q, self.period)
        except self.refusals:
            c["refused"] = 1
            self.discard()
            return
        now = time.monotonic_ns()
        c["submits"] += 1
        c["last_submit_s"] = self.rel(now)
        if arrival is not None:
            lat = c["last_submit_s"] - arrival
            c["direct_submits"] += 1
            c["direct_latency_sum_s"] += lat
            c["direct_latency_max_s"] = max(c["direct_latency_max_s"], lat)
            return
        snap = self.driver.core.get_snapshot()
        after = int(snap["cmd_tick"])
        if after != tick:  # the tick this target was for went out before it arrived
            c["fresh"] -= 1
            kind = "core_late" if self.rel(int(snap["tick_mono_ns"])) - self.last_tick_s < 0.5 * self.period else "late"
            c[kind] += 1
            self._event(kind, self.last_tick_s, tick, c["last_submit_s"] - self.last_tick_s - self.period)
            self._seen(after, snap)


def _is_direct(p: tuple[int, float, float, npt.NDArray[np.float64]]) -> bool:
    """A target of a direct stream: its play time is its arrival (look-ahead 0)."""
    return p[1] <= p[2]


def _faulted(snap: dict[str, Any]) -> bool:
    """True when the controller or the core reports anything that forbids motion."""
    return bool(snap.get("e_stopped") or snap.get("in_error") or snap.get("tp_enabled")
                or int(snap.get("fault", 0)) != 0 or not snap.get("motion_possible", False))
