"""The robot interface every capability talks to; backends ``sim`` (MuJoCo) and ``fanuc`` (Stream Motion).

- :class:`RobotInterface` -- the protocol: ``state()``, ``period``, ``stream(q)``, ``execute(traj)``,
  ``hold()``, ``stop(reason)``, ``recover()``, ``close()``; a context manager.
- :func:`open_robot` -- ``open_robot("sim")`` or ``open_robot("fanuc://HOST")``.
- :class:`SafetyGate` -- the one check every command passes (limits, NaN, per-period jump).
- :class:`RobotState`, :class:`RobotMode`, :class:`ExecutionResult`.
"""
from robointel.interface.backend import Backend, ExecutionResult, Recorder
from robointel.interface.gate import SafetyGate
from robointel.interface.open import open_robot
from robointel.interface.protocol import CycleCallback, RobotInterface
from robointel.interface.state import RobotMode, RobotState

__all__ = ["RobotInterface", "RobotState", "RobotMode", "SafetyGate", "Backend", "ExecutionResult", "Recorder",
           "CycleCallback", "open_robot"]
