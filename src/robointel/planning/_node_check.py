"""Compiled (numba) node check of the tree search: :func:`config_valid`'s verdict, colliding samples refused sooner.

Most samples the search checks collide (95 % of a cage goal tree's), and most of those with the
links at the end of the chain (the gripper in a cage's bars: 55 % of the refusals of cage 12's
goal-side samples). :func:`config_free` therefore looks at the sphere groups from the tool back to
the base, and it tests against ``thresh`` alone (no running minimum, no capped distance), which
the compiler makes cheaper for free samples too; the self-collision pairs compare squared distances
(no root). The pairs tested, and the test of each, are those
of :func:`~robointel.planning._collision_kernels.config_valid` with ``cap = stop = thresh`` (the
packed world ``W`` is described there); only their order differs, so the verdict is the same.
"""
from __future__ import annotations

from numba import njit

from robointel.geometry._kernels import Arr, _one
from robointel.planning._collision_kernels import CLOUD, ENV, FM, SELF, _aabb_dist, _cloud_min, sphere_centres


@njit(cache=True, fastmath=FM)
def config_free(q: Arr, W: tuple, T: Arr, C: Arr, G: Arr, out: Arr, thresh: float) -> bool:  # pragma: no cover
    """True when every checked distance at q is >= thresh: the verdict of ``config_valid``.

    T, C and G are filled as by ``sphere_centres``. ``out`` receives the pair found below
    ``thresh`` (its kind, sphere, obstacle or sphere) as ``config_valid``'s does, though not
    necessarily the same pair when several are.
    """
    sphere_centres(q, W, T, C, G)
    gj = W[8]
    ng = gj.shape[0]
    sr, gr, gs, types, params, cd = W[7], W[10], W[11], W[12], W[13], W[19]
    out[0] = -1
    for kk in range(ng):
        k = ng - 1 - kk  # from the tool back
        if gj[k] == 0:
            continue
        gx, gy, gz, R = G[k, 0], G[k, 1], G[k, 2], gr[k]
        for o in range(types.shape[0]):
            if _one(types[o], params[o], gx, gy, gz)[0] - R >= thresh:
                continue
            for i in range(gs[k], gs[k + 1]):
                if _one(types[o], params[o], C[i, 0], C[i, 1], C[i, 2])[0] - sr[i] < thresh:
                    out[0], out[1], out[2] = ENV, i, o
                    return False
        if cd[0] > 0 and _aabb_dist(gx, gy, gz, W) - R < thresh:
            for i in range(gs[k], gs[k + 1]):
                if _cloud_min(C[i, 0], C[i, 1], C[i, 2], thresh + sr[i], W) - sr[i] < thresh:
                    out[0], out[1], out[2] = CLOUD, i, 0
                    return False
    gpairs, smask, ssr, sgr = W[14], W[15], W[21], W[22]
    for p in range(gpairs.shape[0]):
        a, b = gpairs[p, 0], gpairs[p, 1]
        lim = thresh + sgr[a] + sgr[b]  # squared distances: no root (a distance is never negative)
        if lim <= 0.0:
            continue
        dx, dy, dz = G[a, 0] - G[b, 0], G[a, 1] - G[b, 1], G[a, 2] - G[b, 2]
        if dx * dx + dy * dy + dz * dz >= lim * lim:
            continue
        for i in range(gs[a], gs[a + 1]):
            for j in range(gs[b], gs[b + 1]):
                if smask[i, j] == 0:
                    continue
                lim = thresh + ssr[i] + ssr[j]
                dx, dy, dz = C[i, 0] - C[j, 0], C[i, 1] - C[j, 1], C[i, 2] - C[j, 2]
                if lim > 0.0 and dx * dx + dy * dy + dz * dz < lim * lim:
                    out[0], out[1], out[2] = SELF, i, j
                    return False
    return True

