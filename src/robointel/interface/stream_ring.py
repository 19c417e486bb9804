"""The caller's end of a streaming process: the look-ahead ring, the seqlock state block, requests.

A Python thread that streams one target per period shares its interpreter lock with every other thread of its
process; a planner thread holding the lock while the kernel preempts it delays the stream by a scheduling
latency (docs/design/streaming.md). A streaming process moves the per-window work out of the caller's
interpreter: a child process (:func:`~robointel.interface.stream_child.serve_forever` with a
:class:`~robointel.interface.stream_player.Player`) owns the robot's real-time side, and each target the
caller streams is stamped with the time it is to be played, ``lookahead_s`` after it arrived (then one period
after the previous one), and written into a ring in shared memory (:mod:`robointel.interface.stream_layout`).
At each controller tick the child interpolates the targets at the tick's time and submits the result, so a
stall of the caller shorter than the look-ahead costs no window; the price is ``lookahead_s`` of added
latency. With a look-ahead of 0 (:meth:`RingProcess.set_lookahead`, what a force loop asks for) each target is
submitted as soon as the child wakes for it (an eventfd the caller writes): no queue, no interpolation, one
wake-up of latency.

:class:`RingProcess` is what every backend's streaming process shares (the FANUC driver's,
:class:`~robointel.interface.stream_process.StreamProcess`; the simulated cell's,
:class:`~robointel.interface.sim_stream.SimStreamProcess`): it starts the child script, sends it
its bring-up arguments, and offers the ring, the block and the requests. A subclass names the
errors: :attr:`RingProcess.LOST` for a child that is gone, :meth:`RingProcess.remote_error` for one
the child reported.
"""
from __future__ import annotations

import mmap
import os
import socket
import struct
import subprocess
import sys
import threading
import time
from multiprocessing.connection import Connection
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from robointel.errors import ConnectionLost, InvalidInput
from robointel.interface import stream_layout as layout
from robointel.interface import stream_state

START_TIMEOUT_S = 60.0
"""Bring-up of the child (interpreter start, imports, driver bring-up), s."""
FIRST_STATUS_TIMEOUT_S = 5.0
"""After bring-up, the child must publish a state from a received controller status within this, s."""
REPLY_TIMEOUT_S = 30.0
"""A request to the child (recovery ladders included), s."""
ALIVE_FRESH_S = 0.02
"""A child that published its state this recently is running (it publishes at least every 2 ms while it
serves); an older state is checked with ``waitpid``, s."""

_CHILD = ("import runpy, sys; sys.path.pop(0); sys.argv = sys.argv[1:]; "
          "runpy.run_path(sys.argv[0], run_name='__main__')")
_R, _RX = stream_state.R, stream_state.RX
_PUBLISHED = layout.STATE_INDEX["published_s"].start
_HEAD = struct.Struct(f"={stream_state.HEAD}d")
_SLOT = struct.Struct(f"={layout.SLOT_WIDTH}d")
"""One ring slot as written by :meth:`RingProcess.servo_j`: play time, arrival, the target."""


class RingProcess:
    """A child process that plays streamed targets from a look-ahead ring (the caller's end).

    Args:
        script: the child's script (run as ``__main__``; it gets the socket, memory and eventfd numbers).
        hello: the bring-up arguments sent first (picklable); ``(base_ns, period, stall_periods)``
            follow them.
        period: controller period, s.
        lookahead_s: delay between a target's arrival and its play time, s (0: direct; at most 1).
        stall_periods: the child stops the robot after this many consecutive windows without a target.
        path: a directory put first on the child's ``PYTHONPATH`` (the package the script imports).

    Raises:
        InvalidInput: a look-ahead or stall count out of range.
        Exception: what :meth:`remote_error` makes of the child's bring-up failure, or :attr:`LOST`.
    """

    LOST: ClassVar[type[Exception]] = ConnectionLost
    """Raised when the child is gone or does not answer."""
    ERRORS: ClassVar[tuple[type[Exception], ...]] = (ConnectionLost,)
    """What :meth:`call` may raise (:meth:`stop_j` swallows these)."""
    START_S: ClassVar[float] = START_TIMEOUT_S
    """How long the child's bring-up may take, s."""

    def __init__(self, script: str, hello: tuple[Any, ...], *, period: float, lookahead_s: float,
                 stall_periods: int, path: str | None = None) -> None:
        check_lookahead(lookahead_s)
        if int(stall_periods) < 1:
            raise InvalidInput(f"stall_periods must be >= 1, got {stall_periods}", value=stall_periods)
        self.period, self.lookahead_s = float(period), float(lookahead_s)
        self._stream_lookahead = self.lookahead_s  # the running stream's (set_lookahead applies at the next)
        self.base_ns = time.monotonic_ns()
        self._lock = threading.Lock()
        self._closed = False
        self._last_slot: float | None = None
        self._prev_slot = -np.inf
        fd = os.memfd_create("robointel-stream")
        self._wake = os.eventfd(0, os.EFD_NONBLOCK | os.EFD_CLOEXEC)  # a direct target is waiting
        try:
            os.ftruncate(fd, layout.SHM_BYTES)
            self._mm = mmap.mmap(fd, layout.SHM_BYTES)
            self._buf: npt.NDArray[np.float64] = np.frombuffer(self._mm, dtype=np.float64)
            self._mv = memoryview(self._mm).cast("d")  # the per-target path: no numpy call (docs/design/streaming.md)
            ours, theirs = socket.socketpair()
            self._conn = Connection(ours.detach())
            env = None
            if path is not None:
                env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (path, os.environ.get("PYTHONPATH"))
                                                                  if p))
            try:
                self._proc = subprocess.Popen([sys.executable, "-c", _CHILD, script, str(theirs.fileno()),
                                               str(fd), str(self._wake)], pass_fds=(theirs.fileno(), fd, self._wake),
                                              env=env)
            finally:
                theirs.close()
        finally:
            os.close(fd)
        try:
            self._conn.send((*hello, self.base_ns, self.period, int(stall_periods)))
            self.hello_reply = self._reply(self.START_S, "bring-up")
            """What the child answered at bring-up (None for the FANUC driver)."""
            self._await_first_status(FIRST_STATUS_TIMEOUT_S)
        except BaseException:
            self._kill()
            raise

    def remote_error(self, kind: str, message: str) -> Exception:
        """The exception to raise for an error of class name ``kind`` the child reported."""
        return self.LOST(f"{kind}: {message}")

    def _await_first_status(self, timeout_s: float) -> None:
        """Return once the child has published a state built from a received status (never the zeroed block).

        Raises:
            ConnectionLost: no such state within ``timeout_s`` (the child died or no status came).
        """
        deadline = time.monotonic() + timeout_s
        while self.values()[_RX] <= 0.0:
            if not self.alive() or time.monotonic() > deadline:
                raise ConnectionLost(f"the streaming process published no controller status within {timeout_s:.0f} s "
                                     "of bring-up", reason="no status")
            time.sleep(0.001)

    # ------------------------------------------------------------------ plumbing
    @property
    def returncode(self) -> int | None:
        """The child's exit status once it has ended (negative: killed by that signal), else None."""
        return self._proc.poll()

    def alive(self) -> bool:
        """True while the child process runs.

        A state published within :data:`ALIVE_FRESH_S` answers without a system call: ``waitpid``
        releases the interpreter lock, and another thread (a planner) that takes it then holds it for
        at least a switch interval while the streaming thread waits. An older state (the child busy
        with a request, or gone) is checked with ``waitpid``.
        """
        if self._closed or self._proc.returncode is not None:
            return False
        if (time.monotonic_ns() - self.base_ns) * 1e-9 - self._mv[_PUBLISHED] < ALIVE_FRESH_S:
            return True
        return self._proc.poll() is None

    def scheduling(self) -> dict[str, int]:
        """The child's threads by scheduling policy and priority, e.g. ``{"SCHED_FIFO 60": 1, "SCHED_OTHER 0": 2}``.

        Whether the real-time policy was granted (it needs CAP_SYS_NICE; the child goes on at normal
        priority without it). Empty when the child is gone.
        """
        names = {os.SCHED_OTHER: "SCHED_OTHER", os.SCHED_FIFO: "SCHED_FIFO", os.SCHED_RR: "SCHED_RR",
                 os.SCHED_BATCH: "SCHED_BATCH", os.SCHED_IDLE: "SCHED_IDLE"}
        out: dict[str, int] = {}
        try:
            tids = [int(t) for t in os.listdir(f"/proc/{self._proc.pid}/task")]
        except OSError:
            return out
        for tid in tids:
            try:
                key = f"{names.get(os.sched_getscheduler(tid), 'other')} {os.sched_getparam(tid).sched_priority}"
            except OSError:  # the thread ended meanwhile
                continue
            out[key] = out.get(key, 0) + 1
        return out

    def values(self) -> list[float]:
        """A consistent copy of the child's state block as floats (seqlock read; fields at ``stream_state.R``)."""
        mv = self._mv
        for _ in range(1000):
            v0 = mv[layout.H_VERSION]
            block: list[float] = mv[layout.S_OFF:layout.RING_OFF].tolist()  # type: ignore[assignment]  # "d" format
            if v0 % 2 == 0 and mv[layout.H_VERSION] == v0:
                break
        return block

    def head(self) -> tuple[float, ...]:
        """The state block's first :data:`~robointel.interface.stream_state.HEAD` fields (seqlock read).

        Everything the per-target path reads (the snapshot, the stop flags), unpacked in one ``struct``
        call: the per-target state read (docs/design/streaming.md).
        """
        mv, mm = self._mv, self._mm
        for _ in range(1000):
            v0 = mv[layout.H_VERSION]
            block = _HEAD.unpack_from(mm, layout.S_OFF * 8)
            if v0 % 2 == 0 and mv[layout.H_VERSION] == v0:
                break
        return block

    def read_block(self) -> npt.NDArray[np.float64]:
        """:meth:`values` as a (fields,) array."""
        return np.array(self.values())

    def read_state(self) -> dict[str, Any]:
        """The child's state block by field name (a float, or an array for vectors)."""
        block = self.read_block()
        return {name: block[_R[name]:_R[name] + sl.stop - sl.start] if sl.stop - sl.start > 1
                else float(block[_R[name]]) for name, sl in layout.STATE_INDEX.items()}

    def _reply(self, timeout: float, what: str) -> Any:
        if not self._conn.poll(timeout):
            raise self.LOST(f"the streaming process did not answer {what} within {timeout:.0f} s")
        try:
            ok, value = self._conn.recv()
        except (EOFError, OSError) as exc:
            raise self.LOST(f"the streaming process is gone ({what}): {exc}") from exc
        if not ok:
            raise self.remote_error(*value)
        return value

    def call(self, name: str, *args: Any, **kwargs: Any) -> Any:
        """Run request ``name`` in the child and return its answer.

        Raises:
            Exception: what :meth:`remote_error` makes of the child's error, or :attr:`LOST` (the
                child is gone).
        """
        with self._lock:
            if not self.alive():
                raise self.LOST("the streaming process is not running")
            try:
                self._conn.send((name, args, kwargs, True))
            except OSError as exc:
                raise self.LOST(f"the streaming process is gone: {exc}") from exc
            return self._reply(REPLY_TIMEOUT_S, name)

    # ------------------------------------------------------------------ the stream
    def set_lookahead(self, lookahead_s: float) -> None:
        """The look-ahead of the next stream (after a hold or a stop), s: 0 submits each target at once.

        Raises:
            InvalidInput: outside [0, 1] s or not finite.
        """
        check_lookahead(lookahead_s)
        self.lookahead_s = float(lookahead_s)
        if self._last_slot is None:
            self._stream_lookahead = self.lookahead_s

    def servo_j(self, q: npt.NDArray[np.float64], duration: float) -> None:
        """Queue target ``q`` (6,) rad; it is played ``lookahead_s`` after the stream's start.

        The target's slot is one period after the previous one, or ``lookahead_s`` from now when the
        stream (re)starts or the previous slot has already passed (the caller fell behind by more
        than the look-ahead). A caller faster than the period replaces its last queued slot once the
        queue holds twice the look-ahead. With a look-ahead of 0 the slot is the arrival and the
        child is woken to submit the target at once.

        Raises:
            Exception: :attr:`LOST` when the child is gone or no longer takes targets.
        """
        if not self.alive():
            raise self.LOST("the streaming process is not running")
        mv = self._mv
        now = (time.monotonic_ns() - self.base_ns) * 1e-9
        last = self._last_slot
        if last is None:
            self._stream_lookahead = self.lookahead_s
        look = self._stream_lookahead
        if look == 0.0:
            slot = now
        elif last is None or now > last:
            slot = max(now + look, self._prev_slot + self.period)
        else:
            slot = last + self.period
            if slot > now + 2 * look + self.period:
                slot = last
        w = int(mv[layout.H_WRITE])
        if w - int(mv[layout.H_READ]) >= layout.RING - 1:
            raise self.LOST(f"the streaming process took no target for {layout.RING} targets")
        o = layout.RING_OFF + (w % layout.RING) * layout.SLOT_WIDTH
        _SLOT.pack_into(self._mm, o * 8, slot, now, *(q.tolist() if isinstance(q, np.ndarray) else q))
        mv[layout.H_WRITE] = w + 1  # published last: the child reads the count, then the slot
        self._last_slot = self._prev_slot = slot
        if look == 0.0:
            os.eventfd_write(self._wake, 1)

    def hold(self) -> None:
        """Hold after the targets already queued have been played."""
        b = self._buf
        b[layout.H_HOLD] = b[layout.H_WRITE]
        b[layout.H_HOLD_GEN] += 1
        self._last_slot = None

    def stop_j(self) -> None:
        """Drop the queued targets and brake at once (never raises)."""
        self._buf[layout.H_CUT] = self._buf[layout.H_WRITE]
        self._last_slot = None
        try:
            self.call("stop_j")
        except self.ERRORS:
            pass  # the child is gone: its robot side stopped with it

    def kick(self) -> None:
        """Feed the child's deadman (no answer awaited)."""
        with self._lock:
            if self.alive():
                try:
                    self._conn.send(("kick", (), {}, False))
                except OSError:
                    pass

    def window_stats(self) -> dict[str, Any]:
        """The child's window counters (see ``stream_player``: a window is fresh, starved, late or core-late).

        ``stream_windows``: controller windows while a stream played; ``stream_fresh``: windows that got
        a freshly interpolated target in time; ``stream_starved``: windows the caller left without a
        target (late by more than the look-ahead); ``stream_late``: windows this process itself missed;
        ``stream_core_late``: windows whose tick the robot side sent late while this process polled for
        it; ``direct_submits`` and ``direct_latency_{mean,max}_ms``: targets of direct streams and the
        time from their arrival to their submission; ``gc_max_ms``: the longest collection of the
        child's serve loop; ``lookahead_s``.
        """
        out: dict[str, Any] = {}
        s = self.read_state()
        for k in ("windows", "fresh", "starved", "late", "submits", "core_late"):
            out[f"stream_{k}"] = int(s[k])
        n = int(s["direct_submits"])
        out["direct_submits"] = n
        out["direct_latency_mean_ms"] = float(s["direct_latency_sum_s"]) / n * 1e3 if n else 0.0
        out["direct_latency_max_ms"] = float(s["direct_latency_max_s"]) * 1e3
        out["gc_max_ms"] = float(s["gc_max_s"]) * 1e3
        out["lookahead_s"] = self.lookahead_s
        return out

    def missed_events(self) -> list[tuple[str, float, int, float, float, float, int, float, float, int, int]]:
        """The last 512 missed windows, each a tuple (see below).

        (kind, time s after ``base_ns``, cmd_tick, gap ms, cpu ms, runq ms, runs, wait ms, late ms, faults,
        preemptions). ``kind`` is starved, late or core_late. Gap to wait describe the child's main thread between the
        wake-up that counted the window and its previous one: the gap between them, its time on a CPU
        and runnable but waiting for one over the gap (``/proc`` schedstat), how many times it was
        scheduled in (1: the poll's wake-up alone), and the poll timeout it had asked for. ``late``: a
        late window's submission (or the wake-up that found it skipped) after its deadline, a starved
        one's time since the caller's last target was due. ``faults``: page faults (minor + major) and
        ``preemptions``: involuntary context switches of that thread over the gap.
        """
        return [tuple(e) for e in self.call("missed_events")]  # type: ignore[misc]

    def last_submit_ns(self) -> int:
        """CLOCK_MONOTONIC time of the child's last target submission, ns (0: none yet)."""
        s = float(self.read_state()["last_submit_s"])
        return self.base_ns + int(round(s * 1e9)) if s > 0 else 0

    def close(self) -> None:
        """Stop the robot side between two ticks, close it and end the child (idempotent)."""
        if self._closed:
            return
        quiet: tuple[type[BaseException], ...] = (*self.ERRORS, OSError, subprocess.TimeoutExpired)
        try:
            if self.alive():
                with self._lock:
                    self._conn.send(("close", (), {}, True))
                    self._reply(REPLY_TIMEOUT_S, "close")
                self._proc.wait(10.0)
        except quiet:
            pass
        finally:
            self._kill()

    def _kill(self) -> None:
        self._closed = True
        if self._proc.poll() is None:
            self._proc.kill()
            self._proc.wait(5.0)
        self._conn.close()
        if self._wake >= 0:
            os.close(self._wake)
            self._wake = -1


def check_lookahead(lookahead_s: float) -> None:
    """InvalidInput unless 0 <= lookahead_s <= 1 s."""
    if not (np.isfinite(lookahead_s) and 0 <= lookahead_s <= 1.0):
        raise InvalidInput(f"lookahead_s must be in [0, 1] s (0: each target at once), got {lookahead_s}",
                           value=lookahead_s)
