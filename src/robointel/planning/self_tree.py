"""A bounding-volume tree of the self-collision solids on each joint, and the pairs of its nodes a check visits.

The solids hanging on one joint (a link's slabs, an end effector's many links) form a binary tree
whose inner nodes are the convex hulls of their members. A trajectory's self-collision check starts
from the pairs of the joints' root nodes and measures a node pair by one GJK call on the two hulls
(a lower bound of every solid pair below it); only a node pair within :data:`EXPAND` of the
threshold is replaced by the pairs of the larger node's children, down to the solid pairs, which
are measured exactly below the threshold. Each node pair carries the largest lever of the solid
pairs below it, so a measured node pair proves all of them for as long as its margin lasts.
"""
from __future__ import annotations

from collections import defaultdict
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from robointel.planning.exact_geometry import hull_bound

#: a node pair closer than this above the threshold is replaced by its children's pairs, m
EXPAND = 0.01


def convex_hull(points: np.ndarray) -> Any:
    """The convex hull of ``points`` (k, 3) as a coal geometry."""
    from scipy.spatial import ConvexHull

    tri = ConvexHull(points).simplices
    m = coal.BVHModelOBBRSS()
    m.beginModel(len(tri), len(points))
    m.addVertices(np.ascontiguousarray(points, dtype=float))
    m.addTriangles(np.ascontiguousarray(tri, dtype=np.int64))
    m.endModel()
    m.buildConvexHull(True, "Qt")
    return m.convex


class SelfTree:
    """The node tree of a :class:`~robointel.planning.exact_self.SelfGeometry` and every node pair a check can reach.

    Builds the compound hulls into the geometry's Pinocchio model (one collision pair per inner node
    pair) and rebuilds its geometry data. Attributes: ``roots`` (R,) the root node pairs; per node
    pair ``lever`` (M, n) (m/rad, the largest of its solid pairs'), ``coll`` (M,) its collision pair
    in the model, ``leaf`` (M,) its solid pair (an index into ``sg.pairs``, -1 for an inner pair),
    ``children`` (a list of (c,) arrays of node pairs).

    Args:
        sg: the :class:`~robointel.planning.exact_self.SelfGeometry` (its solids, solid pairs and
            their levers, geometry model and data; typed loosely: that module builds the tree).
    """

    def __init__(self, sg: Any) -> None:
        self.sg = sg
        S, n = len(sg.solids), sg.robot.nq
        self._pid = np.full((S, S), -1, np.int64)
        self._pl = np.zeros((S, S, n))
        for p, (a, b) in enumerate(sg.pairs):
            self._pid[a, b] = self._pid[b, a] = p
            self._pl[a, b] = self._pl[b, a] = sg.pair_lever[p]
        # per solid: its points and centre in its joint's frame
        self._pts = []
        for i, s in enumerate(sg.solids):
            M = sg._in_joint[i]
            self._pts.append(_hull_points(s) @ M[:3, :3].T + M[:3, 3])
        self.members: list[np.ndarray] = []
        self.obj: list[int] = []
        self.radius: list[float] = []
        self.kids: list[tuple[int, int] | None] = []
        by_joint: dict[int, list[int]] = defaultdict(list)
        for i in range(S):
            by_joint[int(sg._solid_joint[i])].append(i)
        node_roots = [self._node(sg, np.array(m, np.int64)) for m in by_joint.values()]
        lever: list[np.ndarray] = []
        coll: list[int] = []
        leaf: list[int] = []
        children: list[np.ndarray] = []
        index: dict[tuple[int, int], int] = {}

        def pair(a: int, b: int) -> int:
            """The node pair (a, b) (and every pair below it) numbered; -1 when no solid pair below is checked."""
            key = (min(a, b), max(a, b))
            got = index.get(key)
            if got is not None:
                return got
            sub = self._pid[np.ix_(self.members[a], self.members[b])]
            if not (sub >= 0).any():
                return -1
            k = index[key] = len(lever)
            lever.append(self._pl[np.ix_(self.members[a], self.members[b])].reshape(-1, n).max(axis=0))
            leaf.append(-1)
            coll.append(-1)
            children.append(np.zeros(0, np.int64))
            ka, kb = self.kids[a], self.kids[b]
            if ka is None and kb is None:  # two solids: the solid pair itself
                leaf[k] = coll[k] = int(sub[0, 0])
                return k
            split_a = kb is None or (ka is not None and self.radius[a] >= self.radius[b])
            parts = [pair(c, b) for c in ka] if split_a and ka is not None else \
                [pair(a, c) for c in kb] if kb is not None else []
            children[k] = np.array([c for c in parts if c >= 0], np.int64)
            coll[k] = len(sg._gm.collisionPairs)
            sg._gm.addCollisionPair(pin.CollisionPair(int(self.obj[a]), int(self.obj[b])))
            return k

        roots = []
        for x in range(len(node_roots)):
            for y in range(x + 1, len(node_roots)):
                r = pair(node_roots[x], node_roots[y])
                if r >= 0:
                    roots.append(r)
        self.roots = np.array(roots, np.int64)
        self.lever = np.array(lever, float).reshape(-1, n)
        self.coll = np.array(coll, np.int64)
        self.leaf = np.array(leaf, np.int64)
        self.children = children
        self._leaf, self._coll = self.leaf.tolist(), self.coll.tolist()  # (plain lists: the check's inner loop)
        sg._gd = pin.GeometryData(sg._gm)

    def _node(self, sg: Any, members: np.ndarray) -> int:
        """A node over ``members`` (solids on one joint) and its subtree; returns its index."""
        k = len(self.members)
        pts = np.vstack([self._pts[i] for i in members])
        c = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
        self.members.append(members)
        self.radius.append(float(np.max(np.linalg.norm(pts - c, axis=1))))
        self.kids.append(None)
        if len(members) == 1:
            self.obj.append(int(members[0]))
            return k
        self.obj.append(sg._gm.ngeoms)
        sg._gm.addGeometryObject(pin.GeometryObject(f"node#{k}", int(sg._solid_joint[members[0]]), pin.SE3.Identity(),
                                                    convex_hull(pts)))
        ctr = np.array([self._pts[i].mean(axis=0) for i in members])
        axis = int(np.argmax(ctr.max(axis=0) - ctr.min(axis=0)))
        order = members[np.argsort(ctr[:, axis], kind="stable")]
        h = len(order) // 2
        self.kids[k] = (self._node(sg, order[:h]), self._node(sg, order[h:]))
        return k

    def distances(self, q: np.ndarray, which: np.ndarray, *, thresh: float) -> np.ndarray:
        """Distances (len(which),) of the node pairs ``which`` at q (m).

        Inner pairs: the hulls' GJK distance, a lower bound of every solid pair below. Solid pairs:
        exact below ``thresh``, else a lower bound above it.
        """
        return self.measure(q, which, thresh=thresh, expand=-np.inf)[0]

    def measure(self, q: np.ndarray, which: np.ndarray, *, thresh: float,
                expand: float) -> tuple[np.ndarray, list[int], list[int]]:
        """:meth:`distances` with two lists of positions in ``which``.

        Returns:
            (distances (len(which),) m, the solid pairs below ``thresh`` (hits), the inner pairs at or
            below ``expand`` m (to be replaced by their children)).
        """
        sg = self.sg
        gm, gd = sg._gm, sg._gd
        pin.updateGeometryPlacements(sg.robot.model, sg._data, gm, gd, q)
        out = np.empty(len(which))
        hits: list[int] = []
        near: list[int] = []
        leaf, coll, dist = self._leaf, self._coll, pin.computeDistance
        for n, it in enumerate(which.tolist()):
            p = leaf[it]
            d = hull_bound(dist(gm, gd, coll[it]).min_distance)
            if p >= 0:
                if d <= thresh:
                    d = sg._refined(p, thresh)
                    if d < thresh:
                        hits.append(n)
            elif d <= expand:
                near.append(n)
            out[n] = d
        return out, hits, near

    def closest_below(self, q: np.ndarray, thresh: float) -> tuple[float, int] | None:
        """The closest solid pair closer than ``thresh`` (m) at q: (distance m, pair index), or None.

        Walks the tree from the root pairs, expanding only the node pairs at or below ``thresh``.
        """
        best: tuple[float, int] | None = None
        front = self.roots
        while len(front):
            d, hits, near = self.measure(q, front, thresh=thresh, expand=thresh)
            for h in hits:
                if best is None or d[h] < best[0]:
                    best = (float(d[h]), int(self.leaf[front[h]]))
            front = np.array([c for w in near for c in self.children[front[w]]], np.int64)
        return best


def _hull_points(s: Any) -> np.ndarray:
    """(k, 3) the vertices of a solid's convex hull (a primitive: its bounding box's corners), in its own frame."""
    from scipy.spatial import ConvexHull

    pts = np.asarray(s.points(), float).reshape(-1, 3)
    if len(pts) <= 8:
        return pts
    try:
        return pts[ConvexHull(pts).vertices]
    except Exception:  # noqa: BLE001 - a flat point set: every point
        return pts


__all__ = ["EXPAND", "SelfTree", "convex_hull"]
