"""The part's shape class, read off the perceived cloud, and where each class is best held.

The classification (6.17)-(6.19) names a category, and the category's taught grasps transfer; but a
category can be misread (a rectangular tin read as a box) and a template's grasps can land where the
target is weak (a screwdriver's handle grasp on a fork's tines). The shape class comes from what the
cameras see, whatever the category read:

* ``"box"``: a rectangular footprint (the footprint's hull fills its minimum-area rectangle) under a
  flat top that covers it (a prism standing or lying on the table, not a posed toy arm): a tin or a
  box. Taken across its short side (the closing axis along the footprint's short axis), near the
  middle of its long side. Its sides are vertical under the seen top: :func:`box_sides` completes
  them where the cameras saw little of them (a low box's sides, its far sides).
* ``"long"``: a long, low part lying on the table (a utensil, a tool): taken near its centre of mass
  along its length, where it is thickest (its seen top is highest there).
* ``"other"``: no rule (round parts, cups, toy arms, clamps): the hold and the isotropy decide.

:func:`shape_cost` turns the rules into a cost added to each candidate's (6.21) cost, and
:func:`shape_grasps` proposes the grasps each rule asks for, to compete with the transferred ones.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial import ConvexHull, QhullError

from robointel._validate import as_array
from robointel.errors import InvalidInput
from robointel.learning.grasp.classify import footprint_rectangle, yaw_matrix
from robointel.learning.grasp.quality import ParallelGripper
from robointel.learning.grasp.transfer import Grasp, grasp_from_axis

__all__ = ["BOX_FILL", "BOX_ASPECT", "BOX_TOP", "LONG_ASPECT", "LONG_HEIGHT", "ShapeClass", "box_sides",
           "shape_class", "shape_cost", "shape_grasps"]

#: Least ratio of the footprint hull's area to its minimum-area rectangle's for a "box" (a disc: pi/4).
BOX_FILL = 0.88

#: Least long-to-short footprint ratio for a "box" (1: any rectangle; a square block is taken across
#: either side, never across its corners).
BOX_ASPECT = 1.0

#: Least share of the footprint hull's area covered by the hull of the seen points within 10 mm of the
#: top, for a "box" (its flat top spans its footprint).
BOX_TOP = 0.6

#: Least long-to-short footprint ratio for a "long" part.
LONG_ASPECT = 3.0

#: Most height over the long footprint side for a "long" part (it lies on the table).
LONG_HEIGHT = 0.35


@dataclass(frozen=True)
class ShapeClass:
    """A part's shape class (see the module docstring).

    Attributes:
        kind: "box", "long" or "other".
        centre: (2,) the footprint rectangle's centre (m, world x, y).
        long_axis: (2,) unit vector along the footprint's long side (world x, y).
        extents: (3,) the footprint's long and short sides and the seen height above the table (m).
        fill: The footprint hull's area over its rectangle's.
        top: The share of the footprint hull's area under the seen top (points within 10 mm of it).
    """

    kind: str
    centre: np.ndarray
    long_axis: np.ndarray
    extents: np.ndarray
    fill: float
    top: float = 0.0

    @property
    def short_axis(self) -> np.ndarray:
        """(2,) unit vector along the footprint's short side."""
        return np.array([-self.long_axis[1], self.long_axis[0]])


def shape_class(cloud: npt.ArrayLike, *, table_z: float = 0.0) -> ShapeClass:
    """The shape class of a perceived part.

    Args:
        cloud: The perceived part (n, 3), m, world frame (its top and near sides; z up).
        table_z: The table's height (m).

    Returns:
        The :class:`ShapeClass`.

    Raises:
        InvalidInput: fewer than 4 points or not finite.
    """
    P = as_array(cloud, "cloud", (None, 3))
    if len(P) < 4:
        raise InvalidInput(f"shape_class needs at least 4 points, got {len(P)}", value=len(P))
    angle, ext = footprint_rectangle(P)
    R = yaw_matrix(angle)[:2, :2]
    xy = P[:, :2]
    mid = xy.mean(0)
    local = (xy - mid) @ R
    lo, hi = np.percentile(local, [2.0, 98.0], axis=0)
    centre = mid + R @ (0.5 * (lo + hi))
    a, b = float(ext[0]), float(ext[1])
    long_axis = R[:, 0] if a >= b else R[:, 1]
    L, S = max(a, b), max(min(a, b), 1e-6)
    height = float(P[:, 2].max() - table_z)
    area = _area(xy)
    fill = area / max(float(np.ptp(local[:, 0]) * np.ptp(local[:, 1])), 1e-12)
    top = _area(xy[P[:, 2] >= P[:, 2].max() - 0.01]) / max(area, 1e-12)
    if L / S >= LONG_ASPECT and height <= LONG_HEIGHT * L:
        kind = "long"
    elif fill >= BOX_FILL and L / S >= BOX_ASPECT and top >= BOX_TOP:
        kind = "box"
    else:
        kind = "other"
    return ShapeClass(kind, centre, long_axis, np.array([L, S, height]), fill, top)


def _area(xy: np.ndarray) -> float:
    """Area (m^2) of the convex hull of the points ``xy`` (n, 2); 0 when degenerate."""
    try:
        return float(ConvexHull(xy).volume) if len(xy) >= 3 else 0.0
    except (QhullError, ValueError):
        return 0.0


def box_sides(shape: ShapeClass, *, table_z: float = 0.0, spacing: float = 0.004) -> np.ndarray:
    """Points on the four vertical sides of a "box" (its footprint rectangle, from the table to the seen top).

    Args:
        shape: The part's :class:`ShapeClass` (kind "box"; any other kind gives no points).
        table_z: The table's height (m).
        spacing: Distance between the points (m).

    Returns:
        The points (k, 3), m, world (k = 0 for a kind other than "box").
    """
    if shape.kind != "box":
        return np.zeros((0, 3))
    L, S, H = (float(v) for v in shape.extents)
    u, v = shape.long_axis, shape.short_axis
    zs = table_z + np.arange(spacing, H, spacing)
    out = []
    for half, along, side, across in ((0.5 * S, L, v, u), (0.5 * L, S, u, v)):
        ts = np.arange(-0.5 * along, 0.5 * along + 1e-9, spacing)
        for sgn in (-1.0, 1.0):
            xy = shape.centre + sgn * half * side + ts[:, None] * across
            out.append(np.column_stack([np.repeat(xy, len(zs), axis=0), np.tile(zs, len(ts))]))
    return np.vstack(out) if out else np.zeros((0, 3))


def shape_cost(grasp: Grasp, shape: ShapeClass, *, com: npt.ArrayLike | None = None,
               observed: npt.ArrayLike | None = None, column: float = 0.008) -> float:
    """The cost of holding a part of class ``shape`` at ``grasp`` (0 for class "other").

    * "box": ``1 - |cos|`` of the angle between the closing axis's horizontal part and the short side,
      plus the grasp centre's distance from the footprint centre along the long side over half the
      long side;
    * "long": the grasp centre's distance from the centre of mass ``com`` (default the footprint
      centre) along the long side over half the length, plus ``1 - h / h_max``: the seen top's height
      ``h`` above the lowest seen point within ``column`` m (horizontally) of the grasp centre over
      the part's (``observed``: the perceived points; without them this term is 0).

    Args:
        grasp: The candidate grasp (world frame).
        shape: The part's :class:`ShapeClass`.
        com: The part's estimated centre of mass (3,), m, world.
        observed: The perceived points (n, 3), m, world.
        column: Radius (m) of the column whose top is the part's height at the grasp.

    Returns:
        The cost (dimensionless, 0..2).
    """
    if shape.kind == "other":
        return 0.0
    half = max(0.5 * float(shape.extents[0]), 1e-6)
    c = grasp.centre[:2]
    if shape.kind == "box":
        ax = grasp.axis[:2]
        n = float(np.linalg.norm(ax))
        align = 1.0 - (abs(float(ax @ shape.short_axis)) / n if n > 1e-9 else 0.0)
        off = abs(float((c - shape.centre) @ shape.long_axis)) / half
        return float(align + min(off, 1.0))
    ref = shape.centre if com is None else np.asarray(com, float)[:2]
    off = min(abs(float((c - ref) @ shape.long_axis)) / half, 1.0)
    thin = 0.0
    if observed is not None:
        P = np.asarray(observed, float)
        base = float(P[:, 2].min())
        top = float(P[:, 2].max()) - base
        near = P[np.linalg.norm(P[:, :2] - c, axis=1) < column]
        if top > 1e-6:
            thin = 1.0 - (float(near[:, 2].max()) - base) / top if len(near) else 1.0
    return float(off + thin)


def shape_grasps(shape: ShapeClass, observed: npt.ArrayLike, gripper: ParallelGripper, *, table_z: float = 0.0,
                 com: npt.ArrayLike | None = None, clearance: float = 0.003,
                 offsets: tuple[float, ...] = (0.0, -0.01, 0.01, -0.02, 0.02, -0.03, 0.03),
                 slab: float = 0.005) -> list[Grasp]:
    """The grasps a shape class's rule asks for (top-down; none for class "other").

    * "box": across the short side (closing axis along it) through the footprint's centre and at
      +-15 % of the long side from it, as deep as the fingers go (the palm ``clearance`` m above the
      seen top, the fingertips ``clearance`` m above the table), and 10 mm higher;
    * "long": across the part at ``offsets`` (m) along it from the centre of mass ``com`` (default the
      footprint centre), each centred on the seen cross-section there (the perceived points within
      ``slab`` m along the part) and at the middle of its height (its underside on the table).

    Args:
        shape: The part's :class:`ShapeClass`.
        observed: The perceived points (n, 3), m, world.
        gripper: The jaws (finger length and tip depth set the heights).
        table_z: The table's height (m).
        com: The part's estimated centre of mass (3,), m, world.
        clearance: Room (m) kept by the fingertips over the table and the palm over the part's top.
        offsets: Positions (m) along a long part, from its centre of mass.
        slab: Half-thickness (m) of a long part's cross-section.

    Returns:
        The grasps (world frame), named ``shape-box-<k>`` / ``shape-long-<k>``.
    """
    P = np.asarray(observed, float)
    down = np.array([0.0, 0.0, -1.0])
    z_low = table_z + gripper.tip_depth + clearance
    out: list[Grasp] = []
    if shape.kind == "box":
        short = np.r_[shape.short_axis, 0.0]
        top = table_z + float(shape.extents[2])
        z_deep = max(top + clearance - (gripper.finger_length - gripper.tip_depth), z_low)
        for f in (0.0, -0.15, 0.15):
            c = shape.centre + f * float(shape.extents[0]) * shape.long_axis
            for z in (z_deep, z_deep + 0.01):
                if z < top:
                    out.append(grasp_from_axis([c[0], c[1], z], short, down, float(shape.extents[1]),
                                               f"shape-box-{len(out)}"))
    elif shape.kind == "long":
        ref = shape.centre if com is None else np.asarray(com, float)[:2]
        along = (P[:, :2] - ref) @ shape.long_axis
        across = (P[:, :2] - ref) @ shape.short_axis
        for b in offsets:
            sl = np.abs(along - b) < slab
            if np.count_nonzero(sl) < 3:
                continue
            mid = 0.5 * (float(across[sl].max()) + float(across[sl].min()))
            c = ref + b * shape.long_axis + mid * shape.short_axis
            z = max(0.5 * (table_z + float(P[sl, 2].max())), z_low)
            out.append(grasp_from_axis([c[0], c[1], z], np.r_[shape.short_axis, 0.0], down,
                                       float(np.ptp(across[sl])), f"shape-long-{len(out)}"))
    return out
