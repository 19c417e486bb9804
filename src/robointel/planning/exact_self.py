"""Exact self-collision distances with ``coal`` on the URDF's collision geometry (meshes and primitives).

The pairs are those a user's description asks to keep apart: links on different rigid bodies, not
joined by one URDF joint, and not disabled by the SRDF. Each pair is bounded first by the two
parts' bounding spheres, then by their convex hulls (GJK, a lower bound of the mesh distance);
only a pair whose hulls are closer than the threshold is measured on the meshes (BVH).

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

from robointel.planning.exact_geometry import coal_geometry, contact_distance
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


def _solid(robot: Robot, link: str, p: dict) -> _Solid | None:
    got = coal_geometry(link, p)
    if got is None:
        return None
    g, hull, c, r = got
    M = np.asarray(p["origin"], float)
    return _Solid(link, robot.frame_id(link), M, g, hull, M[:3, :3] @ c + M[:3, 3], r)


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
                    self.solids.append(s)
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
        solid_lever = self._levers()
        #: (P, n): the distance of pair p changes at most sum_k pair_lever[p, k] |dq_k| (m)
        # a joint that moves both solids of a pair moves them together: only the others change their distance
        moves = robot._ancestor[[robot.link_joint(s.link) for s in self.solids]].reshape(-1, robot.nq)
        pa, pb = self.pairs[:, 0], self.pairs[:, 1]
        rel = moves[pa] ^ moves[pb]
        self.pair_lever = ((solid_lever[pa] + solid_lever[pb]) * rel).reshape(-1, robot.nq)

    def _levers(self) -> np.ndarray:
        """(S, n) bound of the speed of any point of each solid per unit joint speed, m/rad (1: prismatic)."""
        m = self.robot.model
        kind = self.robot.chain[3]
        lev = np.zeros((len(self.solids), self.robot.nq))
        for i, s in enumerate(self.solids):
            f = m.frames[s.frame]
            j = int(f.parentJoint)
            reach = float(np.linalg.norm(f.placement.act(s.centre))) + s.radius
            while j > 0:
                k = int(m.joints[j].idx_q)
                lev[i, k] = 1.0 if kind[j] == 1 else reach
                reach += float(np.linalg.norm(m.jointPlacements[j].translation))
                j = int(m.parents[j])
        return lev

    def pair_distances(self, q: np.ndarray, which: np.ndarray, *, thresh: float) -> np.ndarray:
        """Distances (len(which),) of the pairs ``which`` at q: exact below ``thresh``, else lower bounds above it."""
        chain_placements(q, *self.robot.chain, self._T)  # compiled joint placements (no Pinocchio call)
        req = coal.DistanceRequest()
        placed: dict[int, Any] = {}
        out = np.empty(len(which))
        for n, p in enumerate(which):
            i, j = int(self.pairs[p, 0]), int(self.pairs[p, 1])
            for k in (i, j):
                if k not in placed:
                    T = self._T[self._solid_joint[k]] @ self._in_joint[k]
                    placed[k] = coal.Transform3s(T[:3, :3], T[:3, 3])
            si, sj = self.solids[i], self.solids[j]
            d = coal.distance(si.hull, placed[i], sj.hull, placed[j], req, coal.DistanceResult())
            if d <= thresh:
                d = contact_distance(si.geom, placed[i], sj.geom, placed[j], req)
            out[n] = d
        return out

    @property
    def empty(self) -> bool:
        """True when no pair is checked."""
        return len(self.pairs) == 0

    def clearance(self, q: np.ndarray, *, cap: float = 1.0, thresh: float = 0.0) -> tuple[float, str, str]:
        """Smallest distance (capped at ``cap``) over the self-collision pairs at q.

        Hull distances at or above ``thresh`` are taken as they are (lower bounds); below it the
        exact distance replaces them, so the result is exact whenever it is below ``thresh``.

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
            Ti, Tj = place(i), place(j)
            d = coal.distance(si.hull, Ti, sj.hull, Tj, req, coal.DistanceResult())
            if d <= thresh and d < best:  # (<=: a hull touching at thresh 0 still needs the mesh's sign)
                d = contact_distance(si.geom, Ti, sj.geom, Tj, req)
            if d < best:
                best, la, lb = float(d), si.link, sj.link
        return best, la, lb


_CACHE: weakref.WeakKeyDictionary[Robot, dict[frozenset, SelfGeometry]] = weakref.WeakKeyDictionary()


def self_geometry(robot: Robot, disabled: set[frozenset[str]] | frozenset[frozenset[str]]) -> SelfGeometry:
    """The :class:`SelfGeometry` of ``robot`` with these disabled pairs (built once per robot and pair set)."""
    per = _CACHE.setdefault(robot, {})
    key = frozenset(disabled)
    sg = per.get(key)
    if sg is None:
        sg = per[key] = SelfGeometry(robot, key)
    return sg
