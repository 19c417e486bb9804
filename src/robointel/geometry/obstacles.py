"""Obstacle shapes with exact signed distances (Ch. 4, Fig. 4.2; Ch. 7 collision constraints).

Every shape is a small frozen dataclass validated on construction; its arrays are read-only so a
shape can be shared, cached and moved only through :meth:`Obstacle.translated` /
:meth:`Obstacle.moved` / :meth:`Obstacle.transformed`, which return new shapes (moving obstacles in
replanning). ``distance(points)`` returns, for ``points`` (m, 3) in metres:

* ``d`` (m,): signed distance from each point to the surface, negative inside;
* ``closest`` (m, 3): the nearest point on the obstacle surface;
* ``normal`` (m, 3): unit vector from the obstacle toward the point, the gradient of ``d`` with
  respect to the point (outward also for inside points), so ``d(p + e n) ~ d(p) + e``.

Where the nearest surface point is not unique (a point exactly on a capsule or cylinder axis, the
centre of a sphere, equidistant box faces) a valid choice is returned, never NaN.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from robointel._validate import as_array
from robointel.errors import InvalidInput
from robointel.geometry import _kernels as K
from robointel.geometry.rotations import check_rotation, quat_to_matrix, rpy_to_matrix

__all__ = ["Obstacle", "Sphere", "Capsule", "Cylinder", "Box", "PointCloud", "obstacle_from_dict",
           "OBSTACLE_TYPES"]


def _vec3(x: ArrayLike, name: str) -> np.ndarray:
    a = as_array(x, name, (3,)).copy()
    a.flags.writeable = False
    return a


def _positive(x: ArrayLike, name: str) -> float:
    v = float(as_array(x, name, ()))
    if not v > 0.0:
        raise InvalidInput(f"{name} must be positive (metres), got {v!r}", value=x)
    return v


def _points(points: ArrayLike) -> np.ndarray:
    P = np.asarray(points, float) if not isinstance(points, np.ndarray) else points
    if P.ndim == 1 and P.shape == (3,):
        P = P[None]
    P = as_array(P, "points", (None, 3))
    return np.ascontiguousarray(P, dtype=float)


def _perpendicular(u: np.ndarray) -> np.ndarray:
    """A fixed unit vector perpendicular to unit ``u``."""
    t = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e = t - (t @ u) * u
    return e / np.linalg.norm(e)


@dataclass(frozen=True, eq=False)
class Obstacle:
    """Base of all obstacle shapes. Subclasses set :attr:`type` and implement the packing."""

    type: ClassVar[str] = "obstacle"
    _code: ClassVar[int] = -1

    def __setstate__(self, state: dict) -> None:
        """Unpickling: restore the fields and keep the arrays read-only (immutable shapes)."""
        for k, v in state.items():
            if isinstance(v, np.ndarray):
                v = v.copy()
                v.flags.writeable = False
            object.__setattr__(self, k, v)

    # geometry ---------------------------------------------------------------
    def distance(self, points: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Signed distance of ``points`` (m, 3) (or one point (3,)) to the surface.

        Returns:
            d (m,) metres, negative inside; closest (m, 3) points on the surface; normal (m, 3)
            unit vectors from the obstacle toward the points (the gradient of d).
        """
        P = _points(points)
        return K.point_distances(self._code, self._packed, P)  # type: ignore[attr-defined]  # every subclass packs

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounding box (lower (3,), upper (3,)) in metres."""
        raise NotImplementedError  # pragma: no cover

    # moving -----------------------------------------------------------------
    def transformed(self, T: ArrayLike) -> Obstacle:
        """The shape moved by the rigid transform ``T`` (4x4, applied in the world frame)."""
        raise NotImplementedError  # pragma: no cover

    def translated(self, offset: ArrayLike) -> Obstacle:
        """The shape shifted by ``offset`` (3,) metres."""
        T = np.eye(4)
        T[:3, 3] = as_array(offset, "offset", (3,))
        return self.transformed(T)

    def moved(self, center: ArrayLike) -> Obstacle:
        """The shape translated so that its reference point is at ``center`` (3,), m.

        The shape translated so that its reference point ``center`` (the centre of a sphere or box, the axis
        mid-point of a capsule or cylinder, the centroid of a point cloud) is at ``center`` (3,).
        """
        return self.translated(as_array(center, "center", (3,)) - self.center)  # type: ignore[attr-defined]

    # files ------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """Plain data for YAML/JSON scenes: ``{"type": ..., <params>, "name": ...}``."""
        d: dict[str, Any] = {"type": self.type}
        d.update({k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in self._fields().items()})
        if getattr(self, "name", None) is not None:
            d["name"] = self.name  # type: ignore[attr-defined]
        return d

    def _fields(self) -> dict[str, Any]:  # pragma: no cover - overridden
        raise NotImplementedError

    def label(self, index: int | None = None) -> str:
        """Name for messages: the ``name`` or ``"<type>[index]"``."""
        name = getattr(self, "name", None)
        if name:
            return str(name)
        return self.type if index is None else f"{self.type}[{index}]"


def _rigid(T: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    T = as_array(T, "T", (4, 4))
    return check_rotation(T[:3, :3], "T[:3, :3]"), T[:3, 3].copy()


@dataclass(frozen=True, eq=False)
class Sphere(Obstacle):
    """Ball of ``radius`` (m) about ``center`` (3,)."""

    center: np.ndarray
    radius: float
    name: str | None = None
    _packed: np.ndarray = field(init=False, repr=False)

    type: ClassVar[str] = "sphere"
    _code: ClassVar[int] = K.SPHERE

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec3(self.center, "center"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))
        p = np.zeros(K.NPARAM)
        p[:3], p[3] = self.center, self.radius
        p.flags.writeable = False
        object.__setattr__(self, "_packed", p)

    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Axis-aligned bounding box (lower (3,), upper (3,)) in metres."""
        return self.center - self.radius, self.center + self.radius

    def transformed(self, T: ArrayLike) -> Sphere:
        """The shape moved by the rigid transform ``T`` (4, 4)."""
        R, t = _rigid(T)
        return replace(self, center=R @ self.center + t)

    def _fields(self) -> dict[str, Any]:
        return {"center": self.center, "radius": self.radius}


@dataclass(frozen=True, eq=False)
class Capsule(Obstacle):
    """Points within ``radius`` (m) of the segment from ``a`` to ``b`` (3,) (a == b: a sphere)."""

    a: np.ndarray
    b: np.ndarray
    radius: float
    name: str | None = None
    _packed: np.ndarray = field(init=False, repr=False)

    type: ClassVar[str] = "capsule"
    _code: ClassVar[int] = K.CAPSULE

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", _vec3(self.a, "a"))
        object.__setattr__(self, "b", _vec3(self.b, "b"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))
        v = self.b - self.a
        L = float(np.linalg.norm(v))
        u = v / L if L > 1e-12 else np.array([0.0, 0.0, 1.0])
        p = np.zeros(K.NPARAM)
        p[:3], p[3:6], p[6], p[7], p[8:11] = self.a, u, (L if L > 1e-12 else 0.0), self.radius, _perpendicular(u)
        p.flags.writeable = False
        object.__setattr__(self, "_packed", p)

    @property
    def length(self) -> float:
        """Segment length |b - a| (m)."""
        return float(self._packed[6])

    @property
    def center(self) -> np.ndarray:
        """Reference point (3,), m: the axis mid-point (the centroid for a point cloud)."""
        return (self.a + self.b) / 2

    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Axis-aligned bounding box (lower (3,), upper (3,)) in metres."""
        return np.minimum(self.a, self.b) - self.radius, np.maximum(self.a, self.b) + self.radius

    def transformed(self, T: ArrayLike) -> Capsule:
        """The shape moved by the rigid transform ``T`` (4, 4)."""
        R, t = _rigid(T)
        return replace(self, a=R @ self.a + t, b=R @ self.b + t)

    def _fields(self) -> dict[str, Any]:
        return {"a": self.a, "b": self.b, "radius": self.radius}


@dataclass(frozen=True, eq=False)
class Cylinder(Obstacle):
    """Finite solid cylinder with flat caps: axis from ``a`` to ``b`` (3,), ``radius`` (m)."""

    a: np.ndarray
    b: np.ndarray
    radius: float
    name: str | None = None
    _packed: np.ndarray = field(init=False, repr=False)

    type: ClassVar[str] = "cylinder"
    _code: ClassVar[int] = K.CYLINDER

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", _vec3(self.a, "a"))
        object.__setattr__(self, "b", _vec3(self.b, "b"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))
        v = self.b - self.a
        L = float(np.linalg.norm(v))
        if not L > 1e-9:
            raise InvalidInput("cylinder end points a and b must differ (length > 0); use a Sphere or "
                               "a Capsule for a degenerate shape", value=(self.a, self.b))
        u = v / L
        p = np.zeros(K.NPARAM)
        p[:3], p[3:6], p[6], p[7], p[8:11] = (self.a + self.b) / 2, u, L / 2, self.radius, _perpendicular(u)
        p.flags.writeable = False
        object.__setattr__(self, "_packed", p)

    @property
    def length(self) -> float:
        """Axis length |b - a| (m)."""
        return 2.0 * float(self._packed[6])

    @property
    def axis(self) -> np.ndarray:
        """Unit axis (b - a) / |b - a|."""
        return self._packed[3:6].copy()

    @property
    def center(self) -> np.ndarray:
        """Reference point (3,), m: the axis mid-point (the centroid for a point cloud)."""
        return (self.a + self.b) / 2

    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Axis-aligned bounding box (lower (3,), upper (3,)) in metres."""
        u = self._packed[3:6]
        ext = self.radius * np.sqrt(np.clip(1.0 - u * u, 0.0, None))  # disc extent per axis
        return np.minimum(self.a, self.b) - ext, np.maximum(self.a, self.b) + ext

    def transformed(self, T: ArrayLike) -> Cylinder:
        """The shape moved by the rigid transform ``T`` (4, 4)."""
        R, t = _rigid(T)
        return replace(self, a=R @ self.a + t, b=R @ self.b + t)

    def _fields(self) -> dict[str, Any]:
        return {"a": self.a, "b": self.b, "radius": self.radius}


@dataclass(frozen=True, eq=False)
class Box(Obstacle):
    """Oriented box.

    ``center`` (3,), full edge lengths ``size`` (3,) m, ``rotation`` (3x3) of the box axes in the world frame.
    """

    center: np.ndarray
    size: np.ndarray
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    name: str | None = None
    _packed: np.ndarray = field(init=False, repr=False)

    type: ClassVar[str] = "box"
    _code: ClassVar[int] = K.BOX

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec3(self.center, "center"))
        size = _vec3(self.size, "size")
        if not np.all(size > 0):
            raise InvalidInput(f"box size (full extents) must be positive, got {size.tolist()}", value=size)
        object.__setattr__(self, "size", size)
        R = check_rotation(self.rotation, "rotation")
        R.flags.writeable = False
        object.__setattr__(self, "rotation", R)
        p = np.zeros(K.NPARAM)
        p[:3], p[3:6], p[6:15] = self.center, size / 2, R.ravel()
        p.flags.writeable = False
        object.__setattr__(self, "_packed", p)

    @property
    def half(self) -> np.ndarray:
        """Half extents (3,)."""
        return self.size / 2

    @property
    def pose(self) -> np.ndarray:
        """4x4 pose of the box frame in the world."""
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = self.rotation, self.center
        return T

    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Axis-aligned bounding box (lower (3,), upper (3,)) in metres."""
        ext = np.abs(self.rotation) @ (self.size / 2)
        return self.center - ext, self.center + ext

    def transformed(self, T: ArrayLike) -> Box:
        """The shape moved by the rigid transform ``T`` (4, 4)."""
        R, t = _rigid(T)
        return replace(self, center=R @ self.center + t, rotation=R @ self.rotation)

    def _fields(self) -> dict[str, Any]:
        f: dict[str, Any] = {"center": self.center, "size": self.size}
        if not np.allclose(self.rotation, np.eye(3), atol=0.0):
            f["rotation"] = self.rotation
        return f


@dataclass(frozen=True, eq=False)
class PointCloud(Obstacle):
    """Points (N, 3), each inflated by ``radius`` >= 0 (m).

    Distance to the nearest point minus ``radius`` (a k-d tree query, :class:`scipy.spatial.cKDTree`). Inside a ball
    the value is the depth below that ball's surface (exact outside the union of balls, conservative inside).
    """

    points: np.ndarray
    radius: float = 0.0
    name: str | None = None
    tree: cKDTree = field(init=False, repr=False)

    type: ClassVar[str] = "pointcloud"
    _code: ClassVar[int] = -1

    def __post_init__(self) -> None:
        P = np.ascontiguousarray(as_array(self.points, "points", (None, 3)))
        if len(P) == 0:
            raise InvalidInput("a point cloud needs at least one point", value=P)
        P.flags.writeable = False
        object.__setattr__(self, "points", P)
        r = float(as_array(self.radius, "radius", ()))
        if r < 0:
            raise InvalidInput(f"point-cloud radius must be >= 0 (metres), got {r!r}", value=r)
        object.__setattr__(self, "radius", r)
        object.__setattr__(self, "tree", cKDTree(P))

    def distance(self, points: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Signed distances (m,), closest points (m, 3) and normals (m, 3) of ``points`` (m, 3), m."""
        P = _points(points)
        dist, idx = self.tree.query(P)
        near = self.points[idx]
        v = P - near
        n = np.empty_like(v)
        ok = dist > 1e-12
        n[ok] = v[ok] / dist[ok, None]
        n[~ok] = (0.0, 0.0, 1.0)
        return dist - self.radius, near + self.radius * n, n

    @property
    def center(self) -> np.ndarray:
        """Reference point (3,), m: the axis mid-point (the centroid for a point cloud)."""
        return self.points.mean(0)

    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Axis-aligned bounding box (lower (3,), upper (3,)) in metres."""
        return self.points.min(0) - self.radius, self.points.max(0) + self.radius

    def transformed(self, T: ArrayLike) -> PointCloud:
        """The shape moved by the rigid transform ``T`` (4, 4)."""
        R, t = _rigid(T)
        return replace(self, points=self.points @ R.T + t)

    def _fields(self) -> dict[str, Any]:
        return {"points": self.points, "radius": self.radius}


OBSTACLE_TYPES: dict[str, type[Obstacle]] = {c.type: c for c in (Sphere, Capsule, Cylinder, Box, PointCloud)}
_ALIASES = {"point_cloud": "pointcloud", "cloud": "pointcloud", "ball": "sphere", "cuboid": "box"}


def obstacle_from_dict(d: dict) -> Obstacle:
    """Build an obstacle from :meth:`Obstacle.to_dict` output (YAML scenes).

    Accepts flat ``{"type": "box", "center": ..., "size": ..., "name": ...}`` or nested
    ``{"type": ..., "params": {...}, "name": ...}``. A box's orientation may be given as
    ``rotation`` (3x3), ``rpy`` (rad) or ``quat`` (w, x, y, z).

    Raises:
        InvalidInput: unknown type, missing or unknown parameters, invalid values.
    """
    if not isinstance(d, dict) or "type" not in d:
        raise InvalidInput(f"an obstacle must be a mapping with a 'type' ({', '.join(OBSTACLE_TYPES)}), got {d!r}",
                           value=d)
    kind = str(d["type"]).lower()
    kind = _ALIASES.get(kind, kind)
    if kind not in OBSTACLE_TYPES:
        raise InvalidInput(f"unknown obstacle type {d['type']!r}; use one of {', '.join(OBSTACLE_TYPES)}",
                           value=d)
    params = dict(d.get("params") or {})
    params.update({k: v for k, v in d.items() if k not in ("type", "params")})
    if kind == "box":
        rots = [k for k in ("rotation", "rpy", "quat") if k in params]
        if len(rots) > 1:
            raise InvalidInput(f"box orientation given twice ({rots}); use one of rotation, rpy, quat", value=d)
        if "rpy" in params:
            params["rotation"] = rpy_to_matrix(params.pop("rpy"))
        elif "quat" in params:
            params["rotation"] = quat_to_matrix(params.pop("quat"))
    cls = OBSTACLE_TYPES[kind]
    try:
        return cls(**params)
    except TypeError as exc:
        raise InvalidInput(f"bad parameters for a {kind} obstacle: {exc}", value=d) from None
