"""robointel: teach, learn and plan for an industrial arm.

The entry points a user starts from; each is imported from its module on first access, so
``import robointel`` stays light (it loads neither MuJoCo nor h5py):

- :class:`Robot` -- a robot from a built-in name or a URDF (kinematics, IK, dynamics, collision spheres).
- :func:`plan_motion` in an :class:`Environment`, set by :class:`MotionSettings`, returning a
  :class:`MotionPlan` -- start-to-goal planning for any arm.
- :func:`load_scene` / :class:`Scene` -- planning scenes (YAML, or the built-in ``table71``).
- :class:`Trajectory`, :func:`load_trajectory`, :func:`save_trajectory` -- the time-stamped joint trajectory.
- :func:`open_robot` -- the robot interface (``"sim"`` or ``"fanuc://HOST"``); :class:`Workcell` -- the
  simulated cell in MuJoCo.
- The errors every public function raises (:mod:`robointel.errors`), with :class:`RobointelError` at the root.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version
from typing import TYPE_CHECKING

from robointel._lazy import lazy_exports
from robointel.errors import (
    CollisionAtStart,
    ControllerFault,
    DescriptionError,
    IKFailure,
    InfeasibleProblem,
    InvalidInput,
    MissingExtra,
    RobointelError,
    SafetyStop,
    UnknownRobot,
)

if TYPE_CHECKING:
    from robointel.interface.open import open_robot
    from robointel.io.trajectory import load_trajectory, save_trajectory
    from robointel.planning.environment import Environment
    from robointel.planning.motion import MotionPlan, plan_motion
    from robointel.planning.motion_settings import MotionSettings
    from robointel.planning.scene import Scene, load_scene
    from robointel.robot import Robot
    from robointel.sim.workcell import Workcell
    from robointel.trajectory import Trajectory

try:
    __version__ = version("robointel")
except PackageNotFoundError:  # pragma: no cover - run from a source tree that was never installed
    __version__ = "0+unknown"

_EXPORTS = {
    "Robot": "robointel.robot",
    "Environment": "robointel.planning.environment",
    "MotionPlan": "robointel.planning.motion",
    "plan_motion": "robointel.planning.motion",
    "MotionSettings": "robointel.planning.motion_settings",
    "Scene": "robointel.planning.scene",
    "load_scene": "robointel.planning.scene",
    "Trajectory": "robointel.trajectory",
    "load_trajectory": "robointel.io.trajectory",
    "save_trajectory": "robointel.io.trajectory",
    "open_robot": "robointel.interface.open",
    "Workcell": "robointel.sim.workcell",
}

__all__ = [
    "Robot", "Environment", "MotionPlan", "MotionSettings", "plan_motion", "Scene", "load_scene", "Trajectory",
    "load_trajectory", "save_trajectory", "open_robot", "Workcell",
    "RobointelError", "InvalidInput", "InfeasibleProblem", "CollisionAtStart", "IKFailure", "UnknownRobot",
    "DescriptionError", "SafetyStop", "ControllerFault", "MissingExtra", "__version__",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
