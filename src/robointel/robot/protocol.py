"""What the collision model needs of a robot: the interface :class:`robointel.robot.Robot` provides.

Declared here, below both, so that the sphere model (``collision.py``) is typed without importing
the robot model that builds it.
"""
from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike


class KinematicRobot(Protocol):
    """A robot whose links carry collision spheres (see :class:`robointel.robot.Robot`)."""

    nq: int
    lower: np.ndarray
    upper: np.ndarray
    model: Any
    _link_in_joint: dict[str, np.ndarray]

    @property
    def link_names(self) -> list[str]:
        """Names of the links."""
        ...

    def link_joint(self, link: str) -> int:
        """Pinocchio joint index a link hangs on."""
        ...

    def collision_primitives(self) -> dict[str, list[dict]]:
        """Collision geometry of each link."""
        ...

    def check_q(self, q: ArrayLike, name: str = "q", *, limits: bool = False) -> np.ndarray:
        """A validated configuration."""
        ...

    def points_kinematics(self, q: np.ndarray, joints: np.ndarray, points: np.ndarray, *,
                          angular: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """World positions and Jacobians of points fixed on joints."""
        ...

    def points_kinematics_batch(self, Q: ArrayLike, joints: np.ndarray, points: np.ndarray, *,
                                angular: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`points_kinematics` for many configurations."""
        ...
