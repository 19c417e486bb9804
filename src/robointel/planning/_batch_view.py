"""The batch view of a packed world: the self-collision sphere pairs by cluster, the obstacles' boxes, the scratch.

:func:`batch_world` turns the planner's packed world ``W`` (see
:mod:`robointel.planning._collision_kernels`) into the arrays the batched checks of
:mod:`robointel.planning._batch_kernels` walk; the robot side (clusters of each group's spheres and
the sphere pairs between them) is built once per sphere layout and shared by every world using it.
:class:`BatchScratch` holds the per-batch arrays over the lanes.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from robointel.geometry._kernels import CAPSULE, CYLINDER, SPHERE

#: configurations per batch, a compile-time constant: every lane loop has this trip count, so the compiler
#: emits whole vectors with no remainder loop (lanes past the batch's B repeat lane B - 1)
LANES = 16


class BatchScratch:
    """Work arrays of batched checks in one world (placements, centres, lane values), allocated once."""

    def __init__(self, W: tuple, clusters: int = 0) -> None:
        lanes = LANES
        nj, m, g, n = W[0].shape[0], W[5].shape[0], W[8].shape[0], int(W[20].shape[1])
        self.lanes = lanes
        self.Q = np.zeros((max(n, 1), lanes))
        self.TB = np.zeros((nj, 12, lanes))
        self.TB[0, 0], self.TB[0, 5], self.TB[0, 10] = 1.0, 1.0, 1.0  # joint 0: the fixed base
        self.X, self.Y, self.Z = np.empty((m, lanes)), np.empty((m, lanes)), np.empty((m, lanes))
        self.GX, self.GY, self.GZ = np.empty((g, lanes)), np.empty((g, lanes)), np.empty((g, lanes))
        self.L = np.empty((4, lanes))  # lane work rows: sin, 1 - cos, distances, best
        self.GB = np.empty((g, 6))  # each group's box over the lanes: min xyz, max xyz
        self.placed = np.zeros(g, np.int64)  # 1 where the group's sphere centres are computed
        c = max(clusters, 1)
        self.CX, self.CY, self.CZ = np.empty((c, lanes)), np.empty((c, lanes)), np.empty((c, lanes))
        self.CR = np.empty(c)  # cluster radii over the current self-collision radii

    def arrays(self) -> tuple:
        """The tuple the kernels take: (Q, TB, X, Y, Z, GX, GY, GZ, L, GB, placed, CX, CY, CZ, CR)."""
        return (self.Q, self.TB, self.X, self.Y, self.Z, self.GX, self.GY, self.GZ, self.L, self.GB, self.placed,
                self.CX, self.CY, self.CZ, self.CR)


#: most spheres in a cluster (a group's spheres are split into clusters for the self-collision pairs)
CLUSTER = 4


def batch_world(W: tuple) -> tuple:
    """The batch view of ``W``'s geometry.

    (start (p + 1,), i (s,), j (s,), obstacle boxes (k, 6), ca (c2,), cb (c2,), sstart (c2 + 1,),
    cj (c,), cc (c, 3), cdist (m,), mstart (c + 1,), members (m,)): each group's spheres split into
    clusters of at most :data:`CLUSTER` (joint ``cj``, centre ``cc`` in the joint frame, the spheres
    ``members[mstart[c]:mstart[c+1]]`` at ``cdist`` from it; the radius over the world's current
    self-collision radii is computed per batch,
    :func:`~robointel.planning._batch_kernels.place_clusters`, since the planner shifts those radii
    per plan); group pair ``p`` (``W[14][p]``) holds the cluster pairs
    ``start[p]:start[p+1]`` (clusters ``ca``, ``cb``), cluster pair ``t`` the sphere pairs
    ``i[sstart[t]:sstart[t+1]]``, ``j[...]`` (those with ``W[15][i, j] == 1``); each obstacle's
    axis-aligned bounding box (min xyz, max xyz, m).
    """
    rv = _robot_view(W)
    return (*rv[:3], obstacle_boxes(W[12], W[13]), *rv[3:])


#: the robot side of :func:`batch_world`, per sphere layout (a few kept: a plan's worlds share one)
_ROBOT_VIEWS: dict[bytes, tuple] = {}


def _robot_view(W: tuple) -> tuple:
    """:func:`batch_world` without the obstacle boxes: (start, i, j) and the cluster arrays, cached per layout."""
    key = b"|".join(np.ascontiguousarray(W[k]).tobytes() for k in (5, 6, 8, 11, 14, 15))
    got = _ROBOT_VIEWS.get(key)
    if got is None:
        if len(_ROBOT_VIEWS) >= 8:
            _ROBOT_VIEWS.pop(next(iter(_ROBOT_VIEWS)))
        got = _ROBOT_VIEWS[key] = _build_robot_view(W)
    return got


def _build_robot_view(W: tuple) -> tuple:
    gs, sp, gj, gpairs, smask = W[11], W[6], W[8], W[14], W[15]
    cl_of = np.empty(len(sp), np.int64)
    members: list[np.ndarray] = []
    for k in range(len(gj)):
        stack = [np.arange(gs[k], gs[k + 1])]
        while stack:
            idx = stack.pop()
            if len(idx) <= CLUSTER:
                cl_of[idx] = len(members)
                members.append(idx)
                continue
            pts = sp[idx]
            ax = int(np.argmax(pts.max(0) - pts.min(0)))
            order = idx[np.argsort(pts[:, ax], kind="stable")]
            stack += [order[len(order) // 2:], order[:len(order) // 2]]
    cj = np.array([int(W[5][m[0]]) for m in members], np.int64)
    cc = np.array([(sp[m].min(0) + sp[m].max(0)) / 2 for m in members]).reshape(-1, 3)
    cdist = np.zeros(len(sp))
    for m, c in zip(members, cc):
        cdist[m] = np.linalg.norm(sp[m] - c, axis=1)
    mstart = np.concatenate([[0], np.cumsum([len(m) for m in members])]).astype(np.int64)
    midx = np.concatenate(members).astype(np.int64) if members else np.zeros(0, np.int64)
    start, ca, cb, sstart, pi, pj = [0], [], [], [0], [], []
    for a, b in gpairs:
        pairs: dict[tuple[int, int], list[tuple[int, int]]] = {}
        for i in range(gs[a], gs[a + 1]):
            for j in range(gs[b], gs[b + 1]):
                if smask[i, j]:
                    pairs.setdefault((int(cl_of[i]), int(cl_of[j])), []).append((i, j))
        for (x, y), lst in sorted(pairs.items()):
            ca.append(x)
            cb.append(y)
            pi += [i for i, _ in lst]
            pj += [j for _, j in lst]
            sstart.append(len(pi))
        start.append(len(ca))
    i64 = np.int64
    out = (np.array(start, i64), np.array(pi, i64), np.array(pj, i64),
           np.array(ca, i64), np.array(cb, i64), np.array(sstart, i64), cj, np.ascontiguousarray(cc), cdist, mstart,
           midx)
    return out  # (shared by every world of this layout: the kernels only read it)


@njit(cache=True)
def obstacle_boxes(types, params):  # pragma: no cover - compiled
    """Axis-aligned boxes (k, 6) (min xyz, max xyz) containing the primitives (types, params)."""
    k = types.shape[0]
    out = np.empty((k, 6))
    for o in range(k):
        p = params[o]
        t = types[o]
        for r in range(3):
            if t == SPHERE:
                lo, hi = p[r] - p[3], p[r] + p[3]
            elif t == CAPSULE:
                e = p[r] + p[6] * p[3 + r]
                lo, hi = min(p[r], e) - p[7], max(p[r], e) + p[7]
            elif t == CYLINDER:
                ext = p[6] * abs(p[3 + r]) + p[7]
                lo, hi = p[r] - ext, p[r] + ext
            else:
                ext = abs(p[6 + 3 * r]) * p[3] + abs(p[7 + 3 * r]) * p[4] + abs(p[8 + 3 * r]) * p[5]
                lo, hi = p[r] - ext, p[r] + ext
            out[o, r], out[o, 3 + r] = lo, hi
    return out
