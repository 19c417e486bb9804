"""The robot state every backend reports: time, joints, wrench, mode and why it stopped."""
from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np
import numpy.typing as npt


class RobotMode(StrEnum):
    """What the robot is doing, as the interface sees it."""

    IDLE = "idle"
    """Connected, at rest, no command stream running."""
    STREAMING = "streaming"
    """Position targets are being streamed (one per controller period)."""
    HOLDING = "holding"
    """Holding the last commanded position on request."""
    STOPPED = "stopped"
    """Stopped by :meth:`RobotInterface.stop`, a stalled stream or a refused command; needs ``recover()``."""
    FAULTED = "faulted"
    """The controller reported a fault (e-stop, alarm); needs ``recover()`` after the cause is cleared."""
    DISCONNECTED = "disconnected"
    """The connection is lost or closed; the state is the last one known."""


@dataclass(frozen=True)
class RobotState:
    """One reading of the robot.

    Attributes:
        t: time of the reading, s (simulated time for ``sim``, monotonic wall time for ``fanuc``).
        q: (n,) measured joint positions, rad.
        qd: (n,) measured (or estimated) joint velocities, rad/s.
        wrench: (6,) measured wrench [f (N); m (N m)] in the sensor frame, or None without a sensor.
        mode: the :class:`RobotMode`.
        faults: active fault names (``"e_stop"``, ``"in_error"``, ``"stream_stalled"``...), empty if none.
        why_stopped: a sentence saying why the robot stopped, empty while it may move.
        q_cmd: (n,) the last joint position command the robot received, rad (None before the first).
    """

    t: float
    q: npt.NDArray[np.float64]
    qd: npt.NDArray[np.float64]
    wrench: npt.NDArray[np.float64] | None
    mode: RobotMode
    faults: tuple[str, ...] = ()
    why_stopped: str = ""
    q_cmd: npt.NDArray[np.float64] | None = None

    @property
    def ok(self) -> bool:
        """True when the robot may be commanded (no fault, not stopped, connected)."""
        return self.mode not in (RobotMode.STOPPED, RobotMode.FAULTED, RobotMode.DISCONNECTED) and not self.faults
