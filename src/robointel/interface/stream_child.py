"""The streaming process: owns the robot's real-time side and plays time-stamped targets at the ticks.

This file runs as a script in the FANUC driver's child process (:mod:`robointel.interface.stream_process`
starts it; it imports only the standard library, numpy, ``airo_fanuc`` and the streaming modules
:mod:`~robointel.interface.stream_layout` and :mod:`~robointel.interface.stream_player`, and has its own
interpreter lock); the sim's child (:mod:`robointel.interface.sim_child`) runs its loop too. The loop
(:func:`serve_forever`) wakes at each core tick, at each request of the caller, at the caller's eventfd after
a direct target and every 2 ms to publish the state; the :class:`~robointel.interface.stream_player.Player`
submits the targets of the ring (the shared memory of :mod:`~robointel.interface.stream_layout`) and counts
the windows.
"""
from __future__ import annotations

import contextlib
import gc
import logging
import mmap
import os
import resource
import select
import sys
import threading
import time
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
import numpy.typing as npt
from airo_fanuc import FanucDriver
from airo_fanuc.exceptions import FanucConnectionError, FanucError

from robointel.interface.stream_layout import SHM_BYTES
from robointel.interface.stream_player import Player

PRIORITY = 60
"""SCHED_FIFO priority of this process's threads (below the core's 80, above the emulator's 50, a caller's 40)."""
GC_TICKS = 125
"""Automatic GC is off; the loop collects the young generations every this many ticks, just after one."""


def stop_core_between_ticks(driver: Any, period: float, attempts: int = 25) -> None:
    """End the Stream Motion session with its terminal packet in the middle of a tick window.

    ``FanucDriver.close`` from another thread may race the core's own command for the window (a
    double send): the core is quiesced (``stop_j``) and stopped half a period after one of its ticks.

    Args:
        driver: the ``FanucDriver``.
        period: controller period, s.
        attempts: windows to try before stopping anyway.
    """
    core = driver.core
    if core is None or not core.running:
        return
    driver.stop_j()
    period_ns = int(period * 1e9)
    last = int(core.get_snapshot()["tick_mono_ns"])
    for _ in range(attempts):
        while True:  # wait for the next tick
            tick = int(core.get_snapshot()["tick_mono_ns"])
            if tick != last or time.monotonic_ns() - last > 4 * period_ns:
                break
            time.sleep(0.0002)
        last = tick
        mid = tick + period_ns // 2
        now = time.monotonic_ns()
        if now > mid - period_ns // 4:
            continue  # woke too late in this window: take the next one
        rem = (mid - now) * 1e-9
        if rem > 0.0003:
            time.sleep(rem - 0.0003)
        while time.monotonic_ns() < mid:
            pass
        if time.monotonic_ns() < tick + 3 * period_ns // 4:
            break
    core.stop()


def serve_forever(conn: Connection, buf: npt.NDArray[np.float64], driver: Any, base_ns: int, period: float,
                  stall_periods: int, wake_fd: int = -1, *, request: Any = None,
                  refusals: tuple[type[Exception], ...] = (FanucError,)) -> None:
    """The streaming process's loop: one :meth:`Player.serve` per tick, requests from the caller between.

    Every wake-up (a tick, a request, the caller's eventfd ``wake_fd`` after a direct target, or the
    2 ms publishing timer) submits the newest direct target that arrived (:meth:`Player.serve_direct`).
    Returns when the caller asks to close or its end of the connection is gone (it died): the core
    is stopped between ticks and the driver closed either way. ``request`` (``_request``'s signature;
    default: the FANUC driver's) answers the caller's requests; ``refusals`` go to :class:`Player`.
    """
    player = Player(buf, base_ns, period, stall_periods, driver, refusals)
    request = _request if request is None else request
    handles: dict[int, Any] = {}
    core = driver.core
    seen = -1
    poller = select.poll()
    poller.register(conn.fileno(), select.POLLIN)
    if wake_fd >= 0:
        poller.register(wake_fd, select.POLLIN)
    stat_fd = os.open("/proc/thread-self/schedstat", os.O_RDONLY)
    served = 0
    try:
        while True:
            running = core is not None and core.running
            t_read = player.rel(time.monotonic_ns())  # before the read: no tick by then, if none in it
            player.prev_wake_s, player.wake_s = player.wake_s, t_read
            ru = resource.getrusage(resource.RUSAGE_THREAD)
            player.prev_sched, player.sched = player.sched, (*map(int, os.pread(stat_fd, 96, 0).split()),
                                                             ru.ru_minflt + ru.ru_majflt, ru.ru_nivcsw)
            snap = core.get_snapshot() if core is not None else {}
            if running and int(snap["cmd_tick"]) != seen:
                player.serve(snap)
                snap = core.get_snapshot()
                seen = int(snap["cmd_tick"])
                served += 1
                if served % GC_TICKS == 0:  # just after a tick: the window's remaining ~7 ms are ahead
                    g0 = time.perf_counter()
                    gc.collect(1)
                    player.counters["gc_max_s"] = max(player.counters["gc_max_s"], time.perf_counter() - g0)
            elif running:
                player.empty_poll_s = t_read
                player.consume()
                player.serve_direct(snap)
            player.publish(snap, running)
            if running:  # wake 0.3 ms after the next tick, and every 2 ms to publish the state
                nxt = int(snap["tick_mono_ns"]) + int(period * 1e9) + 300_000
                wait = min(0.002, max(0.0002, (nxt - time.monotonic_ns()) * 1e-9))
            else:
                wait = period
            player.waited_s = wait
            ready = {fd for fd, _ in poller.poll(wait * 1e3)}
            if wake_fd in ready:
                with contextlib.suppress(BlockingIOError):
                    os.eventfd_read(wake_fd)
            if conn.fileno() not in ready:
                continue
            try:
                name, args, kwargs, reply = conn.recv()
            except (EOFError, OSError):
                return  # the caller is gone
            if name == "close":
                break
            try:
                value = request(name, args, kwargs, driver, player, handles, core)
                if reply:
                    conn.send((True, value))
            except Exception as exc:  # reported to the caller; the stream goes on
                if reply:
                    conn.send((False, (type(exc).__name__, str(exc))))
    finally:
        os.close(stat_fd)
        try:
            stop_core_between_ticks(driver, period)
        finally:
            driver.close()
            player.publish(core.get_snapshot() if core is not None else {}, False)
    conn.send((True, None))


def _request(name: str, args: tuple, kwargs: dict, driver: Any, player: Player, handles: dict[int, Any],
             core: Any) -> Any:
    """Carry out one request of the caller (see :class:`~robointel.interface.stream_process.StreamProcess`)."""
    if name in ("kick", "stop_j"):
        if name == "stop_j":
            player.discard()
        getattr(driver, name)()
        return None
    if name == "recover":
        player.discard()
        player.counters.update(stalled=0, stall_gap_s=0.0, refused=0)
        ok = driver.recover(escalate_reconnect=False)
        driver.arm()
        return bool(ok)
    if name == "move_trajectory":
        player.discard()
        h = driver.move_trajectory(*args, **kwargs)
        handles[h.motion_id] = h
        return h.motion_id
    if name in ("motion_done", "motion_result"):
        h = handles[args[0]]
        return bool(h.done()) if name == "motion_done" else getattr(h.result(), "value", None)  # None: it runs
    if name in ("timing_stats", "missed_events", "threads"):  # threads: {native id: name}, who is who in /proc
        return (dict(driver.timing_stats()) if name == "timing_stats" else list(player.events)
                if name == "missed_events" else {t.native_id: t.name for t in threading.enumerate()})
    if name in ("rmi_write_register", "rmi_read_register"):
        if driver.rmi is None:
            raise FanucConnectionError("no RMI session")
        return getattr(driver.rmi, name[4:])(*args)
    if name == "alarms":  # the controller's active alarm texts (FRC_ReadError), for the fault's reason
        return [] if driver.rmi is None else list(driver.rmi.read_error(int(args[0]) if args else 3).messages)
    raise ValueError(f"unknown request {name!r}")


def main(conn_fd: int, shm_fd: int, wake_fd: int = -1) -> None:
    """Entry point of the child: bring the driver up, report, serve until closed."""
    conn, buf = Connection(conn_fd), np.frombuffer(mmap.mmap(shm_fd, SHM_BYTES), dtype=np.float64)
    host, policy, base_ns, period, stall_periods = conn.recv()
    # Before bring-up, so that the driver's Python threads inherit it (preempted at normal priority while
    # holding the interpreter lock they would delay this thread); the core's thread sets its own FIFO 80.
    with contextlib.suppress(OSError):  # PermissionError without CAP_SYS_NICE
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(PRIORITY))
    # the driver logs each failed bring-up attempt; the caller reports the cause in one line instead
    logging.getLogger("airo_fanuc").addHandler(logging.NullHandler())
    logging.getLogger("airo_fanuc").propagate = False
    try:
        driver = FanucDriver(host, policy)
    except Exception as exc:  # any failure (a reply that is not RMI's too) goes back as one message, no traceback
        conn.send((False, (type(exc).__name__, str(exc))))
        return
    gc.collect()
    gc.freeze()
    gc.disable()  # the serve loop collects between ticks (GC_TICKS)
    sys.setswitchinterval(0.0005)
    conn.send((True, None))
    serve_forever(conn, buf, driver, base_ns, period, stall_periods, wake_fd)


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:4]))
