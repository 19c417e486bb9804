"""The robot interface every capability talks to; backends ``sim`` (MuJoCo) and ``fanuc`` (Stream Motion).

- :class:`RobotInterface` -- the protocol: ``state()``, ``period``, ``stream(q)``, ``execute(traj)``,
  ``hold()``, ``stop(reason)``, ``recover()``, ``close()``; a context manager.
- :func:`open_robot` -- ``open_robot("sim")`` or ``open_robot("fanuc://HOST")``.
- :class:`SafetyGate` -- the one check every command passes (limits, NaN, per-period jump).
- :class:`RobotState`, :class:`RobotMode`, :class:`ExecutionResult`.
- :func:`realtime_thread`, :func:`sleep_until` -- the streaming thread's real-time section and wait.
- :class:`NetFTSensor`, :class:`WrenchSource` -- a wrist F/T sensor beside a FANUC controller.
- :func:`approach_trajectory` -- the quintic move to a trajectory's start (``Backend.move_to``).

Each name is imported from its module on first access, so importing a module of this package (the
streaming child's, which imports only numpy and airo-fanuc besides) does not load the others.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from robointel._lazy import lazy_exports

if TYPE_CHECKING:
    from robointel.interface.approach import approach_trajectory
    from robointel.interface.backend import Backend, ExecutionResult, Recorder
    from robointel.interface.ft_sensor import NetFTSensor, WrenchSource
    from robointel.interface.gate import SafetyGate
    from robointel.interface.open import open_robot
    from robointel.interface.protocol import CycleCallback, RobotInterface
    from robointel.interface.realtime import realtime_thread, sleep_until
    from robointel.interface.state import RobotMode, RobotState

_EXPORTS = {
    "approach_trajectory": "robointel.interface.approach",
    "Backend": "robointel.interface.backend",
    "ExecutionResult": "robointel.interface.backend",
    "Recorder": "robointel.interface.backend",
    "NetFTSensor": "robointel.interface.ft_sensor",
    "WrenchSource": "robointel.interface.ft_sensor",
    "SafetyGate": "robointel.interface.gate",
    "open_robot": "robointel.interface.open",
    "CycleCallback": "robointel.interface.protocol",
    "RobotInterface": "robointel.interface.protocol",
    "realtime_thread": "robointel.interface.realtime",
    "sleep_until": "robointel.interface.realtime",
    "RobotMode": "robointel.interface.state",
    "RobotState": "robointel.interface.state",
}

__all__ = ["RobotInterface", "RobotState", "RobotMode", "SafetyGate", "Backend", "ExecutionResult", "Recorder",
           "CycleCallback", "open_robot", "realtime_thread", "sleep_until", "NetFTSensor", "WrenchSource",
           "approach_trajectory"]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
