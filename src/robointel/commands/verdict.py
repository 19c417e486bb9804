"""What ``--execute`` accepts: the checks a planned trajectory passes before any robot moves.

``robointel plan scene|motion`` prints this verdict for every plan, and ``--execute`` runs the very same
checks before it moves, so the report and the execution cannot disagree on them:

- the collision guard (:class:`robointel.teach.collision_guard.CollisionGuard`) on a 10 ms resample: every
  movable collision sphere clear of the obstacles and of the table and floor the robot stands on, no
  self-collision pair of spheres overlapping;
- the robot interface's safety gate (:class:`robointel.interface.gate.SafetyGate`) on the controller's 8 ms
  resample: finite, within the joint position limits, no jump beyond the joint speed limits in one period.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from robointel.errors import RobointelError
from robointel.geometry.table import table_obstacles
from robointel.interface.gate import SafetyGate
from robointel.teach.collision_guard import CollisionGuard
from robointel.trajectory import Trajectory

#: resample step of the collision guard's check, s
GUARD_DT = 0.01
#: the robot interface's controller period, s (the FANUC Stream Motion period)
GATE_PERIOD = 0.008


def guard_environment(obstacles: Sequence[Any]) -> list[Any]:
    """The obstacles the guard checks: the given ones plus the workcell's table and floor (once)."""
    obs = list(obstacles)
    have = {getattr(o, "name", None) for o in obs}
    return obs + [o for o in table_obstacles() if o.name not in have]


def execute_verdict(robot: Any, obstacles: Sequence[Any], trajectory: Trajectory) -> str:
    """Why ``--execute`` refuses ``trajectory`` ('' when it accepts it).

    Args:
        robot: The :class:`robointel.robot.Robot` the trajectory is for.
        obstacles: The scene's obstacles (the table and floor are added when missing).
        trajectory: The planned trajectory.

    Returns:
        '' or the refusal (the guard's or the gate's message: which link, which obstacle or sample).
    """
    try:
        CollisionGuard(robot, guard_environment(obstacles)).check_many(trajectory.resample(GUARD_DT).q,
                                                                       "planned trajectory")
        SafetyGate(robot.joint_names, robot.lower, robot.upper, robot.velocity_limit,
                   GATE_PERIOD).check_path(trajectory.resample(GATE_PERIOD).q, None)
    except RobointelError as exc:
        return " ".join(str(exc).split())
    return ""
