"""Compiled (numba) node check of the tree search: :func:`config_valid`'s verdict, colliding samples refused sooner.

Most samples the search checks collide (95 % of a cage goal tree's), and most of those with the
links at the end of the chain (the gripper in a cage's bars: 55 % of the refusals of cage 12's
goal-side samples). :func:`config_free` therefore looks at the sphere groups from the tool back to
the base, and it tests against ``thresh`` alone (no running minimum, no capped distance), which
the compiler makes cheaper for free samples too; the self-collision pairs compare squared distances
(no root), and in a group pair whose bounding spheres overlap, a sphere of the first group is paired
with the second group's spheres only when it reaches that group's bounding sphere (which holds every
one of them): a uniform Fetch sample then tests 17 % of the sphere pairs of every overlapping group
pair. A group's sphere centres are placed only when one of its tests needs them (a sample refused
at the gripper places the gripper's alone), and an obstacle is measured only when the sphere or
group reaches its axis-aligned box. The pairs that can fail, and the test of each, are those
of :func:`~robointel.planning._collision_kernels.config_valid` with ``cap = stop = thresh`` (the
packed world ``W`` is described there); only their order differs, so the verdict is the same.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from robointel.geometry._kernels import Arr, _one
from robointel.planning._collision_kernels import (
    CLOUD,
    ENV,
    FM,
    SELF,
    _aabb_dist,
    _cloud_min,
    chain_fk,
    group_centres,
    place_spheres,
)


@njit(cache=True, fastmath=FM, inline="always")
def _place(k: int, W: tuple, T: Arr, C: Arr, placed: Arr) -> None:  # pragma: no cover - compiled
    """The sphere centres C of group k (as ``sphere_centres`` fills them), unless already placed."""
    if not placed[k]:
        place_spheres(W[11][k], W[11][k + 1], W, T, C)
        placed[k] = True


@njit(cache=True, fastmath=FM, inline="always")
def _box_gap2(B: Arr, o: int, x: float, y: float, z: float) -> float:  # pragma: no cover - compiled
    """Squared distance from (x, y, z) to box o of B (min xyz, max xyz): 0 inside."""
    e0 = max(max(B[o, 0] - x, x - B[o, 3]), 0.0)
    e1 = max(max(B[o, 1] - y, y - B[o, 4]), 0.0)
    e2 = max(max(B[o, 2] - z, z - B[o, 5]), 0.0)
    return e0 * e0 + e1 * e1 + e2 * e2


@njit(cache=True, fastmath=FM)
def config_free(q: Arr, W: tuple, T: Arr, C: Arr, G: Arr, out: Arr, thresh: float,
                obox: Arr) -> bool:  # pragma: no cover
    """True when every checked distance at q is >= thresh: the verdict of ``config_valid``.

    T and G are filled as by ``sphere_centres``, C only for the groups looked into (a sample that
    collides at the tool places few spheres). ``out`` receives the pair found below ``thresh`` (its
    kind, sphere, obstacle or sphere) as ``config_valid``'s does, though not necessarily the same
    pair when several are. ``obox`` (k, 6): the obstacles' axis-aligned boxes
    (:func:`~robointel.planning._batch_view.obstacle_boxes`); a sphere or group farther from an
    obstacle's box than ``thresh`` is not measured against the obstacle itself.
    """
    chain_fk(q, W, T)
    group_centres(W, T, G)
    gj = W[8]
    ng = gj.shape[0]
    placed = np.zeros(ng, np.bool_)
    sr, gr, gs, types, params, cd = W[7], W[10], W[11], W[12], W[13], W[19]
    out[0] = -1
    for kk in range(ng):
        k = ng - 1 - kk  # from the tool back
        if gj[k] == 0:
            continue
        gx, gy, gz, R = G[k, 0], G[k, 1], G[k, 2], gr[k]
        for o in range(types.shape[0]):
            tR = thresh + R
            if (tR > 0.0 and _box_gap2(obox, o, gx, gy, gz) >= tR * tR) or \
                    _one(types[o], params[o], gx, gy, gz)[0] - R >= thresh:
                continue
            _place(k, W, T, C, placed)
            for i in range(gs[k], gs[k + 1]):
                ti = thresh + sr[i]
                if ti > 0.0 and _box_gap2(obox, o, C[i, 0], C[i, 1], C[i, 2]) >= ti * ti:
                    continue
                if _one(types[o], params[o], C[i, 0], C[i, 1], C[i, 2])[0] - sr[i] < thresh:
                    out[0], out[1], out[2] = ENV, i, o
                    return False
        if cd[0] > 0 and _aabb_dist(gx, gy, gz, W) - R < thresh:
            _place(k, W, T, C, placed)
            for i in range(gs[k], gs[k + 1]):
                if _cloud_min(C[i, 0], C[i, 1], C[i, 2], thresh + sr[i], W) - sr[i] < thresh:
                    out[0], out[1], out[2] = CLOUD, i, 0
                    return False
    gpairs, smask, ssr, sgr = W[14], W[15], W[21], W[22]
    for k in range(ng):  # the self-collision pairs: every sphere (most groups take part)
        _place(k, W, T, C, placed)
    for p in range(gpairs.shape[0]):
        a, b = gpairs[p, 0], gpairs[p, 1]
        rb = sgr[b]
        lim = thresh + sgr[a] + rb  # squared distances: no root (a distance is never negative)
        if lim <= 0.0:
            continue
        bx, by, bz = G[b, 0], G[b, 1], G[b, 2]
        dx, dy, dz = G[a, 0] - bx, G[a, 1] - by, G[a, 2] - bz
        if dx * dx + dy * dy + dz * dz >= lim * lim:
            continue
        for i in range(gs[a], gs[a + 1]):
            # sphere i against b's bounding sphere first: it holds every sphere of b, radius included
            xi, yi, zi = C[i, 0], C[i, 1], C[i, 2]
            lim = thresh + ssr[i] + rb
            dx, dy, dz = xi - bx, yi - by, zi - bz
            if lim <= 0.0 or dx * dx + dy * dy + dz * dz >= lim * lim:
                continue
            for j in range(gs[b], gs[b + 1]):
                if smask[i, j] == 0:
                    continue
                lim = thresh + ssr[i] + ssr[j]
                dx, dy, dz = xi - C[j, 0], yi - C[j, 1], zi - C[j, 2]
                if lim > 0.0 and dx * dx + dy * dy + dz * dz < lim * lim:
                    out[0], out[1], out[2] = SELF, i, j
                    return False
    return True

