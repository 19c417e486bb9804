"""Spheres that hold a collision part's triangles: a compiled lower bound of its distance to an obstacle.

The exact checks (:mod:`robointel.planning.exact_geometry`) ask coal for a convex hull's distance (GJK) only
where a cheaper bound cannot settle a pair. That bound was the part's one bounding sphere against the
obstacle's axis-aligned box; here each mesh part also carries up to :data:`LEAVES` smaller spheres, one per
cell of a median split of its triangles, each holding every vertex of its cell's triangles (a ball is
convex, so it holds those triangles whole). The smallest of their distances to the obstacle's exact
primitive (:func:`robointel.geometry._kernels._one`), each less its radius, is a lower bound of the mesh's
distance, and so is the bounding sphere's; :func:`part_bounds` takes the larger of the two.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from robointel.geometry._kernels import _one

#: the most spheres per mesh part (median splits of its triangles' centroids, four levels deep)
LEAVES = 16
#: added to every radius, m (rounding of the vertices' distances)
PAD = 1e-9


def triangle_spheres(vertices: np.ndarray, triangles: np.ndarray, leaves: int = LEAVES) -> tuple[np.ndarray,
                                                                                                  np.ndarray]:
    """Spheres that together hold every triangle of a mesh.

    The triangles are split at the median of their centroids along the cell's longest side, cell by
    cell, until there are ``leaves`` cells (or a cell holds one triangle); each cell's sphere is centred
    on the box of its triangles' vertices and reaches the farthest of them.

    Args:
        vertices: (V, 3) the mesh's vertices, m.
        triangles: (T, 3) vertex indices of each triangle.
        leaves: the most spheres.

    Returns:
        (centres (k, 3), radii (k,)) in the mesh's frame, m; k = 0 for a mesh without triangles.
    """
    V = np.asarray(vertices, float).reshape(-1, 3)
    F = np.asarray(triangles, np.int64).reshape(-1, 3)
    if len(F) == 0:
        return np.zeros((0, 3)), np.zeros(0)
    cells = [np.arange(len(F))]
    mid = V[F].mean(axis=1)
    while len(cells) < leaves:
        k = max(range(len(cells)), key=lambda i: len(cells[i]))
        c = cells[k]
        if len(c) < 2:
            break
        ext = mid[c].max(axis=0) - mid[c].min(axis=0)
        order = c[np.argsort(mid[c, int(np.argmax(ext))], kind="stable")]
        cells[k:k + 1] = [order[:len(order) // 2], order[len(order) // 2:]]
    centres, radii = [], []
    for c in cells:
        P = V[np.unique(F[c])]
        m = 0.5 * (P.min(axis=0) + P.max(axis=0))
        centres.append(m)
        radii.append(float(np.linalg.norm(P - m, axis=1).max()) + PAD)
    return np.array(centres), np.array(radii)


def mesh_triangles(mesh: Any) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3), triangles (T, 3)) of a coal BVH mesh (empty arrays for any other geometry)."""
    if not hasattr(mesh, "num_tris"):
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    tris = np.empty((int(mesh.num_tris), 3), np.int64)
    for i in range(len(tris)):
        t = mesh.tri_indices(i)
        tris[i] = t[0], t[1], t[2]
    return np.asarray(mesh.vertices(), float).reshape(-1, 3), tris


@njit(cache=True)
def part_bounds(T: np.ndarray, part_frame: np.ndarray, centres: np.ndarray, radii: np.ndarray,
                sub_centres: np.ndarray, sub_radii: np.ndarray, sub_start: np.ndarray, types: np.ndarray,
                params: np.ndarray, pp: np.ndarray, oo: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """out[n] = a lower bound of the distance from part pp[n] to obstacle oo[n], m (negative: may touch).

    The larger of the bounding sphere's and the smallest cell sphere's distance to the obstacle's
    primitive, each less its radius.

    Args:
        T: (F, 4, 4) the placements of the parts' link frames in the world.
        part_frame: (P,) each part's index into T.
        centres: (P, 3) each part's bounding-sphere centre in its link frame, m.
        radii: (P,) the bounding spheres' radii, m.
        sub_centres: (S, 3) the cell spheres' centres in their link frames, m.
        sub_radii: (S,) their radii, m.
        sub_start: (P + 1,) part p's cell spheres are sub_start[p]:sub_start[p + 1].
        types: (O,) each obstacle's primitive code (:mod:`robointel.geometry._kernels`).
        params: (O, NPARAM) each obstacle's packed parameters.
        pp: (N,) the parts of the pairs.
        oo: (N,) the obstacles of the pairs.
        out: (N,) receives the bounds.
    """
    for n in range(pp.shape[0]):
        p, o = pp[n], oo[n]
        M = T[part_frame[p]]
        c0, c1, c2 = centres[p, 0], centres[p, 1], centres[p, 2]
        x = M[0, 0] * c0 + M[0, 1] * c1 + M[0, 2] * c2 + M[0, 3]
        y = M[1, 0] * c0 + M[1, 1] * c1 + M[1, 2] * c2 + M[1, 3]
        z = M[2, 0] * c0 + M[2, 1] * c1 + M[2, 2] * c2 + M[2, 3]
        b = _one(types[o], params[o], x, y, z)[0] - radii[p]
        s0, s1 = sub_start[p], sub_start[p + 1]
        if s1 > s0:
            m = np.inf
            for s in range(s0, s1):
                c0, c1, c2 = sub_centres[s, 0], sub_centres[s, 1], sub_centres[s, 2]
                x = M[0, 0] * c0 + M[0, 1] * c1 + M[0, 2] * c2 + M[0, 3]
                y = M[1, 0] * c0 + M[1, 1] * c1 + M[1, 2] * c2 + M[1, 3]
                z = M[2, 0] * c0 + M[2, 1] * c1 + M[2, 2] * c2 + M[2, 3]
                d = _one(types[o], params[o], x, y, z)[0] - sub_radii[s]
                if d < m:
                    m = d
            if m > b:
                b = m
        out[n] = b


__all__ = ["LEAVES", "mesh_triangles", "part_bounds", "triangle_spheres"]
