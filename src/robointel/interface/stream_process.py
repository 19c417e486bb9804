"""The FANUC driver in a streaming process of its own, fed through a look-ahead queue in shared memory.

:class:`StreamProcess` is a :class:`~robointel.interface.stream_ring.RingProcess` (the ring, the
seqlock block, the window counters: docs/design/streaming.md) whose child
(:mod:`robointel.interface.stream_child` run as a script) owns the ``airo-fanuc`` driver and its
real-time core, and submits the interpolated target at each of the core's ticks.

The class offers the part of ``FanucDriver``'s surface that :class:`~robointel.interface.fanuc.FanucRobot`
uses (``servo_j``, ``hold``, ``stop_j``, ``kick``, ``recover``, ``arm``, ``move_trajectory``,
``timing_stats``, ``close`` and ``core.get_snapshot()`` / ``core.running``), so the robot's own
checks (gate, faults, stall, recording) stay where they are.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt
from airo_fanuc import MotionResult
from airo_fanuc.exceptions import (
    FanucConnectionError,
    FanucError,
    RmiError,
    RmiSessionDown,
    RobotFaultedError,
    TrajectoryValidationError,
)

from robointel.interface import stream_child as sc
from robointel.interface import stream_layout as layout
from robointel.interface import stream_state
from robointel.interface.stream_ring import (
    ALIVE_FRESH_S,
    FIRST_STATUS_TIMEOUT_S,
    REPLY_TIMEOUT_S,
    START_TIMEOUT_S,
    RingProcess,
    check_lookahead,
)

_ROOT = str(Path(__file__).resolve().parents[2])
"""The directory holding this robointel package (the child's script imports its streaming modules)."""

__all__ = ["StreamProcess", "check_lookahead", "ALIVE_FRESH_S", "FIRST_STATUS_TIMEOUT_S", "REPLY_TIMEOUT_S",
           "START_TIMEOUT_S"]

_ERRORS: dict[str, type[Exception]] = {"TrajectoryValidationError": TrajectoryValidationError,
                                       "RobotFaultedError": RobotFaultedError,
                                       "FanucConnectionError": FanucConnectionError,
                                       "RmiSessionDown": RmiSessionDown,
                                       "RmiError": RmiError}


def _error(kind: str, message: str) -> Exception:
    """The ``airo_fanuc`` exception the child reported (``FanucError`` for any other kind)."""
    return _ERRORS.get(kind, FanucError)(f"{message}" if kind in _ERRORS else f"{kind}: {message}")


class _CoreView:
    """``core.get_snapshot()`` and ``core.running`` read from the shared state block."""

    def __init__(self, owner: StreamProcess) -> None:
        self._owner = owner

    @property
    def running(self) -> bool:
        """True while the child runs and its core streams."""
        o = self._owner
        return o.alive() and bool(o._mv[_RUNNING])  # one aligned double: no seqlock needed

    def get_snapshot(self) -> dict[str, Any]:
        """The core's snapshot as the child last published it (the keys ``FanucRobot`` reads)."""
        o = self._owner
        return stream_state.snapshot(o.values(), o.base_ns, time.monotonic_ns())


_RUNNING = layout.STATE_INDEX["running"].start


class _RmiView:
    """The child's RMI session: numeric register reads and writes (``FanucDriver.rmi``'s surface)."""

    def __init__(self, owner: StreamProcess) -> None:
        self._owner = owner

    def write_register(self, number: int, value: float) -> None:
        """Write R[number] in the child (raises ``RmiError`` / ``RmiSessionDown`` as the driver does)."""
        self._owner.call("rmi_write_register", int(number), value)

    def read_register(self, number: int) -> float:
        """Read R[number] in the child."""
        return float(self._owner.call("rmi_read_register", int(number)))


class _Handle:
    """A ``MotionHandle`` of a trajectory the child's core plays."""

    def __init__(self, owner: StreamProcess, motion_id: int) -> None:
        self._owner, self.motion_id = owner, int(motion_id)

    def done(self) -> bool:
        """True once the motion has a result."""
        return bool(self._owner.call("motion_done", self.motion_id))

    def result(self) -> MotionResult | None:
        """The motion's result, or None while it runs."""
        v = self._owner.call("motion_result", self.motion_id)
        return None if v is None else MotionResult(v)


class StreamProcess(RingProcess):
    """A FANUC driver in a child process, streamed through a look-ahead queue.

    Args:
        host: controller address.
        policy: the ``airo_fanuc.DriverPolicy`` (sent to the child).
        period: controller period, s.
        lookahead_s: delay between a target's arrival and its play time, s (0: direct, each target
            submitted at once; else > 0, at most 1).
        stall_periods: the child stops the robot after this many consecutive controller windows
            without a target to play.

    Raises:
        InvalidInput: a look-ahead or stall count out of range.
        FanucError: the child could not bring the controller up (the driver's own error class).
    """

    LOST: ClassVar[type[Exception]] = FanucConnectionError
    ERRORS: ClassVar[tuple[type[Exception], ...]] = (FanucError,)
    gripper = None
    """No gripper dispatcher in the streaming process (``FanucRobot(gripper=True)`` keeps the driver in-process)."""

    def __init__(self, host: str, policy: Any, *, period: float, lookahead_s: float, stall_periods: int) -> None:
        self.core = _CoreView(self)
        self.rmi = _RmiView(self)
        super().__init__(sc.__file__, (host, policy), period=period, lookahead_s=lookahead_s,
                         stall_periods=stall_periods, path=_ROOT)

    def remote_error(self, kind: str, message: str) -> Exception:
        """The ``airo_fanuc`` exception the child reported (``FanucError`` for any other kind)."""
        return _error(kind, message)

    # ------------------------------------------------------------------ the driver's surface
    def recover(self, timeout_s: float | None = None, *, escalate_reconnect: bool = False) -> bool:
        """The driver's recovery ladder and ARM gate in the child; the queue starts empty."""
        self._last_slot = None
        return bool(self.call("recover"))

    def arm(self) -> None:
        """Nothing to do: :meth:`recover` arms in the child."""

    def move_trajectory(self, times: npt.NDArray[np.int64], q: npt.NDArray[np.float64], qd: npt.NDArray[np.float64],
                        *, deadman_s: float | None = None, asynchronous: bool = True) -> _Handle:
        """Play a trajectory on the child's core (``FanucDriver.move_trajectory``); drops queued targets."""
        self._last_slot = None
        mid = self.call("move_trajectory", np.asarray(times, dtype=np.int64).tolist(), np.asarray(q).tolist(),
                        np.asarray(qd).tolist(), deadman_s=deadman_s, asynchronous=asynchronous)
        return _Handle(self, mid)

    def timing_stats(self) -> dict[str, Any]:
        """The core's timing statistics plus the streaming process's window counters (:meth:`window_stats`)."""
        out = dict(self.call("timing_stats"))
        out.update(self.window_stats())
        return out


