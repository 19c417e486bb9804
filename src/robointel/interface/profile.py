"""The FANUC LR Mate 200iD/7L motion envelope for ``airo-fanuc``, from our robot description."""
from __future__ import annotations

from typing import Any

import numpy as np
from airo_fanuc import RobotProfile

JERK_PER_ACCELERATION = 20.0
"""Jerk clamp = this x the acceleration limit, 1/s (full acceleration is reached in 50 ms)."""


def lrmate_profile(robot: Any = None) -> RobotProfile:
    """The :class:`airo_fanuc.RobotProfile` of the LR Mate 200iD/7L (or any 6-joint robot).

    Velocity and position limits are the description's (J1 +-170, J2 -100..145, J3 -70..213,
    J4 +-190, J5 +-125, J6 +-360 deg; 370, 310, 410, 550, 545, 1000 deg/s); the acceleration clamp
    is the robot's ``acceleration_limit`` (3 x the speed per second) and the jerk clamp
    :data:`JERK_PER_ACCELERATION` x that. They are clamps: at or above what the planners shape.

    Args:
        robot: a :class:`robointel.robot.Robot` with 6 joints (default: the built-in LR Mate).

    Returns:
        The profile, in radians.

    Raises:
        airo_fanuc.ProfileError: the robot does not have 6 joints.
    """
    if robot is None:
        from robointel.robot import Robot

        robot = Robot.load("lrmate200id7l")
    v = np.asarray(robot.velocity_limit, dtype=np.float64)
    a = np.asarray(robot.acceleration_limit, dtype=np.float64)
    return RobotProfile(name=getattr(robot, "name", "lrmate200id7l"), model="FANUC LR Mate 200iD/7L",
                        velocity_limits=v, acceleration_limits=a, jerk_limits=JERK_PER_ACCELERATION * a,
                        position_limits_lower=np.asarray(robot.lower, dtype=np.float64),
                        position_limits_upper=np.asarray(robot.upper, dtype=np.float64),
                        ndof=len(v), max_payload_kg=7.0, source="robointel LR Mate 200iD/7L description")
