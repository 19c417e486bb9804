"""Grasp poses and their transfer through a fitted warp (6.14)-(6.16).

A grasp is a frame: ``centre`` (3,) in metres and ``rotation`` (3, 3) whose columns are the
gripper axes: x = finger breadth direction, y = closing (grasp) axis between the jaws, z = approach
direction (from the palm toward the object). ``width`` is the jaw opening at teach time (m).
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from robointel._validate import as_array
from robointel.errors import InvalidInput

if TYPE_CHECKING:
    from robointel.learning.grasp.cpd_warps import Warp

__all__ = ["Grasp", "nearest_rotation", "transfer_grasp", "transfer_grasps", "grasp_from_axis"]


@dataclass(frozen=True)
class Grasp:
    """A parallel-jaw grasp frame (see module docstring). ``name`` labels taught grasps."""

    centre: np.ndarray
    rotation: np.ndarray
    width: float = 0.0
    name: str = ""

    def __post_init__(self) -> None:
        c = as_array(self.centre, "grasp centre", (3,))
        R = as_array(self.rotation, "grasp rotation", (3, 3))
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
            raise InvalidInput("grasp rotation must be a proper rotation (R^T R = I, det R = +1)", value=R)
        object.__setattr__(self, "centre", c)
        object.__setattr__(self, "rotation", R)

    @property
    def axis(self) -> np.ndarray:
        """Closing (grasp) axis, unit (3,)."""
        return self.rotation[:, 1]

    @property
    def approach(self) -> np.ndarray:
        """Approach direction, unit (3,)."""
        return self.rotation[:, 2]

    @property
    def pose(self) -> np.ndarray:
        """4x4 homogeneous pose of the grasp frame."""
        T = np.eye(4)
        T[:3, :3] = self.rotation
        T[:3, 3] = self.centre
        return T

    def transformed(self, T: np.ndarray) -> Grasp:
        """The grasp moved by a rigid 4x4 transform ``T``."""
        T = as_array(T, "T", (4, 4))
        return replace(self, centre=T[:3, :3] @ self.centre + T[:3, 3], rotation=T[:3, :3] @ self.rotation)

    def rotated_about_axis(self, angle: float) -> Grasp:
        """The grasp turned by ``angle`` (rad) about its own closing axis (the search of (6.21))."""
        c, s = np.cos(angle), np.sin(angle)
        Ry = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
        return replace(self, rotation=self.rotation @ Ry)


def grasp_from_axis(centre: npt.ArrayLike, axis: npt.ArrayLike, approach: npt.ArrayLike, width: float = 0.0,
                    name: str = "") -> Grasp:
    """Build a :class:`Grasp` from its closing ``axis`` and an ``approach`` direction (made orthogonal).

    Args:
        centre: Grasp centre (3,), m.
        axis: Closing axis (3,), any length.
        approach: Approach direction (3,); its part along ``axis`` is removed.
        width: Jaw opening (m).
        name: Label.

    Returns:
        The grasp frame (x = breadth, y = closing axis, z = approach).

    Raises:
        InvalidInput: a wrong shape, or ``approach`` parallel to ``axis``.
    """
    y = as_array(axis, "axis", (3,))
    z = as_array(approach, "approach", (3,))
    y = y / np.linalg.norm(y)
    z = z - (z @ y) * y
    nz = np.linalg.norm(z)
    if nz < 1e-9:
        raise InvalidInput("approach direction is parallel to the grasp axis", value=(axis, approach))
    z = z / nz
    return Grasp(as_array(centre, "centre", (3,)), np.column_stack([np.cross(y, z), y, z]), width, name)


def nearest_rotation(A: npt.ArrayLike) -> np.ndarray:
    """(6.15)-(6.16): the proper rotation nearest to ``A`` (3, 3): ``U diag(1, 1, det(U V^T)) V^T``.

    The sign fix makes det = +1 even when ``A`` (e.g. a warp Jacobian times R) is a reflection.
    """
    A = as_array(A, "A", (3, 3))
    U, _, Vt = np.linalg.svd(A)
    d = np.sign(np.linalg.det(U @ Vt)) or 1.0
    return U @ np.diag([1.0, 1.0, d]) @ Vt


def transfer_grasp(warp: Warp, grasp: Grasp) -> Grasp:
    """(6.14)-(6.16): move a taught grasp through a fitted warp T.

    Centre ``t' = T(t)``; rotation ``R' = U V^T`` from the SVD ``grad T(t) R = U S V^T`` (det = +1).
    The width is scaled by the stretch of the warp along the grasp axis.
    """
    c = np.asarray(warp(grasp.centre[None]), float)[0]
    J = np.asarray(warp.jacobian(grasp.centre[None]), float)[0]
    R = nearest_rotation(J @ grasp.rotation)
    width = grasp.width * float(np.linalg.norm(J @ grasp.axis))
    return Grasp(c, R, width, grasp.name)


def transfer_grasps(warp: Warp, grasps: Iterable[Grasp]) -> list[Grasp]:
    """:func:`transfer_grasp` for each grasp."""
    return [transfer_grasp(warp, g) for g in grasps]
