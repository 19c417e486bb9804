"""Exact robot-obstacle distances with ``coal`` on the URDF's collision meshes.

Used where the sphere model is too coarse: next to a start or goal that is closer to the obstacles
than the covering spheres allow. Each mesh pair is first measured on the mesh's convex hull (GJK,
about a microsecond; the hull contains the mesh, so its distance is a lower bound); only when the
hull is closer than the threshold is the exact mesh distance (BVH) computed.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

import coal
import numpy as np
import pinocchio as pin
from numba import njit

from robointel.errors import DescriptionError
from robointel.geometry import _kernels as GK
from robointel.geometry.obstacles import Box, Capsule, Cylinder, Obstacle, Sphere
from robointel.planning.part_spheres import mesh_triangles, part_bounds, triangle_spheres
from robointel.robot._ik_kernels import chain_placements
from robointel.robot.model import Robot


@dataclass
class _Part:
    frame: int
    placement: np.ndarray  # (4, 4) mesh in its link frame
    mesh: Any  # coal BVH model
    hull: Any  # coal Convex
    centre: np.ndarray  # bounding-sphere centre in the link frame
    radius: float
    link: str


def contact_distance(ga: Any, Ta: Any, gb: Any, Tb: Any, req: Any) -> float:
    """Coal's distance of two placed geometries, negative (at most -1e-9 m) when they touch or overlap.

    Coal reports 0 (not a depth) for meshes in contact: a collision query decides those.
    """
    d = float(coal.distance(ga, Ta, gb, Tb, req, coal.DistanceResult()))
    if d <= 1e-9 and coal.collide(ga, Ta, gb, Tb, coal.CollisionRequest(), coal.CollisionResult()) > 0:
        return min(d, -1e-9)
    return d


#: GJK's tolerance: a hull distance d is taken GJK_TOL (1 + d / 1 m) lower before it bounds the mesh distance
#: (GJK returns up to ~2e-7 m more than the exact distance near contact, and about 1e-6 of d far from it)
GJK_TOL = 1e-6


def hull_bound(d: float) -> float:
    """A GJK hull distance ``d`` (m) lowered by its tolerance: a lower bound of the exact distance."""
    return d - GJK_TOL * (1.0 + abs(d))


#: security margins (m, above the threshold) at which :func:`bounded_distance` asks coal for a collision
#: before it measures a distance: a pair clear at a margin is proven at least that far apart
MARGINS = (0.004, 0.001)


_THREAD = threading.local()
#: a distance request with coal's defaults (read only)
DISTANCE_REQUEST = coal.DistanceRequest()


def _distance_result() -> Any:
    """This thread's ``coal.DistanceResult``, cleared: one object per thread (making one costs ~1.7 us, clearing 0.3).

    Coal keeps the smallest distance a result has seen, so a result is cleared before each query and never
    shared between threads.
    """
    r = getattr(_THREAD, "result", None)
    if r is None:
        r = _THREAD.result = coal.DistanceResult()
    else:
        r.clear()
    return r


def bounded_distance(hull_a: Any, ga: Any, Ta: Any, hull_b: Any, gb: Any, Tb: Any, thresh: float,
                     req: Any) -> float:
    """A lower bound of the distance of two placed geometries, exact where it is below ``thresh``.

    The convex hulls' distance first (GJK, a lower bound); where it is at or below ``thresh``, collision
    queries with security margins ``thresh`` + :data:`MARGINS` (a clear query proves the distance is
    at least that margin) and finally at ``thresh`` itself; only a pair closer than ``thresh`` gets
    coal's exact mesh distance (:func:`contact_distance`, negative in contact). A mesh distance costs
    0.4-0.9 ms on the UR5's forearm and wrist against 10-70 us for a collision query.

    Args:
        hull_a: convex hull of the first geometry (or the primitive itself).
        ga: the first geometry (BVH mesh or primitive).
        Ta: its placement (``coal.Transform3s``).
        hull_b: as ``hull_a``, of the second.
        gb: the second geometry.
        Tb: its placement.
        thresh: the threshold, m (below 0: as 0, contact decided by a collision query).
        req: a ``coal.DistanceRequest``.

    Returns:
        The distance, m: exact when below ``thresh``, else a lower bound >= ``thresh``.
    """
    d = hull_bound(float(coal.distance(hull_a, Ta, hull_b, Tb, req, _distance_result())))
    if d > thresh:
        return d
    t0 = max(thresh, 0.0)  # (coal takes no negative margin for meshes: a contact is a contact)
    creq = coal.CollisionRequest()
    for m in MARGINS:
        creq.security_margin = t0 + m
        if not coal.collide(ga, Ta, gb, Tb, creq, coal.CollisionResult()):
            return t0 + m
    creq.security_margin = t0
    if not coal.collide(ga, Ta, gb, Tb, creq, coal.CollisionResult()):
        return t0
    return min(contact_distance(ga, Ta, gb, Tb, req), t0 - 1e-12)  # closer than t0: the query said so


def placed_clear(hull_a: Any, ga: Any, Ta: Any, hull_b: Any, gb: Any, Tb: Any, margin: float) -> bool:
    """Whether two placed geometries are proven at least ``margin`` (m) apart.

    The convex hulls' distance (GJK, less its tolerance) first; below ``margin``, coal's collision query
    on the geometries with ``margin`` (at least 0) as its security margin. Arguments as
    :func:`bounded_distance`.
    """
    if hull_bound(float(coal.distance(hull_a, Ta, hull_b, Tb, DISTANCE_REQUEST, _distance_result()))) >= margin:
        return True
    creq = coal.CollisionRequest()
    creq.security_margin = max(margin, 0.0)
    return not coal.collide(ga, Ta, gb, Tb, creq, coal.CollisionResult())


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The cross product a x b of two 3-vectors (``np.cross`` without its broadcasting overhead)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _axis_frame(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A rotation whose z axis points from a to b."""
    u = (b - a) / np.linalg.norm(b - a)
    x = _cross(u, np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0]))
    x /= np.linalg.norm(x)
    return np.stack([x, _cross(u, x), u], 1)


@njit(cache=True)
def frame_placements(q: np.ndarray, parent: np.ndarray, place: np.ndarray, axis: np.ndarray, kind: np.ndarray,
                     qidx: np.ndarray, frame_joint: np.ndarray, frame_place: np.ndarray, T: np.ndarray,
                     out: np.ndarray) -> None:  # pragma: no cover - compiled
    """out[f] = the world placement (4, 4) at q of a frame on joint ``frame_joint[f]`` at ``frame_place[f]``.

    The joints' placements T (nj, 4, 4) by the chain kernel (:func:`~robointel.robot._ik_kernels.chain_placements`,
    the chain arrays of :func:`~robointel.robot.chain.chain_arrays`); Pinocchio's ``oMf`` of those frames.
    """
    for r in range(4):
        for c in range(4):
            T[0, r, c] = 1.0 if r == c else 0.0
    chain_placements(q, parent, place, axis, kind, qidx, T)
    for f in range(frame_joint.shape[0]):
        A, B = T[frame_joint[f]], frame_place[f]
        for r in range(3):
            for c in range(4):
                out[f, r, c] = A[r, 0] * B[0, c] + A[r, 1] * B[1, c] + A[r, 2] * B[2, c] + A[r, 3] * B[3, c]
        out[f, 3, 0], out[f, 3, 1], out[f, 3, 2], out[f, 3, 3] = 0.0, 0.0, 0.0, 1.0


def warm_broad_phase() -> None:
    """Compile (or load from numba's disk cache) the broad phase and :func:`frame_placements`."""
    i1, f1 = np.zeros(1, np.int64), np.zeros(1)
    part_bounds(np.zeros((1, 4, 4)), i1, np.zeros((1, 3)), f1, np.zeros((1, 3)), f1, np.array([0, 1], np.int64), i1,
                np.zeros((1, GK.NPARAM)), i1, i1, f1)
    i2, T = np.array([-1, 0], np.int64), np.zeros((2, 4, 4))
    frame_placements(f1, i2, T, np.zeros((2, 3)), i2, i2, i1, np.zeros((1, 4, 4)), T.copy(), np.zeros((1, 4, 4)))


class MeshGeometry:
    """The moving links' collision meshes and the primitive obstacles as ``coal`` objects.

    Args:
        robot: the arm (its URDF collision meshes are loaded next to the URDF).
        obstacles: primitives in the world frame (point clouds are not handled here).
    """

    def __init__(self, robot: Robot, obstacles: list[Obstacle]) -> None:
        self.robot = robot
        key = (id(robot), str(robot.urdf_path))
        if key not in _PARTS:  # the robot side (meshes, hulls, levers), built once per robot
            _PARTS[key] = _RobotMeshes(robot, _parts(robot))
        side = _PARTS[key]
        self.parts = side.parts
        #: (label, coal geometry, its placement) of each obstacle coal can place
        self.obstacles: list[tuple[str, Any, Any]] = []
        kept = []
        for k, o in enumerate(obstacles):
            g = _coal_obstacle(o)
            if g is not None:
                self.obstacles.append((o.label(k), g[0], g[1]))
                kept.append(o)
        # each obstacle as a primitive of the compiled distance (part_spheres.part_bounds)
        self._types = np.array([o._code for o in kept], dtype=np.int64)
        packed = [np.asarray(o._packed, dtype=np.float64) for o in kept]  # type: ignore[attr-defined]
        self._params = np.array(packed, dtype=np.float64).reshape(-1, GK.NPARAM)
        self.part_lever = side.part_lever
        #: (P * O, n): the distance of (part p, obstacle o), pair p * O + o, changes at most
        #: sum_k pair_lever[., k] |dq_k| (m)
        self.pair_lever = np.repeat(side.part_lever, len(self.obstacles), axis=0)
        self._req = coal.DistanceRequest()
        self._frames, self._part_frame = side.frames, side.part_frame
        self._frame_joint, self._frame_place = side.frame_joint, side.frame_place
        self._centres, self._radii = side.centres, side.radii
        self._cells = (side.sub_centres, side.sub_radii, side.sub_start)
        P, O = len(self.parts), len(self.obstacles)
        self._all_pp, self._all_oo = np.repeat(np.arange(P), O), np.tile(np.arange(O), P)  # every pair p * O + o

    def _bounds(self, Tl: np.ndarray, pp: np.ndarray, oo: np.ndarray, out: np.ndarray) -> None:
        """out[n] = a lower bound of the distance of (part pp[n], obstacle oo[n]) at the link placements Tl, m."""
        part_bounds(Tl, self._part_frame, self._centres, self._radii, *self._cells, self._types, self._params, pp, oo,
                    out)

    @property
    def empty(self) -> bool:
        """True when there is no mesh or no obstacle to measure."""
        return not self.parts or not self.obstacles

    def clearance(self, q: np.ndarray, *, cap: float = 1.0, thresh: float = 0.0) -> tuple[float, str, str]:
        """Smallest distance (capped at ``cap``) between a moving link mesh and an obstacle.

        Each pair is bounded by :func:`bounded_distance` (hull, then collision queries with
        margins) and measured on the mesh only below ``thresh`` (and below the smallest distance
        found so far): the result is exact below ``thresh`` and a lower bound above it. The (part,
        obstacle) pairs are measured in
        the order of a lower bound (the part's spheres to the obstacle, :meth:`_bounds`) and not at
        all once that bound reaches the smallest distance found: the result is the minimum over
        every pair.

        Args:
            q: (n,) configuration, rad.
            cap: larger distances are reported as ``cap``, m.
            thresh: hull distances below this are refined on the mesh, m.

        Returns:
            (distance m, link, obstacle label); negative distances are penetration depths.
        """
        best, bl, bo = cap, "", ""
        if not self.parts or not self.obstacles:
            return best, bl, bo
        Tl = self._frame_placements(q)
        # broad phase: every part's spheres against every obstacle, pair p * O + o
        flat = np.empty(len(self._all_pp))
        self._bounds(Tl, self._all_pp, self._all_oo, flat)
        cand = np.flatnonzero(flat < best)
        if cand.size == 0:
            return best, bl, bo
        order = cand[np.argsort(flat[cand], kind="stable")]
        nobs = len(self.obstacles)
        req = coal.DistanceRequest()
        placed: dict[int, Any] = {}
        for k in order:
            if flat[k] >= best:
                break
            p, o = divmod(int(k), nobs)
            part = self.parts[p]
            Tp = placed.get(p)
            if Tp is None:
                T = Tl[self._part_frame[p]] @ part.placement
                Tp = placed[p] = coal.Transform3s(T[:3, :3], T[:3, 3])
            label, g, To = self.obstacles[o]
            d = bounded_distance(part.hull, part.mesh, Tp, g, g, To, min(thresh, best), req)
            if d < best:
                best, bl, bo = float(d), part.link, label
        return best, bl, bo

    def pair_distances(self, q: np.ndarray, which: np.ndarray, *, thresh: float,
                       near: float = 0.01) -> np.ndarray:
        """Distances (len(which),) of the (part, obstacle) pairs ``which`` (p * O + o) at q.

        Exact below ``thresh``, else lower bounds above it: the part's spheres to the obstacle (:meth:`_bounds`)
        where that is more than ``near`` (m) above ``thresh``, else the convex hull's distance
        (:func:`bounded_distance`, refined on the mesh below ``thresh``).
        """
        if len(which) == 0:
            return np.empty(0)
        Tl = self._frame_placements(q)
        pp, oo = np.divmod(np.asarray(which, np.int64), len(self.obstacles))
        out = np.empty(len(pp))  # the broad phase
        self._bounds(Tl, pp, oo, out)
        placed: dict[int, Any] = {}  # each part's coal placement
        for n in np.flatnonzero(out <= thresh + near).tolist():
            p, o = int(pp[n]), int(oo[n])
            part = self.parts[p]
            T = placed.get(p)
            if T is None:
                Mp = Tl[self._part_frame[p]] @ part.placement
                T = placed[p] = coal.Transform3s(Mp[:3, :3], Mp[:3, 3])
            _, g, To = self.obstacles[o]
            out[n] = bounded_distance(part.hull, part.mesh, T, g, g, To, thresh, self._req)
        return out

    def pair_clear(self, Tl: np.ndarray, i: int, margin: float) -> bool:
        """Whether the (part, obstacle) pair ``i`` (p * O + o) is at least ``margin`` (m, >= 0) apart.

        A yes is a proof: the part's spheres to the obstacle (:meth:`_bounds`), then the convex hulls' distance
        (GJK, less its tolerance), then coal's collision query on the mesh with ``margin`` as its security
        margin (85-175 us a call on the UR5's finger tip near a shelf, against ~560 us for its mesh distance).

        Args:
            Tl: (F, 4, 4) the link frames' placements, :meth:`link_placements` at the configuration.
            i: the pair.
            margin: the distance to prove, m.
        """
        p, o = divmod(int(i), len(self.obstacles))
        one = np.empty(1)
        self._bounds(Tl, np.array([p], np.int64), np.array([o], np.int64), one)
        if one[0] >= margin:
            return True
        part = self.parts[p]
        Mp = Tl[self._part_frame[p]] @ part.placement
        _, g, To = self.obstacles[o]
        return placed_clear(part.hull, part.mesh, coal.Transform3s(Mp[:3, :3], Mp[:3, 3]), g, g, To, margin)

    def link_placements(self, q: np.ndarray) -> np.ndarray:
        """(F, 4, 4) the world placements at q (n,) of the link frames that carry parts, for :meth:`pair_clear`."""
        return self._frame_placements(q)

    def _frame_placements(self, q: np.ndarray) -> np.ndarray:
        """(F, 4, 4) the placements at q of the link frames that carry parts (``self._frames``)."""
        robot = self.robot
        if robot._chain_batch:  # compiled over the joint chain
            out = np.empty((len(self._frames), 4, 4))
            frame_placements(np.asarray(q, float), *robot.chain, self._frame_joint, self._frame_place,
                             np.empty((robot.model.njoints, 4, 4)), out)
            return out
        pin.framesForwardKinematics(robot.model, robot.data, q)
        oMf = robot.data.oMf
        return np.array([oMf[f].homogeneous for f in self._frames])

    def pair_names(self, i: int) -> tuple[str, str]:
        """(link, obstacle label) of pair ``i`` (p * O + o)."""
        p, o = divmod(int(i), len(self.obstacles))
        return self.parts[p].link, self.obstacles[o][0]


class _RobotMeshes:
    """What :class:`MeshGeometry` needs of the robot alone (shared read-only by every instance).

    ``part_lever``: :func:`_part_levers`; per part its link frame (an index into the distinct
    ``frames``), bounding-sphere centre and radius, and its cell spheres
    (:func:`~robointel.planning.part_spheres.triangle_spheres`: part p's are ``sub_start[p]:sub_start[p + 1]``).
    """

    def __init__(self, robot: Robot, parts: list[_Part]) -> None:
        self.parts = parts
        self.part_lever = _part_levers(robot, parts)
        self.frames = sorted({p.frame for p in parts})
        #: each frame's joint and placement on it (Pinocchio's frame tree, for the compiled placements)
        self.frame_joint = np.array([robot.model.frames[f].parentJoint for f in self.frames], np.int64)
        self.frame_place = np.array([robot.model.frames[f].placement.homogeneous for f in self.frames],
                                    float).reshape(-1, 4, 4)
        self.part_frame = np.array([self.frames.index(p.frame) for p in parts], int)
        self.centres = np.array([p.centre for p in parts], float).reshape(-1, 3)
        self.radii = np.array([p.radius for p in parts], float)
        # each mesh part's cell spheres (part_spheres.triangle_spheres) in its link frame; none for a primitive
        cells = [triangle_spheres(*mesh_triangles(p.mesh)) for p in parts]
        self.sub_centres = np.concatenate([c @ p.placement[:3, :3].T + p.placement[:3, 3]
                                           for (c, _), p in zip(cells, parts)] + [np.zeros((0, 3))])
        self.sub_radii = np.concatenate([r for _, r in cells] + [np.zeros(0)])
        self.sub_start = np.concatenate([[0], np.cumsum([len(r) for _, r in cells], dtype=np.int64)]).astype(np.int64)
        for a in (self.part_lever, self.part_frame, self.centres, self.radii, self.sub_centres, self.sub_radii,
                  self.sub_start):
            a.flags.writeable = False


_PARTS: dict[tuple[int, str], _RobotMeshes] = {}


def _part_levers(robot: Robot, parts: list[_Part]) -> np.ndarray:
    """(P, n) bound of the speed of any point of each part per unit speed of each joint, m/rad (1: prismatic).

    A point moved by revolute joint k moves at most |dq_k| times its distance from the joint's origin,
    bounded by the part's bounding sphere (centre distance + radius) plus the joint offsets down the chain.
    """
    m = robot.model
    out = np.zeros((len(parts), robot.nq))
    for i, p in enumerate(parts):
        lev = out[i]
        f = m.frames[p.frame]
        j = int(f.parentJoint)
        reach = float(np.linalg.norm(f.placement.act(p.centre))) + p.radius
        while j > 0:
            k = int(m.joints[j].idx_q)
            prismatic = m.joints[j].shortname().startswith("JointModelP") and "Planar" not in m.joints[j].shortname()
            lev[k] = max(lev[k], 1.0 if prismatic else reach)
            reach += float(np.linalg.norm(m.jointPlacements[j].translation))
            j = int(m.parents[j])
    return out


def coal_geometry(link: str, p: dict) -> tuple[Any, Any, np.ndarray, float] | None:
    """Coal geometry of one collision primitive of ``link``: (geometry, hull, bounding centre, radius).

    The hull is a mesh's convex hull (a primitive is its own); the centre (3,) is in the
    primitive's own frame; meshes are scaled. None for an unknown type.

    Raises:
        DescriptionError: a mesh file coal cannot read.
    """
    size = np.asarray(p["size"], float)
    if p["type"] == "mesh":
        try:
            g = coal.MeshLoader().load(str(p["path"]), size)
        except Exception as exc:  # coal raises RuntimeError/ValueError wrappers of assimp failures
            raise DescriptionError(f"cannot read the collision mesh {p['path']} of link {link!r}: {exc}",
                                   value=str(p["path"])) from None
        g.buildConvexHull(True, "Qt")
        v = np.asarray(g.vertices())
        c = 0.5 * (v.min(0) + v.max(0))
        return g, g.convex, c, float(np.max(np.linalg.norm(v - c, axis=1)))
    if p["type"] == "box":
        return coal.Box(*size), coal.Box(*size), np.zeros(3), float(np.linalg.norm(size) / 2)
    if p["type"] == "cylinder":
        g = coal.Cylinder(size[0], size[1])
        return g, g, np.zeros(3), float(np.hypot(size[0], size[1] / 2))
    if p["type"] == "capsule":
        g = coal.Capsule(size[0], size[1])
        return g, g, np.zeros(3), float(size[0] + size[1] / 2)
    if p["type"] == "sphere":
        g = coal.Sphere(size[0])
        return g, g, np.zeros(3), float(size[0])
    return None


def _parts(robot: Robot) -> list[_Part]:
    """Geometry (meshes and primitives) and convex hulls of the moving links (loaded once per robot)."""
    parts: list[_Part] = []
    for link, prims in robot.collision_primitives().items():
        if link not in robot.link_names or robot.link_joint(link) == 0:
            continue
        fid = robot.frame_id(link)
        for p in prims:
            if p["type"] == "mesh" and p.get("path") is None:
                continue
            got = coal_geometry(link, p)
            if got is None:
                continue
            g, hull, c, r = got
            M = np.asarray(p["origin"], float)
            parts.append(_Part(fid, M, g, hull, M[:3, :3] @ c + M[:3, 3], r, link))
    return parts


def _coal_obstacle(o: Obstacle) -> tuple[Any, Any] | None:
    if isinstance(o, Box):
        return coal.Box(*o.size), coal.Transform3s(o.rotation, o.center)
    if isinstance(o, Sphere):
        return coal.Sphere(o.radius), coal.Transform3s(np.eye(3), o.center)
    if isinstance(o, (Cylinder, Capsule)):
        a, b = np.asarray(o.a, float), np.asarray(o.b, float)
        L = float(np.linalg.norm(b - a))
        g = coal.Cylinder(o.radius, L) if isinstance(o, Cylinder) else coal.Capsule(o.radius, L)
        return g, coal.Transform3s(_axis_frame(a, b), (a + b) / 2)
    return None
