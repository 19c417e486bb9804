"""The sim's streaming process: owns a MuJoCo workcell and steps it one controller period per wall-clock tick.

This file runs as a script in a child process (:class:`~robointel.interface.sim_stream.SimStreamProcess`
starts it and talks to it) with an interpreter lock of its own, so a planner thread in the caller's
process cannot delay a simulated controller window (docs/design/streaming.md). It
builds the :class:`~robointel.sim.Workcell` from picklable arguments and runs the FANUC streaming
process's loop (:func:`~robointel.interface.stream_child.serve_forever` with its
:class:`~robointel.interface.stream_player.Player`: the look-ahead ring, the window accounting, the
stall stop, the requests) over :class:`SimSide`, a simulated controller with the surface of the
``airo-fanuc`` driver that loop drives.

The simulated controller ticks every ``period`` of CLOCK_MONOTONIC from its start. When its state is
read (``core.get_snapshot()``, at each wake-up of the loop) it first steps the workcell through every
window whose tick has passed: window k tracks the straight line from the target of window k-1 to the
target submitted before tick k (:func:`~robointel.interface.sim.step_window`), or holds the last one
when none came. A window the loop served late is stepped all the same, with the target it had.
"""
from __future__ import annotations

import contextlib
import ctypes
import gc
import importlib
import mmap
import os
import sys
import time
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput, RobointelError, SafetyStop
from robointel.interface import stream_child as sc
from robointel.interface import stream_layout as layout
from robointel.interface.sim import step_window, substeps_of
from robointel.sim.workcell import Workcell

_WRENCH_KEYS = ("fx", "fy", "fz", "mx", "my", "mz")
SLOW_STEP_S, SLOW_STEPS = 0.002, 256
"""A window's physics longer than this (wall time) is remembered with its CPU time, s; how many."""
WAKES = 1 << 18
"""Wake-up delays remembered (9 min at 8 ms; the statistics are of the first this many)."""
_MCL_CURRENT, _MCL_FUTURE = 1, 2


class SimSide:
    """A simulated controller: the workcell stepped at wall-clock ticks (``FanucDriver``'s surface for the loop).

    It is its own ``core`` (``get_snapshot``, ``running``, ``stop``); ``servo_j`` sets the target of the
    next window, ``stop_j`` brakes where the arm is, ``recover`` clears a divergence.

    Args:
        wc: the workcell.
        period: controller period, s (a multiple of the workcell's control period).

    Raises:
        InvalidInput: a period that is not a multiple of the workcell's control period.
    """

    rmi = None

    def __init__(self, wc: Workcell, period: float) -> None:
        self.wc, self.period = wc, float(period)
        self.substeps = substeps_of(self.period, wc.control_dt)
        self.core = self
        self.running = True
        self.has_ft = bool(getattr(wc, "_has_ft", False))
        self.period_ns = int(round(self.period * 1e9))
        self.t0_ns = time.monotonic_ns()  # tick 0
        self.tick = 0
        self.cmd = self.prev = wc.hold_reference  # the target of the next window, of the last one
        self.fault = ""  # why the simulation diverged
        self.step_max_s = 0.0
        self.catch_up_max = 0  # the most windows stepped at one read
        self.slow_steps: list[tuple[float, float, float]] = []  # (CLOCK_MONOTONIC s, wall ms, CPU ms)
        self.wakes_ns: list[int] = []  # each read that found new ticks: how long after the oldest of them, ns
        self.memory_locked = False
        self._snap: dict[str, Any] | None = None

    # ------------------------------------------------------------------ the core
    def get_snapshot(self) -> dict[str, Any]:
        """Step every window whose tick has passed, then the state as ``core.get_snapshot()`` keys."""
        if self.running:
            now = time.monotonic_ns()
            due = (now - self.t0_ns) // self.period_ns
            if due > self.tick:
                if len(self.wakes_ns) < WAKES:
                    self.wakes_ns.append(now - self.t0_ns - (self.tick + 1) * self.period_ns)  # the oldest new tick
                self.catch_up_max = max(self.catch_up_max, due - self.tick)
                while self.tick < due:
                    self._window()
                    self.tick += 1
                self._snap = None
        if self._snap is None:
            self._snap = self._snapshot()
        return self._snap

    def _window(self) -> None:
        t, c = time.perf_counter(), time.thread_time()
        try:
            step_window(self.wc, self.prev, self.cmd, self.period, self.substeps)
        except SafetyStop as exc:
            self.fault = str(exc) or "the simulation diverged"
        self.prev = self.cmd
        wall = time.perf_counter() - t
        self.step_max_s = max(self.step_max_s, wall)
        if wall > SLOW_STEP_S and len(self.slow_steps) < SLOW_STEPS:  # CPU << wall: the thread was not running
            self.slow_steps.append((round(time.monotonic() - wall, 4), round(wall * 1e3, 3),
                                    round((time.thread_time() - c) * 1e3, 3)))

    def _snapshot(self) -> dict[str, Any]:
        wc, ns = self.wc, self.t0_ns + self.tick * self.period_ns
        bad = bool(self.fault)
        snap: dict[str, Any] = {"cmd_tick": self.tick, "tick_mono_ns": ns, "rx_mono_ns": ns, "mode": 0,
                                "fault": int(bad), "e_stopped": False, "in_error": bad, "tp_enabled": False,
                                "motion_possible": not bad, "wrench_valid": self.has_ft, "active_motion_id": 0,
                                "active_motion_status": 0, "q_meas": wc.q.tolist(), "qd_est": wc.qd.tolist(),
                                "q_cmd": self.cmd.tolist()}
        w = wc.ft_reading() if self.has_ft else np.zeros(6)
        snap.update(zip(_WRENCH_KEYS, w.tolist(), strict=True))
        return snap

    def start(self) -> None:
        """Tick 0 is now (the bring-up's time is not simulated)."""
        self.t0_ns, self.tick, self._snap = time.monotonic_ns(), 0, None

    def stop(self) -> None:
        """Stop ticking (the loop's close)."""
        self.running = False

    # ------------------------------------------------------------------ the driver
    def servo_j(self, q: npt.NDArray[np.float64], duration: float) -> None:
        """The target of the next window, (n,) rad.

        Raises:
            SafetyStop: the simulation has diverged (refused until :meth:`recover`).
        """
        if self.fault:
            raise SafetyStop(f"the simulation diverged: {self.fault}", value=q)
        self.cmd = np.array(q, dtype=float)
        self._snap = None

    def hold(self) -> None:
        """Nothing to do: a window without a new target holds the last one."""

    def stop_j(self) -> None:
        """Brake: hold the measured position from the next window on."""
        self.cmd = self.prev = self.wc.q
        self._snap = None

    def kick(self) -> None:
        """No deadman in the simulation."""

    def recover(self, escalate_reconnect: bool = False) -> bool:
        """Clear a divergence; hold the workcell's held reference."""
        self.fault = ""
        self.cmd = self.prev = self.wc.hold_reference
        self._snap = None
        return True

    def arm(self) -> None:
        """Nothing to arm."""

    def timing_stats(self) -> dict[str, Any]:
        """The child's physics figures.

        ``tick_count``, ``step_max_ms`` (the longest window's physics), ``catch_up_max_windows``,
        ``slow_steps`` (windows whose physics took more than :data:`SLOW_STEP_S` of wall time: [start,
        CLOCK_MONOTONIC s; wall ms; CPU ms of this thread]), ``wake_after_tick_ms`` (how long after a
        tick the loop's read found it, from the oldest tick not yet stepped: p50, p99, p99.9, max, and how
        many reads came a period or more late: a window stepped late), ``memory_locked`` (``mlockall`` succeeded).
        """
        w = np.asarray(self.wakes_ns, dtype=float) * 1e-6
        wake = ({"p50": float(np.percentile(w, 50)), "p99": float(np.percentile(w, 99)),
                 "p999": float(np.percentile(w, 99.9)), "max": float(w.max()), "reads": len(w),
                 "over_period": int(np.sum(w >= self.period * 1e3))} if len(w) else {})
        return {"tick_count": self.tick, "step_max_ms": self.step_max_s * 1e3,
                "catch_up_max_windows": int(self.catch_up_max), "slow_steps": [list(x) for x in self.slow_steps],
                "wake_after_tick_ms": wake, "memory_locked": self.memory_locked}

    def close(self) -> None:
        """Nothing to release."""


def build_workcell(workcell_kwargs: dict[str, Any], factory: str | None, factory_args: tuple[Any, ...]) -> Workcell:
    """``Workcell(**workcell_kwargs)``, or ``module:function`` ``factory`` called with ``factory_args``.

    A factory may return the workcell or a tuple whose first item is the workcell (as
    :func:`~robointel.skills.cells.peg_hole_workcell` does).

    Raises:
        InvalidInput: a factory that is not ``module:function``, cannot be imported or gives no workcell.
    """
    if factory is None:
        return Workcell(**workcell_kwargs)
    mod, _, name = factory.partition(":")
    try:
        fn = getattr(importlib.import_module(mod), name)
    except (ImportError, AttributeError, ValueError) as exc:
        raise InvalidInput(f"workcell factory {factory!r} not found: {exc}", value=factory) from None
    wc = fn(*factory_args)
    wc = wc[0] if isinstance(wc, tuple) else wc
    if not isinstance(wc, Workcell):
        raise InvalidInput(f"workcell factory {factory!r} gave a {type(wc).__name__}, not a Workcell", value=factory)
    return wc


def lock_all_memory() -> bool:
    """``mlockall(MCL_CURRENT | MCL_FUTURE)``: no page of this process is paged out or faulted in late.

    Returns:
        False when refused (without CAP_IPC_LOCK the RLIMIT_MEMLOCK, often 8 MB, is far below the
        few hundred MB of an interpreter with MuJoCo and Pinocchio); the process goes on unlocked.
    """
    try:
        return ctypes.CDLL(None, use_errno=True).mlockall(_MCL_CURRENT | _MCL_FUTURE) == 0
    except (OSError, AttributeError):
        return False


def main(conn_fd: int, shm_fd: int, wake_fd: int = -1) -> None:
    """Entry point of the child: build the workcell, report, serve until closed."""
    conn, buf = Connection(conn_fd), np.frombuffer(mmap.mmap(shm_fd, layout.SHM_BYTES), dtype=np.float64)
    workcell_kwargs, q0, factory, factory_args, lock_memory, base_ns, period, stall_periods = conn.recv()
    with contextlib.suppress(OSError):  # PermissionError without CAP_SYS_NICE
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(sc.PRIORITY))
    try:
        wc = build_workcell(workcell_kwargs, factory, factory_args)
        if q0 is not None:
            wc.reset(q0)
        side = SimSide(wc, period)
    except (RobointelError, TypeError, ValueError) as exc:
        conn.send((False, (type(exc).__name__, str(exc))))
        return
    gc.collect()
    gc.freeze()
    gc.disable()  # the serve loop collects between ticks (stream_child.GC_TICKS)
    sys.setswitchinterval(0.0005)
    side.memory_locked = lock_memory and lock_all_memory()
    side.start()
    conn.send((True, {"t0": wc.time, "has_ft": side.has_ft, "tick0_ns": side.t0_ns}))
    sc.serve_forever(conn, buf, side, base_ns, period, stall_periods, wake_fd, refusals=(SafetyStop,))


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:4]))
