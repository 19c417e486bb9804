"""The pre-run check of where parts are and go: on the table, clear of the fixtures, seen, within reach.

A part given ``at: [x, y]`` (and ``yaw_deg``) in a program's ``objects``, or set down by a ``place`` step, must
rest on the grasp cell's table top (every corner of its footprint, rotated by its heading), must not overlap a
fixture of the scene, must be seen by at least one of the two depth cameras (perception finds nothing else)
and must be within the gripper's reach for a top-down grasp. :func:`spot_problem` names the first of these a
spot breaks; :func:`robointel.program.check.check_program` refuses the program with it, naming the step and
the key (``objects[i].at``, ``place.at``) before anything moves.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from functools import lru_cache
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel.errors import IKFailure
from robointel.geometry.table import ENVIRONMENT_NAMES
from robointel.learning.grasp.objects import ObjectModel, primitive_object, ycb_object
from robointel.learning.grasp.perception import DepthCamera, default_cameras
from robointel.learning.grasp.scene import TABLE_CENTRE, TABLE_HALF
from robointel.program.step import TableObject

__all__ = ["TABLE_REGION", "footprint", "in_view", "object_model", "spot_problem"]

#: The grasp cell's table top (x_min, x_max, y_min, y_max), m.
TABLE_REGION = (float(TABLE_CENTRE[0] - TABLE_HALF[0]), float(TABLE_CENTRE[0] + TABLE_HALF[0]),
                float(TABLE_CENTRE[1] - TABLE_HALF[1]), float(TABLE_CENTRE[1] + TABLE_HALF[1]))
#: Footprint half extents (m) and height (m) assumed for a part of unknown shape (a place before any grasp).
DEFAULT_HALF, DEFAULT_HEIGHT = (0.03, 0.03), 0.06


def object_model(obj: TableObject, index: int) -> ObjectModel:
    """The object a program entry places (the generated instance or the YCB scan), as the grasp cell builds it."""
    if obj.ycb is not None:
        return replace(ycb_object(obj.ycb, obj.category), name=f"{obj.category}_{index}")
    return primitive_object(obj.category, obj.seed, name=f"{obj.category}_{index}")


def footprint(x: float, y: float, yaw: float, half: tuple[float, float]) -> npt.NDArray[np.float64]:
    """The four (x, y) corners (4, 2) of a footprint of half extents ``half`` (m) at (x, y) turned by ``yaw`` (rad)."""
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s], [s, c]])
    corners = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]]) * np.asarray(half, float)
    return np.asarray(corners @ R.T + [x, y], float)


@lru_cache(maxsize=1)
def _cameras() -> tuple[DepthCamera, ...]:
    return tuple(default_cameras())


def in_view(point: npt.ArrayLike, cameras: Sequence[DepthCamera] | None = None) -> int:
    """How many of the cell's depth cameras see ``point`` (3,) m (inside the image and the range)."""
    p = np.asarray(point, float)
    n = 0
    for cam in cameras if cameras is not None else _cameras():
        q = cam.R.T @ (p - cam.position)
        if not cam.near < q[2] < cam.far:
            continue
        f = 0.5 * cam.height / np.tan(cam.fovy / 2)
        n += bool(abs(f * q[0] / q[2]) < cam.width / 2 and abs(f * q[1] / q[2]) < cam.height / 2)
    return n


def _fixtures(obstacles: Sequence[Any]) -> list[Any]:
    return [o for o in obstacles if getattr(o, "name", None) not in ENVIRONMENT_NAMES]


def spot_problem(x: float, y: float, *, yaw: float = 0.0, half: tuple[float, float] = DEFAULT_HALF,
                 height: float = DEFAULT_HEIGHT, obstacles: Sequence[Any] = (),
                 reachable: Any = None) -> str:
    """Why a part cannot rest at (x, y) for the grasp cell ('' when it can).

    Args:
        x: Position of the part's frame on the table, m.
        y: Position of the part's frame on the table, m.
        yaw: Its heading, rad.
        half: Half extents (m) of its footprint in its own frame.
        height: Its height, m.
        obstacles: The scene's obstacles (the fixtures: all but the table and the floor).
        reachable: ``reachable((x, y))`` raises :class:`~robointel.errors.IKFailure` when no top-down grasp
            reaches the spot (None: not checked).

    Returns:
        The first problem as a phrase: off the table, inside (or overlapping) a fixture, out of the cameras'
        view, out of the gripper's reach; '' when none.
    """
    x0, x1, y0, y1 = TABLE_REGION
    corners = footprint(x, y, yaw, half)
    if not (x0 <= x <= x1 and y0 <= y <= y1):
        return f"off the table (the table top spans x {x0:.2f}..{x1:.2f} m, y {y0:.2f}..{y1:.2f} m)"
    out = (corners[:, 0] < x0) | (corners[:, 0] > x1) | (corners[:, 1] < y0) | (corners[:, 1] > y1)
    if np.any(out):
        return (f"hangs over the table's edge (a corner of its footprint at {np.round(corners[out][0], 3).tolist()} "
                f"m; the table top spans x {x0:.2f}..{x1:.2f} m, y {y0:.2f}..{y1:.2f} m)")
    u = np.linspace(-1.0, 1.0, 5)
    grid = np.array([[a, b] for a in u for b in u]) * np.asarray(half, float)
    c, s = np.cos(yaw), np.sin(yaw)
    xy = grid @ np.array([[c, s], [-s, c]]) + [x, y]
    P = np.concatenate([np.c_[xy, np.full(len(xy), z)] for z in (0.1 * height, 0.5 * height, 0.9 * height)])
    centre = np.array([[x, y, 0.5 * height]])
    for k, o in enumerate(_fixtures(obstacles)):
        if float(o.distance(centre)[0][0]) < 0.0:
            return f"inside fixture {o.label(k)!r}"
        d = float(np.min(o.distance(P)[0]))
        if d < 0.0:
            return f"overlaps fixture {o.label(k)!r} ({-d * 1e3:.0f} mm into it)"
    if not in_view([x, y, 0.5 * height]):
        return "outside the depth cameras' view (perception would not see it)"
    if reachable is not None:
        try:
            reachable((x, y))
        except IKFailure:
            return "out of the gripper's reach (no top-down grasp within the joint limits reaches it)"
    return ""
