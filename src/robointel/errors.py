"""One exception hierarchy for robointel.

Every error raised at a public boundary is a :class:`RobointelError`. Messages say what was wrong
and what to do; the offending value is kept on the exception (``.value``) where there is one.
"""
from __future__ import annotations

from typing import Any


class RobointelError(Exception):
    """Base class of every robointel error."""

    def __init__(self, message: str, *, value: Any = None) -> None:
        super().__init__(message)
        self.value = value


class InvalidInput(RobointelError, ValueError):
    """An argument has the wrong shape, type, units or contains NaN/inf."""


class ShapeError(InvalidInput):
    """An array has the wrong shape."""


class NotFinite(InvalidInput):
    """An array contains NaN or inf."""


class LimitViolation(InvalidInput):
    """A configuration, velocity or parameter is outside its allowed range."""


class UnknownRobot(RobointelError, KeyError):
    """A robot name is neither built in nor a path to a URDF file."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


class DescriptionError(RobointelError):
    """A robot description (URDF) could not be read or is inconsistent."""


class DescriptionWarning(UserWarning):
    """A robot description entry was skipped (e.g. an SRDF entry naming a link the URDF lacks, as MoveIt skips it)."""


class IKFailure(RobointelError):
    """Inverse kinematics found no solution (unreachable pose, or outside joint limits)."""


class InfeasibleProblem(RobointelError):
    """An optimisation problem has no feasible point (e.g. contradictory limits)."""


class SolverFailure(RobointelError):
    """A numerical solver failed; the result, where there is one, is kept on ``.value``."""


class CollisionAtStart(InfeasibleProblem):
    """A start configuration or waypoint is in collision; the message names link and obstacle."""


class DataMissing(RobointelError, FileNotFoundError):
    """A reference data file is missing."""


class SafetyStop(RobointelError):
    """A controller refused a command (bad sensor data, stalled stream) and held the robot."""


class SweepFileError(InvalidInput):
    """A batch sweep file (YAML) or task spec is malformed; ``.value`` holds the offending part."""


class UnknownTaskKind(InvalidInput):
    """A batch task names a trial kind that is not registered; ``.value`` is the kind."""


class ResultStoreError(RobointelError):
    """A batch result store (Parquet dataset folder) cannot be read or written."""


class EngineUnavailable(RobointelError):
    """A batch engine cannot start (Ray not installed, cluster unreachable); the message says what to do."""

class UnsafeCommand(SafetyStop, InvalidInput):
    """A robot command was refused before it reached the robot.

    Outside the joint limits, NaN, or a jump larger than one controller period allows at the maximum
    joint speed; ``.value`` is the target.
    """


class ControllerFault(SafetyStop):
    """The robot controller stopped (e-stop, alarm, stalled command stream); commanding has stopped.

    ``.value`` is the last known :class:`robointel.interface.RobotState`; ``reason`` says why.
    """

    def __init__(self, message: str, *, value: Any = None, reason: str = "") -> None:
        super().__init__(message, value=value)
        self.reason = reason


class ConnectionLost(ControllerFault):
    """The connection to the robot controller was lost; ``.value`` is the last known state.

    Never retried into motion: reconnect explicitly.
    """

class TargetInCollision(SafetyStop):
    """A target configuration (or the motion to it) would hit the table, the floor, an obstacle or itself.

    The message names the link; ``.value`` holds link, obstacle and distance.
    """


class MissingExtra(RobointelError, ImportError):
    """A feature needs an optional part of robointel that is not installed; ``.value`` is the extra's name.

    The message names the extra and the command that installs it (``pip install 'robointel[teleop]'``).
    """
