"""Exact self-collision distances with ``coal`` on the URDF's collision geometry (meshes and primitives).

The pairs are those a user's description asks to keep apart: links on different rigid bodies, not
joined by one URDF joint, and not disabled by the SRDF. Each pair is bounded first by the two
parts' bounding spheres, then by their convex hulls (GJK, a lower bound of the mesh distance),
then by collision queries with security margins; only a pair closer than the threshold is measured
on the meshes (BVH distance, 10-50x the cost of a collision query).

Used where the fitted spheres cannot decide self-collision: at a start or goal the covering
spheres refuse, and on the trajectory samples where the covering spheres of two links overlap.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Any

import coal
import numpy as np
import pinocchio as pin
from numba import njit

from robointel.planning.exact_geometry import bounded_distance, coal_geometry, hull_bound, placed_clear
from robointel.planning.self_tree import SelfTree
from robointel.robot._ik_kernels import chain_placements
from robointel.robot.model import Robot


@dataclass
class _Solid:
    link: str
    frame: int
    placement: np.ndarray  # (4, 4) in the link frame
    geom: Any  # coal geometry (BVH mesh or primitive)
    hull: Any  # coal Convex of a mesh, or the primitive itself
    centre: np.ndarray  # bounding-sphere centre in the link frame
    radius: float
    slab: bool = False  # one slab of a split mesh (:func:`_slabs`)

    def points(self) -> np.ndarray:
        """(k, 3) points whose convex hull contains the solid, in its own frame (a primitive: its bounding box)."""
        if hasattr(self.geom, "vertices"):
            return np.asarray(self.geom.vertices(), float)
        c = self.centre - self.placement[:3, 3] @ self.placement[:3, :3]  # back in the primitive's frame
        r = self.radius
        return c + r * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)


def _solid(robot: Robot, link: str, p: dict) -> _Solid | None:
    got = coal_geometry(link, p)
    if got is None:
        return None
    g, hull, c, r = got
    M = np.asarray(p["origin"], float)
    return _Solid(link, robot.frame_id(link), M, g, hull, M[:3, :3] @ c + M[:3, 3], r)


#: a mesh solid whose bounding sphere is larger than this is split into slabs (m)
SPLIT_RADIUS = 0.1
#: the slabs' length along the solid's longest axis, at most, m
SLAB_LENGTH = 0.12


def _slabs(s: _Solid) -> list[_Solid]:
    """``s`` as slabs along its longest (principal) axis, each with its own triangles, hull and bound.

    Each triangle goes to the slab of its centroid, so the slabs' triangles are the mesh's: the
    smallest slab distance is the mesh distance. A slab near the joint gets a lever of its own,
    far smaller than the whole link's (:meth:`SelfGeometry._levers`), so a pair of links close
    only near a joint is measured far less often. A primitive, a small mesh, or a slab coal
    cannot hull: ``[s]``.
    """
    g = s.geom
    if s.radius <= SPLIT_RADIUS or not hasattr(g, "tri_indices"):
        return [s]
    V = np.asarray(g.vertices(), float)
    tris = [g.tri_indices(i) for i in range(g.num_tris)]
    T = np.array([[t[0], t[1], t[2]] for t in tris], np.int64).reshape(-1, 3)
    c = V.mean(axis=0)
    axis = np.linalg.svd(V - c, full_matrices=False)[2][0]
    x = (V[T].mean(axis=1) - c) @ axis
    m = int(np.ceil((x.max() - x.min()) / SLAB_LENGTH)) if len(x) else 0
    if m < 2:
        return [s]
    lab = np.clip(((x - x.min()) / (x.max() - x.min()) * m).astype(np.int64), 0, m - 1)
    M = s.placement
    out = []
    for k in range(m):
        tk = T[lab == k]
        if len(tk) == 0:
            continue
        used, inv = np.unique(tk, return_inverse=True)
        Vk = V[used]
        sub = coal.BVHModelOBBRSS()
        sub.beginModel(len(tk), len(used))
        sub.addVertices(np.ascontiguousarray(Vk))
        sub.addTriangles(np.ascontiguousarray(inv.reshape(-1, 3), dtype=np.int64))
        sub.endModel()
        try:
            sub.buildConvexHull(True, "Qt")
        except Exception:  # noqa: BLE001 - a flat slab qhull refuses: keep the solid whole
            return [s]
        ck = 0.5 * (Vk.min(axis=0) + Vk.max(axis=0))
        rk = float(np.max(np.linalg.norm(Vk - ck, axis=1)))
        out.append(_Solid(s.link, s.frame, M, sub, sub.convex, M[:3, :3] @ ck + M[:3, 3], rk, True))
    return out


def _adjacent(robot: Robot) -> set[frozenset[str]]:
    """Link pairs joined by one URDF joint."""
    out = set()
    for j in robot._root.iter("joint"):
        pa, ch = j.find("parent"), j.find("child")
        if pa is not None and ch is not None:
            out.add(frozenset((pa.get("link") or "", ch.get("link") or "")))
    return out


class SelfGeometry:
    """The robot's collision geometry and the link pairs checked for self-collision, as ``coal`` objects.

    Args:
        robot: the robot.
        disabled: link pairs never checked (the SRDF's ``disable_collisions``).
    """

    def __init__(self, robot: Robot, disabled: set[frozenset[str]] | frozenset[frozenset[str]]) -> None:
        self.robot = robot
        links = set(robot.link_names)
        self.solids: list[_Solid] = []
        for link, prims in robot.collision_primitives().items():
            if link not in links:
                continue
            for p in prims:
                s = _solid(robot, link, p)
                if s is not None:
                    self.solids += _slabs(s)
        adj = _adjacent(robot)
        joint = {s.link: robot.link_joint(s.link) for s in self.solids}
        pairs = []
        for a in range(len(self.solids)):
            for b in range(a + 1, len(self.solids)):
                la, lb = self.solids[a].link, self.solids[b].link
                key = frozenset((la, lb))
                if la == lb or joint[la] == joint[lb] or key in adj or key in disabled:
                    continue
                pairs.append((a, b))
        self.pairs = np.array(pairs, int).reshape(-1, 2)
        self._frames = sorted({s.frame for s in self.solids})
        self._solid_frame = np.array([self._frames.index(s.frame) for s in self.solids], int)
        self._centres = np.array([s.centre for s in self.solids], float).reshape(-1, 3)
        self._radii = np.array([s.radius for s in self.solids], float)
        # each solid's placement in its joint's frame, for the compiled joint placements
        self._solid_joint = [robot.link_joint(s.link) for s in self.solids]
        self._in_joint = [robot._link_in_joint[s.link] @ s.placement for s in self.solids]
        self._T = np.zeros((robot.model.njoints, 4, 4))
        self._T[0] = np.eye(4)
        # the hulls as a Pinocchio geometry model: placements and GJK distances in C++, one call each
        self._gm = pin.GeometryModel()
        for k, sl in enumerate(self.solids):
            self._gm.addGeometryObject(pin.GeometryObject(f"{sl.link}#{k}", int(self._solid_joint[k]),
                                                          pin.SE3(self._in_joint[k]), sl.hull))
        for a, b in pairs:
            self._gm.addCollisionPair(pin.CollisionPair(int(a), int(b)))
        self._data = robot.model.createData()
        self._gd = pin.GeometryData(self._gm)  # (rebuilt by the tree once its compound hulls are in the model)
        self._req = coal.DistanceRequest()
        solid_lever = self._levers()
        #: (P, n): the distance of pair p changes at most sum_k pair_lever[p, k] |dq_k| (m)
        # a joint that moves both solids of a pair moves them together: only the others change their distance
        moves = robot._ancestor[[robot.link_joint(s.link) for s in self.solids]].reshape(-1, robot.nq)
        pa, pb = self.pairs[:, 0], self.pairs[:, 1]
        rel = moves[pa] ^ moves[pb]
        # a joint below one solid and moving the other changes the distance as much as it would by turning
        # the first the other way round its axis: the smaller of the two solids' levers bounds it
        down = self._down_levers()
        lever = np.where(moves[pa], np.minimum(solid_lever[pa], down[pb]), np.minimum(solid_lever[pb], down[pa]))
        self.pair_lever = (lever * rel).reshape(-1, robot.nq)
        #: the bounding-volume tree a trajectory's check walks (:class:`~robointel.planning.self_tree.SelfTree`)
        self.tree = SelfTree(self)

    def _levers(self) -> np.ndarray:
        """(S, n) bound of the speed of any point of each solid per unit joint speed, m/rad (1: prismatic).

        A revolute joint moves a point at its distance from the joint's axis: for the solid's own
        joint that is the largest distance of its vertices from the axis; for a joint further up, the
        distance of the child joint's origin from the axis plus the solid's reach from that origin
        (a prismatic joint in between adds its longest stroke).
        """
        parent, place, axis, kind, qidx = self.robot.chain
        lo, hi = np.asarray(self.robot.lower, float), np.asarray(self.robot.upper, float)
        lev = np.zeros((len(self.solids), self.robot.nq))
        for i, s in enumerate(self.solids):
            M = self._in_joint[i]
            V = s.points() @ M[:3, :3].T + M[:3, 3]  # in the solid's joint frame
            j = int(self._solid_joint[i])
            if j == 0 or len(V) == 0:
                continue
            reach = float(np.max(np.linalg.norm(V, axis=1)))
            lev[i, qidx[j]] = 1.0 if kind[j] == 1 else float(np.max(np.linalg.norm(np.cross(V, axis[j]), axis=1)))
            while parent[j] > 0:
                if kind[j] == 1:  # the stroke of a prismatic joint moves everything below it
                    reach += max(abs(lo[qidx[j]]), abs(hi[qidx[j]]))
                k, o = int(parent[j]), place[j][:3, 3]
                lev[i, qidx[k]] = 1.0 if kind[k] == 1 else float(np.linalg.norm(np.cross(o, axis[k]))) + reach
                reach += float(np.linalg.norm(o))
                j = k
        return lev

    def _down_levers(self) -> np.ndarray:
        """(S, n) bound of the distance of any point of each solid from the axis of each joint below it, m.

        Turning joint k by dq moves what hangs below it relative to a solid above it exactly as turning
        that solid by -dq round k's axis would: each of its points moves at most |dq| times its distance
        from the axis. For the first joint below the solid's own the axis is fixed in the solid's frame
        (that distance is exact over the solid's vertices); further down, the distance from the first
        joint's origin plus the joint offsets (and prismatic strokes) down the chain bounds it. Entries
        for joints not below the solid, and prismatic ones, are inf.
        """
        parent, place, axis, kind, qidx = self.robot.chain
        lo, hi = np.asarray(self.robot.lower, float), np.asarray(self.robot.upper, float)
        nj = len(parent)
        out = np.full((len(self.solids), self.robot.nq), np.inf)
        for i, s in enumerate(self.solids):
            M = self._in_joint[i]
            V = s.points() @ M[:3, :3].T + M[:3, 3]  # in the solid's joint frame
            ja = int(self._solid_joint[i])
            if len(V) == 0:
                continue
            for k in range(1, nj):
                if kind[k] == 1:
                    continue
                path = [k]  # the joints from just below ja down to k
                while path[-1] > 0 and int(parent[path[-1]]) != ja:
                    path.append(int(parent[path[-1]]))
                if path[-1] <= 0:
                    continue  # k is not below the solid's joint
                path.reverse()
                c1 = path[0]
                o1 = place[c1][:3, 3]
                if len(path) == 1:
                    u = place[c1][:3, :3] @ axis[c1]
                    out[i, qidx[k]] = float(np.max(np.linalg.norm(np.cross(V - o1, u), axis=1)))
                    continue
                reach = float(np.max(np.linalg.norm(V - o1, axis=1)))
                for c in path[1:]:
                    reach += float(np.linalg.norm(place[c][:3, 3]))
                for c in path[:-1]:
                    if kind[c] == 1:
                        reach += max(abs(lo[qidx[c]]), abs(hi[qidx[c]]))
                out[i, qidx[k]] = reach
        return out

    def pair_distances(self, q: np.ndarray, which: np.ndarray, *, thresh: float) -> np.ndarray:
        """Distances (len(which),) of the pairs ``which`` at q: exact below ``thresh``, else lower bounds above it.

        The hulls' distances come from one placement update and one GJK call per pair in C++
        (Pinocchio's geometry model); only a pair whose hulls are within ``thresh`` goes on to
        :func:`~robointel.planning.exact_geometry.bounded_distance` on the meshes.
        """
        pin.updateGeometryPlacements(self.robot.model, self._data, self._gm, self._gd, q)
        return self._measured(which, thresh)

    def _measured(self, which: np.ndarray, thresh: float) -> np.ndarray:
        """:meth:`pair_distances` at the placements in the geometry data."""
        gm, gd = self._gm, self._gd
        out = np.empty(len(which))
        for n, p in enumerate(which):
            d = hull_bound(pin.computeDistance(gm, gd, int(p)).min_distance)
            out[n] = self._refined(int(p), thresh) if d <= thresh else d
        return out

    def _refined(self, p: int, thresh: float) -> float:
        """Solid pair ``p``'s distance at the placements in the geometry data (:func:`bounded_distance`)."""
        i, j = int(self.pairs[p, 0]), int(self.pairs[p, 1])
        si, sj = self.solids[i], self.solids[j]
        gd = self._gd
        return bounded_distance(si.hull, si.geom, _transform(gd.oMg[i]), sj.hull, sj.geom, _transform(gd.oMg[j]),
                                thresh, self._req)

    def link_placements(self, q: np.ndarray) -> np.ndarray:
        """(J, 4, 4) the joints' world placements at q (n,) (Pinocchio's ``oMi``), for :meth:`pair_clear`."""
        robot, q = self.robot, np.asarray(q, float)
        if robot._chain_batch:  # compiled over the joint chain
            T = np.empty((robot.model.njoints, 4, 4))
            T[0] = np.eye(4)
            chain_placements(q, *robot.chain, T)
            return T
        pin.forwardKinematics(robot.model, self._data, q)
        return np.array([M.homogeneous for M in self._data.oMi])

    def pair_clear(self, T: np.ndarray, p: int, margin: float) -> bool:
        """Whether solid pair ``p`` is at least ``margin`` (m) apart at the joint placements T.

        A yes is a proof (:func:`~robointel.planning.exact_geometry.placed_clear`: hulls, then a
        collision query with ``margin`` as its security margin).
        """
        i, j = int(self.pairs[p, 0]), int(self.pairs[p, 1])
        Mi, Mj = T[self._solid_joint[i]] @ self._in_joint[i], T[self._solid_joint[j]] @ self._in_joint[j]
        si, sj = self.solids[i], self.solids[j]
        return placed_clear(si.hull, si.geom, coal.Transform3s(Mi[:3, :3], Mi[:3, 3]), sj.hull, sj.geom,
                            coal.Transform3s(Mj[:3, :3], Mj[:3, 3]), margin)

    @property
    def empty(self) -> bool:
        """True when no pair is checked."""
        return len(self.pairs) == 0

    def clearance(self, q: np.ndarray, *, cap: float = 1.0, thresh: float = 0.0) -> tuple[float, str, str]:
        """Smallest distance (capped at ``cap``) over the self-collision pairs at q.

        Each pair is bounded by :func:`~robointel.planning.exact_geometry.bounded_distance` (hulls,
        then collision queries with margins), measured exactly only where it is below ``thresh``, so
        the result is exact whenever it is below ``thresh`` and a lower bound otherwise.

        Returns:
            (distance m, link, other link); negative: penetration.
        """
        best, la, lb = cap, "", ""
        if self.empty:
            return best, la, lb
        robot = self.robot
        pin.framesForwardKinematics(robot.model, robot.data, q)
        Tl = np.array([robot.data.oMf[f].homogeneous for f in self._frames])
        Tf = Tl[self._solid_frame]
        ctr = np.einsum("pij,pj->pi", Tf[:, :3, :3], self._centres) + Tf[:, :3, 3]
        a, b = self.pairs[:, 0], self.pairs[:, 1]
        bound = np.linalg.norm(ctr[a] - ctr[b], axis=1) - self._radii[a] - self._radii[b]
        order = np.argsort(bound, kind="stable")
        placed: dict[int, Any] = {}
        req = coal.DistanceRequest()

        def place(i: int) -> Any:
            t = placed.get(i)
            if t is None:
                T = Tf[i] @ self.solids[i].placement
                t = placed[i] = coal.Transform3s(T[:3, :3], T[:3, 3])
            return t

        for k in order:
            if bound[k] >= best:
                break
            i, j = int(a[k]), int(b[k])
            si, sj = self.solids[i], self.solids[j]
            d = bounded_distance(si.hull, si.geom, place(i), sj.hull, sj.geom, place(j), min(thresh, best), req)
            if d < best:
                best, la, lb = float(d), si.link, sj.link
        return best, la, lb


def _transform(M: pin.SE3) -> Any:
    """A Pinocchio placement as a coal transform."""
    return coal.Transform3s(M.rotation, M.translation)


@njit(cache=True)
def next_due(Cq: np.ndarray, lever: np.ndarray, which: np.ndarray, k: int, margin: np.ndarray,
             due: np.ndarray) -> None:  # pragma: no cover - compiled
    """Set ``due[p]`` for each pair p of ``which``: the first sample after ``k`` its margin may not hold at.

    Pair p measured ``margin[i]`` (m) above its threshold at sample k stays above it while its
    travel ``lever[p] . (Cq[j] - Cq[k])`` (``Cq`` (K, n): the joints' cumulated travel) is below the
    margin: ``due[p]`` is the first j > k where it may not be (K: none).
    """
    K, n = Cq.shape
    for i in range(which.shape[0]):
        p = which[i]
        t0 = 0.0
        for c in range(n):
            t0 += lever[p, c] * Cq[k, c]
        target = t0 + margin[i]
        lo, hi = k + 1, K  # the first j in [lo, hi) whose travel reaches target; hi if none
        while lo < hi:
            mid = (lo + hi) // 2
            t = 0.0
            for c in range(n):
                t += lever[p, c] * Cq[mid, c]
            if t >= target:
                hi = mid
            else:
                lo = mid + 1
        due[p] = lo


_CACHE: weakref.WeakKeyDictionary[Robot, dict[frozenset, SelfGeometry]] = weakref.WeakKeyDictionary()


def self_geometry(robot: Robot, disabled: set[frozenset[str]] | frozenset[frozenset[str]]) -> SelfGeometry:
    """The :class:`SelfGeometry` of ``robot`` with these disabled pairs (built once per robot and pair set)."""
    per = _CACHE.setdefault(robot, {})
    key = frozenset(disabled)
    sg = per.get(key)
    if sg is None:
        sg = per[key] = SelfGeometry(robot, key)
    return sg
