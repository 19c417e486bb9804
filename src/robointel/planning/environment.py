"""The planning environment.

The robot's collision spheres, the obstacles around it (primitives and
a point cloud), self-collision pairs and tool-attached objects, packed for the compiled checks.

A configuration q is valid when every robot sphere keeps distance >= d_min to every obstacle
(constraint (7.2) of the CFS planner, d(x, O) >= d_min) and no two self-collision spheres overlap.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from robointel._validate import as_array
from robointel.errors import CollisionAtStart, InvalidInput
from robointel.geometry import _kernels as GK
from robointel.geometry.obstacles import Box, Capsule, Cylinder, Obstacle, PointCloud, Sphere
from robointel.planning import _collision_kernels as K
from robointel.planning._sphere_pack import (
    _chain_arrays,
    _levers,
    _sphere_levers,
    _variable_pairs,
    culling_groups,
    robot_cache,
)
from robointel.planning.sphere_file import urdf_spheres
from robointel.robot.collision import SphereModel, primitive_spheres
from robointel.robot.model import Robot
from robointel.robot.sphere_cover import cover_meshes
from robointel.robot.srdf import disabled_pairs

#: Cells of the point-cloud grid are at least this large (m).
CLOUD_CELL = 0.02
_MAX_CELLS = 2_000_000


@dataclass(frozen=True)
class Contact:
    """The closest pair at a configuration: distance (m), the robot link and what it meets."""

    distance: float
    link: str
    other: str
    self_collision: bool

    def message(self, what: str) -> str:
        """A sentence naming the pair, for errors."""
        kind = "link" if self.self_collision else "obstacle"
        return (f"{what} is in collision: robot link {self.link!r} is {self.distance * 1e3:.1f} mm from "
                f"{kind} {self.other!r}")


#: the attributes :meth:`Environment._pack_spheres` derives from the robot alone (cached per robot)
_PACKED = ("spheres", "_chain", "sphere_links", "sphere_order", "lever", "_self", "_rel", "_fitted", "_cover")


class Environment:
    """Obstacles and the robot's collision model, packed for the compiled planner kernels.

    Args:
        robot: the arm.
        obstacles: primitives (spheres, capsules, cylinders, boxes with any rotation) and point
            clouds (merged into one gridded cloud), in the world frame.
        srdf: SRDF file whose ``disable_collisions`` link pairs are not checked for self-collision.
        spheres: the robot's spheres: a :class:`SphereModel`, a spherized URDF path, or None for
            ``robot.spheres``.
        floor: height (m) of a floor plane (a large box below it), or None.
        attached: objects carried by the tool, each given in the frame of ``attach_link``.
        attach_link: link the attached objects move with (default: the robot's flange frame's link).
        exact_self: decide self-collision on the exact collision geometry (the URDF's meshes and
            primitives) at the start, the goals and along every trajectory. Default: True with the
            robot's own fitted spheres (:attr:`Robot.spheres`, which lie inside the meshes) and with a
            spherized URDF (such files leave parts of the meshes outside every sphere: VAMP's UR5 and
            Fetch files 3-57 mm); False with a :class:`SphereModel` given as such, which is trusted.
        self_padding: clearance required between the robot's own links, m, separate from the
            obstacle clearance ``d_min`` of a plan (the planner offsets the self-collision radii by
            (d_min - self_padding) / 2 each, so that both hold with one threshold).
        cover_meshes: also build spheres grown to cover the URDF's collision meshes
            (:func:`robointel.robot.sphere_cover.cover_meshes`) and check obstacles against them
            (see :meth:`use`); self-collision always uses the spheres as given.

    The robot side (the bound spheres, self-collision pairs, levers, covering radii) is packed once
    per robot and set of these inputs and shared, read-only, by every environment built with them;
    a spherized URDF is read again when its file changes.

    Raises:
        InvalidInput: bad obstacles, spheres, SRDF or attached objects.
    """

    world: tuple
    _spheres: tuple
    _fitted: tuple
    _cover: tuple

    def __init__(self, robot: Robot, obstacles: Iterable[Obstacle] = (), *, srdf: str | Path | None = None,
                 spheres: SphereModel | str | Path | None = None, floor: float | None = None,
                 attached: Sequence[Obstacle] = (), attach_link: str | None = None,
                 cover_meshes: bool = True, exact_self: bool | None = None, self_padding: float = 1e-3) -> None:
        if not isinstance(robot, Robot):
            raise InvalidInput(f"robot must be a robointel Robot, got {type(robot).__name__}", value=robot)
        self.robot = robot
        self.cover_meshes = bool(cover_meshes)
        if srdf is None:
            srdf = robot.srdf_path
        #: self-collision decided on the exact geometry wherever the covering spheres of two links overlap
        #: (default: with the robot's own fitted spheres, which lie inside the meshes)
        from_file = spheres is not None and not isinstance(spheres, SphereModel)
        self.exact_self = bool((spheres is None and robot.fitted_spheres) or from_file) if exact_self is None \
            else bool(exact_self)
        if not (np.isfinite(self_padding) and self_padding >= 0):
            raise InvalidInput(f"self_padding must be >= 0 m, got {self_padding}", value=self_padding)
        self.self_padding = float(self_padding)
        #: subtracted from every self-collision radius, twice (set by the planner for its d_min: d_min - self_padding)
        self.self_offset = 0.0
        #: how far the self-collision radii are moved from the spheres as given toward the covering ones
        #: (0-1, one or one per sphere in the packed order)
        self.self_blend: float | np.ndarray = 0.0
        if spheres is None or isinstance(spheres, SphereModel):
            sm = robot.spheres if spheres is None else spheres
            links, centres, radii = list(sm.links), np.asarray(sm.centers, float), np.asarray(sm.radii, float)
        else:
            links, centres, radii = urdf_spheres(robot, spheres)
        if attached:
            link = attach_link or robot.flange_frame
            if attach_link is not None:
                robot.link_joint(attach_link)
            else:  # the flange frame may be an operational frame: attach to its body
                fr = robot.model.frames[robot.frame_id(robot.flange_frame)]
                link = robot.model.frames[fr.parentFrame].name if fr.type != pin.FrameType.BODY else fr.name
            for k, o in enumerate(attached):
                c, r = _obstacle_spheres(o, k)
                links += [link] * len(r)
                centres = np.vstack([centres, c])
                radii = np.append(radii, r)
        self.disabled = disabled_pairs(srdf, robot.link_names) if srdf is not None else set()
        obs = list(obstacles)
        for k, o in enumerate(obs):
            if not isinstance(o, Obstacle):
                raise InvalidInput(f"obstacles[{k}] is a {type(o).__name__}, not a robointel.geometry obstacle",
                                   value=o)
        if floor is not None:
            z = float(as_array(floor, "floor", ()))
            obs.append(Box(center=np.array([0.0, 0.0, z - 0.5]), size=np.array([20.0, 20.0, 1.0]), name="floor"))
        self.obstacles = [o for o in obs if not isinstance(o, PointCloud)]
        self.labels = [o.label(k) for k, o in enumerate(self.obstacles)]
        # the robot side (bound spheres, joint tree, self-collision pairs, levers, covering radii) depends on the
        # robot and these inputs only: packed once and shared by every environment of the robot (read-only)
        key = ("pack", tuple(links), np.asarray(centres, float).tobytes(), np.asarray(radii, float).tobytes(),
               frozenset(self.disabled), self.cover_meshes, self.exact_self)
        pack = robot_cache(robot).get(key)
        if pack is None:
            self.spheres = SphereModel(links, centres, radii).bind(robot)
            self._chain = _chain_arrays(robot)
            self._pack_spheres()
            pack = {k: getattr(self, k) for k in _PACKED}
            robot_cache(robot)[key] = pack
        self.__dict__.update(pack)
        self._spheres, self.model = self._cover, "cover"
        #: how far each obstacle sphere (packed order) is from the given radius toward the covering one
        self.blend: np.ndarray = np.ones(len(self._fitted[2]))
        packed = [o._packed for o in self.obstacles]  # type: ignore[attr-defined]
        self._prims = (np.array([o._code for o in self.obstacles], np.int64),
                       np.array(packed, dtype=np.float64).reshape(-1, GK.NPARAM))
        clouds = [o for o in obs if isinstance(o, PointCloud)]
        self._cloud: tuple = _empty_cloud()
        if clouds:
            self.update_pointcloud(np.vstack([c.points for c in clouds]), radius=max(c.radius for c in clouds))
        self._rebuild()
        self.scratch = K.Scratch(self.world)

    # ------------------------------------------------------------------ packing
    def _pack_spheres(self) -> None:
        sm = self.spheres
        order, groups, gs = culling_groups(sm.joints, sm._in_joint, sm.radii)  # sorted by joint, wide ones split
        self.sphere_links = [sm.links[i] for i in order]
        #: (m,) the sphere model's index of each packed sphere
        self.sphere_order = order
        sj = sm.joints[order].astype(np.int64)
        sp = np.ascontiguousarray(sm._in_joint[order])
        sr = np.ascontiguousarray(sm.radii[order])
        gc = np.array([sp[gs[k]:gs[k + 1]].mean(0) for k in range(len(groups))]).reshape(-1, 3)
        gr = np.array([np.max(np.linalg.norm(sp[gs[k]:gs[k + 1]] - gc[k], axis=1) + sr[gs[k]:gs[k + 1]])
                       for k in range(len(groups))])
        m = len(sj)
        # self-collision pairs: the sphere model's (non-adjacent joints, apart at q = 0) minus SRDF pairs
        inv = np.empty(m, np.int64)
        inv[order] = np.arange(m)
        smask = np.zeros((m, m), np.uint8)
        for i, k in sm.self_pairs:
            if frozenset((sm.links[i], sm.links[k])) in self.disabled:
                continue
            a, b = inv[i], inv[k]
            smask[a, b] = smask[b, a] = 1
        self._spheres = (sj, sp, sr, groups.astype(np.int64), gc, gr, np.array(gs, np.int64))
        smask &= _variable_pairs(self._chain + self._spheres + _world_tail(), self.robot, smask)
        gid = np.repeat(np.arange(len(groups)), np.diff(gs))  # each sphere's group
        gp = {(min(gid[a], gid[b]), max(gid[a], gid[b])) for a, b in zip(*np.nonzero(smask))}
        gpairs = np.array(sorted(gp), np.int64).reshape(-1, 2)
        self.lever = _levers(self.robot, self._chain, sj, sp)
        anc = self.robot._ancestor  # (nj, nq): does config index k move joint j?
        rel = np.array([(anc[groups[a]] ^ anc[groups[b]]) * self.lever for a, b in gpairs]).reshape(-1, self.robot.nq)
        self._self = (gpairs, smask)
        self._rel = (np.ascontiguousarray(rel, dtype=float), sr, gr, _sphere_levers(self.robot, self._chain, sj, sp))
        self._fitted = self._spheres
        self._cover = self._spheres
        if self.cover_meshes:
            grown = cover_meshes(self.robot, sm, primitives=self.exact_self).radii[order]
            ggr = np.array([np.max(np.linalg.norm(sp[gs[k]:gs[k + 1]] - gc[k], axis=1) + grown[gs[k]:gs[k + 1]])
                            for k in range(len(groups))])
            self._cover = (sj, sp, np.ascontiguousarray(grown), groups.astype(np.int64), gc, ggr,
                           np.array(gs, np.int64))
        self._spheres = self._cover
        self.model = "cover"

    def use(self, model: str, *, blend: float | np.ndarray = 0.0) -> None:
        """Select the spheres checked against obstacles.

        Args:
            model: ``"cover"``: grown to cover the collision meshes (conservative); ``"fitted"``:
                the spheres as given (may leave parts of the meshes uncovered), or with ``blend``
                in (0, 1] radii that far from the given ones toward the covering ones.
            blend: see ``model``: one, or one per sphere in the packed order of :attr:`sphere_links`.

        Raises:
            InvalidInput: another name, or a blend outside [0, 1] or of the wrong length.
        """
        if model not in ("cover", "fitted"):
            raise InvalidInput(f"sphere model must be 'cover' or 'fitted', got {model!r}", value=model)
        b, bg = self._blends(blend)
        if model == "cover":
            self._spheres = self._cover
        elif not np.any(b):
            self._spheres = self._fitted
        else:
            f, c = self._fitted, self._cover
            self._spheres = f[:2] + ((1 - b) * f[2] + b * c[2],) + f[3:5] + ((1 - bg) * f[5] + bg * c[5],) + f[6:]
        self.model = model if model == "cover" or not np.any(b) else f"fitted+{float(np.mean(b)):.2f}"
        self.blend = b if model == "fitted" else np.ones_like(b)
        self._rebuild()

    @property
    def world_cover(self) -> tuple:
        """The packed world with the mesh-covering spheres."""
        return self._chain + self._cover + self._prims + self._self + self._cloud + self._rel_offset()

    def self_clearance(self, q: npt.ArrayLike, *, cap: float = 1.0) -> float:
        """Smallest self-collision distance (m) of the spheres' own radii at q (no offset, no obstacles), capped."""
        qq = self.robot.check_q(np.asarray(q, float))
        empty = (np.zeros(0, np.int64), np.zeros((0, GK.NPARAM)))
        W = self._chain + self._spheres + empty + self._self + _empty_cloud() + self._rel
        s = self.scratch
        return float(K.config_clearance(qq, W, s.T, s.C, s.G, s.out, cap))

    def _rel_offset(self) -> tuple:
        """The self-collision entries of the world: radii blended by ``self_blend``, less ``self_offset / 2``."""
        b = self.self_blend
        if self.self_offset == 0.0 and not np.any(b):
            return self._rel
        h, c = 0.5 * self.self_offset, self._cover
        sr, gr = self._rel[1], self._rel[2]
        if np.any(b):
            bs, bg = self._blends(b)
            sr, gr = (1.0 - bs) * sr + bs * c[2], (1.0 - bg) * gr + bg * c[5]
        return (self._rel[0], sr - h, gr - h, self._rel[3])

    def _blends(self, blend: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(sphere blends (m,), group blends (g,)) of a scalar or per-sphere blend; a group takes its largest.

        A group's radius blended by its spheres' largest blend still bounds each of its spheres
        blended by its own (every radius grows with its blend).

        Raises:
            InvalidInput: a blend outside [0, 1] or of the wrong length.
        """
        m = len(self._fitted[2])
        gs = self._fitted[6]
        if np.ndim(blend) == 0:  # one blend for all (the planner's bisection calls this often: no reductions)
            v = float(blend)  # type: ignore[arg-type]
            if not 0.0 <= v <= 1.0:
                raise InvalidInput(f"a blend must be in [0, 1], one or one per sphere ({m}), got {blend}", value=blend)
            b = np.full(m, v)
            b.flags.writeable = False
            return b, np.full(len(gs) - 1, v) if m else np.zeros(0)
        b = np.asarray(blend, float)
        if b.shape != (m,) or not (np.all(b >= 0.0) and np.all(b <= 1.0)):
            raise InvalidInput(f"a blend must be in [0, 1], one or one per sphere ({m}), got {blend}", value=blend)
        bg = np.maximum.reduceat(b, gs[:-1]) if m else np.zeros(0)
        return b, bg

    def link_spheres(self, links: Iterable[str]) -> np.ndarray:
        """Boolean mask (m,) of the spheres on ``links``, in the packed order of :attr:`sphere_links`."""
        names = set(links)
        return np.array([lk in names for lk in self.sphere_links], bool)

    def set_self_blend(self, blend: float | np.ndarray) -> None:
        """Self-collision radii ``blend`` (0-1, one or one per sphere) of the way to the covering ones.

        The planner moves the spheres of links the exact self-collision check found in contact
        toward the covering spheres, as far as its start and goals allow; 0 restores the spheres
        as given.

        Raises:
            InvalidInput: a blend outside [0, 1] or of the wrong length.
        """
        b, _ = self._blends(blend)
        if not np.array_equal(b, np.broadcast_to(self.self_blend, b.shape)):
            self.self_blend = b.copy() if np.any(b) else 0.0
            self._rebuild()

    def self_offset_clearance(self, q: npt.ArrayLike, *, cap: float = 1.0) -> float:
        """Smallest self-collision distance (m) at q as the planner checks it (offset and blend), capped."""
        qq = self.robot.check_q(np.asarray(q, float))
        empty = (np.zeros(0, np.int64), np.zeros((0, GK.NPARAM)))
        W = self._chain + self._spheres + empty + self._self + _empty_cloud() + self._rel_offset()
        s = self.scratch
        return float(K.config_clearance(qq, W, s.T, s.C, s.G, s.out, cap))

    def set_self_offset(self, d_min: float, margin: float = 0.0) -> None:
        """Make one threshold ``d_min`` check obstacles at ``d_min`` and self-collision at :attr:`self_padding`.

        Every self-collision radius is reduced by (d_min - self_padding) / 2 and grown by ``margin``
        (m; the planner grows fitted spheres, which lie inside the meshes, toward them). The planner
        calls this with its ``d_min``; 0 restores the spheres' own radii.
        """
        off = float(d_min) - self.self_padding - 2.0 * float(margin) if d_min or margin else 0.0
        if off != self.self_offset:
            self.self_offset = off
            self._rebuild()

    def _rebuild(self) -> None:
        self.world = self._chain + self._spheres + self._prims + self._self + self._cloud + self._rel_offset()

    def update_pointcloud(self, points: npt.ArrayLike, *, radius: float = 0.0) -> None:
        """Replace the environment's point cloud (m, world frame) by ``points`` (N, 3).

        The points are sorted into a uniform grid (cells >= 2 cm) that the compiled checks query.

        Args:
            points: (N, 3) points, m; N may be 0 to remove the cloud.
            radius: radius of each point, m (>= 0).

        Raises:
            InvalidInput: wrong shape, NaN/inf, or a negative radius.
        """
        P = np.ascontiguousarray(as_array(points, "points", (None, 3)))
        if not radius >= 0:
            raise InvalidInput(f"point radius must be >= 0 m, got {radius}", value=radius)
        if len(P) == 0:
            self._cloud = _empty_cloud()
        else:
            lo, hi = K.cloud_bounds(P)
            ext = np.maximum(hi - lo, 1e-6)
            h = max(CLOUD_CELL, float(np.cbrt(np.prod(ext + CLOUD_CELL) / _MAX_CELLS)))
            dims = (np.floor(ext / h).astype(np.int64) + 1)
            cpts = np.empty_like(P)
            cstart = np.empty(int(np.prod(dims)) + 1, np.int64)
            K.bin_points(P, lo, h, dims, cpts, cstart)
            grid = np.array([lo[0], lo[1], lo[2], h, float(radius), 0.0, 0.0])
            self._cloud = (cpts, cstart, grid, dims)
        if hasattr(self, "world"):
            self._rebuild()

    # ------------------------------------------------------------------ queries
    def clearance(self, q: npt.ArrayLike, *, cap: float = 1.0) -> float:
        """Smallest signed distance (m) at q over obstacles and self-collision pairs, capped at ``cap``."""
        qq = self.robot.check_q(np.asarray(q, float))
        s = self.scratch
        return float(K.config_clearance(qq, self.world, s.T, s.C, s.G, s.out, cap))

    def contact(self, q: npt.ArrayLike, *, cap: float = 1.0) -> Contact:
        """The closest pair at q: distance (m), robot link and obstacle (or other link)."""
        d = self.clearance(q, cap=cap)
        kind, i, j = (int(v) for v in self.scratch.out[:3])
        if kind < 0:
            return Contact(d, "", "", False)
        link = self.sphere_links[i]
        if kind == K.SELF:
            return Contact(d - self.self_offset, link, self.sphere_links[j], True)
        other = "point cloud" if kind == K.CLOUD else self.labels[j]
        return Contact(d, link, other, False)

    def check_free(self, q: npt.ArrayLike, *, d_min: float = 0.0, what: str = "start configuration") -> None:
        """Raise :class:`CollisionAtStart` naming the pair when q is closer than ``d_min``."""
        c = self.contact(q, cap=max(d_min, 0.0) + 1.0)
        if c.distance < (d_min - self.self_offset if c.self_collision else d_min):
            raise CollisionAtStart(c.message(what) + (f" (required clearance {d_min * 1e3:.1f} mm)" if d_min else "")
                                   + "; move it or lower d_min", value=np.asarray(q, float))


def _obstacle_spheres(o: Obstacle, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Spheres covering an attached object given in its link frame."""
    T = np.eye(4)
    if isinstance(o, Sphere):
        T[:3, 3] = o.center
        return primitive_spheres({"type": "sphere", "size": [o.radius], "origin": T})
    if isinstance(o, Box):
        T[:3, :3], T[:3, 3] = o.rotation, o.center
        return primitive_spheres({"type": "box", "size": o.size, "origin": T})
    if isinstance(o, (Cylinder, Capsule)):
        a, b = np.asarray(o.a, dtype=float), np.asarray(o.b, dtype=float)
        u = (b - a) / np.linalg.norm(b - a)
        T[:3, :3] = _frame_z(u)
        T[:3, 3] = (a + b) / 2
        L = float(np.linalg.norm(b - a)) + (2 * o.radius if isinstance(o, Capsule) else 0.0)
        return primitive_spheres({"type": "cylinder", "size": [o.radius, L], "origin": T})
    if isinstance(o, PointCloud):
        return np.asarray(o.points, dtype=float), np.full(len(o.points), max(o.radius, 1e-4))
    raise InvalidInput(f"attached[{k}]: cannot attach a {o.type}", value=o)


def _frame_z(u: np.ndarray) -> np.ndarray:
    x = np.cross(u, [1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.cross(u, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(u, x), u], 1)


def _empty_cloud() -> tuple:
    return (np.zeros((0, 3)), np.zeros(2, np.int64), np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]),
            np.zeros(3, np.int64))


def _world_tail() -> tuple:
    """Empty arrays typed as the world's entries 12-23: a 12-array prefix padded to the full world's numba type.

    The kernels read only what the prefix holds; the full type spares a second compile of them.
    """
    return ((np.zeros(0, np.int64), np.zeros((0, GK.NPARAM)), np.zeros((0, 2), np.int64), np.zeros((0, 0), np.uint8))
            + _empty_cloud() + (np.zeros((0, 0)), np.zeros(0), np.zeros(0), np.zeros((0, 0, 0))))
