"""Compiled (numba) collision checks of many configurations at once, in structure-of-arrays form.

A batch holds up to :data:`LANES` configurations, one per *lane*. Every quantity of the check is an
array over the lanes: the joint placements ``TB`` (nj, 12, lanes) (the 3x4 top of each 4x4, row
by row), the sphere centres ``X``, ``Y``, ``Z`` (m, lanes) and the group centres ``GX``, ``GY``,
``GZ`` (g, lanes). Each step of the check (a joint's placement, a sphere's centre, a sphere's
distance to one obstacle) is one loop over the lanes with no branch inside, which the compiler
turns into vector instructions; the decisions (is a group near an obstacle in any lane, is any
lane below the threshold) are taken once per loop, for the whole batch.

Before any lane loop, the batch is culled as a whole: each group's centres over the lanes span a
box, and a (group, obstacle) or (group, group) pair whose boxes are farther apart than the pair can
matter is skipped with a few scalar operations; a group's sphere centres are computed only when
one of its pairs is looked into. A batch of nearby configurations (points along an edge, samples
of a trajectory) thus costs the kinematics of its groups plus the pairs near contact.

The packed world ``W`` is the planner's (see :mod:`robointel.planning._collision_kernels`), for any
number of joints (revolute or prismatic) and any number of spheres per link; ``P`` is the batch
view of its geometry (:func:`~robointel.planning._batch_view.batch_world`: the self-collision
sphere pairs as flat lists and the obstacles' bounding boxes). The checks and their verdicts are
those of the scalar kernels:

- :func:`batch_free`: is every checked distance >= ``thresh`` in every lane (``config_valid``'s
  verdict per lane, decided :data:`TOL` below ``thresh``), with an early exit for the batch at the
  first lane found below it;
- :func:`batch_clearance`: each lane's smallest distance over obstacles and self-collision pairs,
  capped (``config_clearance``'s value per lane).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from robointel.geometry._kernels import CAPSULE, CYLINDER, SPHERE
from robointel.planning._batch_view import LANES
from robointel.planning._collision_kernels import FM, _aabb_dist, _cloud_min

#: the batched checks decide "below thresh" at thresh - TOL, m: a configuration whose clearance is exactly thresh
#: (a start or goal the planner lowered thresh to) passes, whatever the order of the floating-point operations
TOL = 1e-9


@njit(cache=True, fastmath=FM)
def batch_fk(B, W, S):  # pragma: no cover - compiled
    """Joint placements ``S[1]`` (nj, 12, lanes) of the configurations ``S[0]`` (n, lanes), lanes 0..B-1."""
    parent, place, axis, kind, qidx = W[0], W[1], W[2], W[3], W[4]
    Qt, TB, L = S[0], S[1], S[8]
    sn, c1 = L[0], L[1]
    for k in range(Qt.shape[0]):  # the lanes past B repeat lane B - 1 (same verdicts, never a stale lane)
        for b in range(B, LANES):
            Qt[k, b] = Qt[k, B - 1]
    for j in range(1, parent.shape[0]):
        P = TB[parent[j]]
        T = TB[j]
        M = place[j]
        qr = Qt[qidx[j]]
        ax, ay, az = axis[j, 0], axis[j, 1], axis[j, 2]
        m00, m01, m02, m03 = M[0, 0], M[0, 1], M[0, 2], M[0, 3]
        m10, m11, m12, m13 = M[1, 0], M[1, 1], M[1, 2], M[1, 3]
        m20, m21, m22, m23 = M[2, 0], M[2, 1], M[2, 2], M[2, 3]
        if kind[j] == 0:
            for b in range(LANES):
                x = qr[b]
                sn[b] = math.sin(x)
                c1[b] = 1.0 - math.cos(x)
            for r in range(3):
                P0, P1, P2, P3 = P[4 * r], P[4 * r + 1], P[4 * r + 2], P[4 * r + 3]
                T0, T1, T2, T3 = T[4 * r], T[4 * r + 1], T[4 * r + 2], T[4 * r + 3]
                for b in range(LANES):
                    p0, p1, p2 = P0[b], P1[b], P2[b]
                    a0 = p0 * m00 + p1 * m10 + p2 * m20
                    a1 = p0 * m01 + p1 * m11 + p2 * m21
                    a2 = p0 * m02 + p1 * m12 + p2 * m22
                    s, c = sn[b], c1[b]
                    R00 = 1.0 - c * (ay * ay + az * az)
                    R11 = 1.0 - c * (ax * ax + az * az)
                    R22 = 1.0 - c * (ax * ax + ay * ay)
                    R01, R10 = -s * az + c * ax * ay, s * az + c * ax * ay
                    R02, R20 = s * ay + c * ax * az, -s * ay + c * ax * az
                    R12, R21 = -s * ax + c * ay * az, s * ax + c * ay * az
                    T0[b] = a0 * R00 + a1 * R10 + a2 * R20
                    T1[b] = a0 * R01 + a1 * R11 + a2 * R21
                    T2[b] = a0 * R02 + a1 * R12 + a2 * R22
                    T3[b] = p0 * m03 + p1 * m13 + p2 * m23 + P3[b]
        else:
            for r in range(3):
                P0, P1, P2, P3 = P[4 * r], P[4 * r + 1], P[4 * r + 2], P[4 * r + 3]
                T0, T1, T2, T3 = T[4 * r], T[4 * r + 1], T[4 * r + 2], T[4 * r + 3]
                for b in range(LANES):
                    p0, p1, p2 = P0[b], P1[b], P2[b]
                    a0 = p0 * m00 + p1 * m10 + p2 * m20
                    a1 = p0 * m01 + p1 * m11 + p2 * m21
                    a2 = p0 * m02 + p1 * m12 + p2 * m22
                    T0[b], T1[b], T2[b] = a0, a1, a2
                    T3[b] = p0 * m03 + p1 * m13 + p2 * m23 + P3[b] + qr[b] * (a0 * ax + a1 * ay + a2 * az)


@njit(cache=True, fastmath=FM, inline="always")
def _place(TB, j, px, py, pz, X, Y, Z, row, B):  # pragma: no cover - compiled
    """X/Y/Z[row, :B] = the point (px, py, pz) of joint j's frame in the world, per lane."""
    T = TB[j]
    xr, yr, zr = X[row], Y[row], Z[row]
    for b in range(LANES):
        xr[b] = T[0, b] * px + T[1, b] * py + T[2, b] * pz + T[3, b]
        yr[b] = T[4, b] * px + T[5, b] * py + T[6, b] * pz + T[7, b]
        zr[b] = T[8, b] * px + T[9, b] * py + T[10, b] * pz + T[11, b]


@njit(cache=True, fastmath=FM)
def batch_groups(B, W, S):  # pragma: no cover - compiled
    """Placements, group centres ``S[5:8]`` (g, lanes) and group boxes ``S[9]`` of lanes 0..B-1; no sphere yet.

    Marks every group's spheres as not computed (``S[10]``, see :func:`ensure_spheres`).
    """
    batch_fk(B, W, S)
    gj, gc = W[8], W[9]
    TB, GX, GY, GZ, GB, placed = S[1], S[5], S[6], S[7], S[9], S[10]
    for k in range(gj.shape[0]):
        _place(TB, gj[k], gc[k, 0], gc[k, 1], gc[k, 2], GX, GY, GZ, k, B)
        x0, y0, z0, x1, y1, z1 = np.inf, np.inf, np.inf, -np.inf, -np.inf, -np.inf
        xr, yr, zr = GX[k], GY[k], GZ[k]
        for b in range(LANES):
            x0, x1 = min(x0, xr[b]), max(x1, xr[b])
            y0, y1 = min(y0, yr[b]), max(y1, yr[b])
            z0, z1 = min(z0, zr[b]), max(z1, zr[b])
        GB[k, 0], GB[k, 1], GB[k, 2], GB[k, 3], GB[k, 4], GB[k, 5] = x0, y0, z0, x1, y1, z1
        placed[k] = 0


@njit(cache=True, fastmath=FM)
def place_clusters(W, P, S):  # pragma: no cover - compiled
    """Cluster centres ``S[11:14]`` (c, lanes) of the batch (after :func:`batch_groups`) and radii ``S[14]``.

    A cluster's radius is the largest of its spheres' distance from its centre plus the sphere's
    current self-collision radius (``W[21]``).
    """
    cj, cc, cdist, mstart, midx = P[7], P[8], P[9], P[10], P[11]
    ssr = W[21]
    TB, CX, CY, CZ, CR = S[1], S[11], S[12], S[13], S[14]
    for c in range(cj.shape[0]):
        _place(TB, cj[c], cc[c, 0], cc[c, 1], cc[c, 2], CX, CY, CZ, c, LANES)
        r = 0.0
        for t in range(mstart[c], mstart[c + 1]):
            i = midx[t]
            r = max(r, cdist[i] + ssr[i])
        CR[c] = r


@njit(cache=True, fastmath=FM, inline="always")
def ensure_spheres(k, B, W, S):  # pragma: no cover - compiled
    """Compute the sphere centres of group k (lanes 0..B-1) unless :func:`batch_groups` has since."""
    placed = S[10]
    if placed[k]:
        return
    sj, sp, gs = W[5], W[6], W[11]
    TB, X, Y, Z = S[1], S[2], S[3], S[4]
    for i in range(gs[k], gs[k + 1]):
        _place(TB, sj[i], sp[i, 0], sp[i, 1], sp[i, 2], X, Y, Z, i, B)
    placed[k] = 1


@njit(cache=True, fastmath=FM)
def batch_centres(B, W, S):  # pragma: no cover - compiled
    """Every sphere centre ``S[2:5]`` (m, lanes) and group centre ``S[5:8]`` (g, lanes) of lanes 0..B-1."""
    batch_groups(B, W, S)
    for k in range(W[8].shape[0]):
        ensure_spheres(k, B, W, S)


@njit(cache=True, fastmath=FM, inline="always")
def box_gap(A, a, C, c):  # pragma: no cover - compiled
    """Distance between the boxes A[a] and C[c] (each min xyz, max xyz): a lower bound of any two points' distance."""
    d2 = 0.0
    for r in range(3):
        e = max(max(C[c, r] - A[a, 3 + r], A[a, r] - C[c, 3 + r]), 0.0)
        d2 += e * e
    return math.sqrt(d2)


@njit(cache=True, fastmath=FM, inline="always")
def _dist(t, p, X, Y, Z, row, B, D):  # pragma: no cover - compiled
    """D[:B] = signed distance of the points (X, Y, Z)[row, :B] to primitive (t, p), branch-free per lane.

    The values of :func:`robointel.geometry._kernels._one` (its first output).
    """
    xr, yr, zr = X[row], Y[row], Z[row]
    if t == SPHERE:
        cx, cy, cz, r = p[0], p[1], p[2], p[3]
        for b in range(LANES):
            vx, vy, vz = xr[b] - cx, yr[b] - cy, zr[b] - cz
            D[b] = math.sqrt(vx * vx + vy * vy + vz * vz) - r
    elif t == CAPSULE:
        ox, oy, oz, ux, uy, uz, L, r = p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7]
        for b in range(LANES):
            vx, vy, vz = xr[b] - ox, yr[b] - oy, zr[b] - oz
            s = min(max(vx * ux + vy * uy + vz * uz, 0.0), L)
            wx, wy, wz = vx - s * ux, vy - s * uy, vz - s * uz
            D[b] = math.sqrt(wx * wx + wy * wy + wz * wz) - r
    elif t == CYLINDER:
        ox, oy, oz, ux, uy, uz, h, r = p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7]
        for b in range(LANES):
            vx, vy, vz = xr[b] - ox, yr[b] - oy, zr[b] - oz
            a = vx * ux + vy * uy + vz * uz
            wx, wy, wz = vx - a * ux, vy - a * uy, vz - a * uz
            dx = abs(a) - h
            dr = math.sqrt(wx * wx + wy * wy + wz * wz) - r
            ex, er = max(dx, 0.0), max(dr, 0.0)
            D[b] = math.sqrt(ex * ex + er * er) + min(max(dx, dr), 0.0)
    else:  # BOX
        cx, cy, cz, h0, h1, h2 = p[0], p[1], p[2], p[3], p[4], p[5]
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = p[6], p[7], p[8], p[9], p[10], p[11], p[12], p[13], p[14]
        for b in range(LANES):
            vx, vy, vz = xr[b] - cx, yr[b] - cy, zr[b] - cz
            q0 = abs(r00 * vx + r10 * vy + r20 * vz) - h0
            q1 = abs(r01 * vx + r11 * vy + r21 * vz) - h1
            q2 = abs(r02 * vx + r12 * vy + r22 * vz) - h2
            e0, e1, e2 = max(q0, 0.0), max(q1, 0.0), max(q2, 0.0)
            D[b] = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2) + min(max(q0, max(q1, q2)), 0.0)


@njit(cache=True, fastmath=FM, inline="always")
def _lane_min(D, B):  # pragma: no cover - compiled (B unused: every lane counts, the padded ones repeat lane B - 1)
    m = np.inf
    for b in range(LANES):
        m = min(m, D[b])
    return m


@njit(cache=True, fastmath=FM, inline="always")
def _first_below(D, B, v):  # pragma: no cover - compiled
    for b in range(LANES):
        if D[b] < v:
            return b
    return -1


@njit(cache=True, fastmath=FM)
def batch_free(B, W, P, S, thresh, out):  # pragma: no cover - compiled
    """A lane (0..B-1) of the batch ``S[0]`` with a checked distance below ``thresh``, or -1 when none.

    The verdict per lane is ``config_valid``'s. The groups are looked at from the tool back (as
    :func:`~robointel.planning._node_check.config_free`), a group against an obstacle only when
    their boxes and then its bounding sphere come below ``thresh`` in some lane, and the check stops
    at the first pair found below ``thresh`` in any lane; ``out`` receives that pair (kind, sphere,
    obstacle or sphere).
    """
    thresh -= TOL  # a lane exactly at thresh passes, whatever the rounding
    batch_groups(B, W, S)
    X, Y, Z, GX, GY, GZ, L, GB = S[2], S[3], S[4], S[5], S[6], S[7], S[8], S[9]
    D = L[2]
    gj, sr, gr, gs, types, params, cd = W[8], W[7], W[10], W[11], W[12], W[13], W[19]
    obox = P[3]
    ng = gj.shape[0]
    out[0] = -1
    for kk in range(ng):
        k = ng - 1 - kk
        if gj[k] == 0:
            continue
        for o in range(types.shape[0]):
            if box_gap(GB, k, obox, o) - gr[k] >= thresh:
                continue
            _dist(types[o], params[o], GX, GY, GZ, k, B, D)
            if _lane_min(D, B) - gr[k] >= thresh:
                continue
            ensure_spheres(k, B, W, S)
            for i in range(gs[k], gs[k + 1]):
                _dist(types[o], params[o], X, Y, Z, i, B, D)
                if _lane_min(D, B) - sr[i] < thresh:
                    out[0], out[1], out[2] = 0, i, o
                    return _first_below(D, B, thresh + sr[i])
        if cd[0] > 0:
            for b in range(LANES):
                if _aabb_dist(GX[k, b], GY[k, b], GZ[k, b], W) - gr[k] >= thresh:
                    continue
                ensure_spheres(k, B, W, S)
                for i in range(gs[k], gs[k + 1]):
                    if _cloud_min(X[i, b], Y[i, b], Z[i, b], thresh + sr[i], W) - sr[i] < thresh:
                        out[0], out[1], out[2] = 2, i, 0
                        return b
    gpairs, ssr, sgr = W[14], W[21], W[22]
    start, pi, pj, ca, cb, sstart, cr = P[0], P[1], P[2], P[4], P[5], P[6], S[14]
    CX, CY, CZ = S[11], S[12], S[13]
    clustered = False
    for p in range(gpairs.shape[0]):
        a, c = gpairs[p, 0], gpairs[p, 1]
        if box_gap(GB, a, GB, c) - sgr[a] - sgr[c] >= thresh:
            continue
        ax, ay, az, cx, cy, cz = GX[a], GY[a], GZ[a], GX[c], GY[c], GZ[c]
        lim = max(thresh + sgr[a] + sgr[c], 0.0)
        for b in range(LANES):
            dx, dy, dz = ax[b] - cx[b], ay[b] - cy[b], az[b] - cz[b]
            D[b] = dx * dx + dy * dy + dz * dz
        if _lane_min(D, B) >= lim * lim:
            continue
        if not clustered:
            place_clusters(W, P, S)
            clustered = True
        ensure_spheres(a, B, W, S)
        ensure_spheres(c, B, W, S)
        for t in range(start[p], start[p + 1]):
            x, y = ca[t], cb[t]
            lim = max(thresh + cr[x] + cr[y], 0.0)
            for b in range(LANES):
                dx, dy, dz = CX[x, b] - CX[y, b], CY[x, b] - CY[y, b], CZ[x, b] - CZ[y, b]
                D[b] = dx * dx + dy * dy + dz * dz
            if _lane_min(D, B) >= lim * lim:
                continue
            for s in range(sstart[t], sstart[t + 1]):
                i, j = pi[s], pj[s]
                xi, yi, zi, xj, yj, zj = X[i], Y[i], Z[i], X[j], Y[j], Z[j]
                lim = thresh + ssr[i] + ssr[j]
                if lim <= 0.0:  # a distance is never negative
                    continue
                for b in range(LANES):
                    dx, dy, dz = xi[b] - xj[b], yi[b] - yj[b], zi[b] - zj[b]
                    D[b] = dx * dx + dy * dy + dz * dz
                if _lane_min(D, B) < lim * lim:
                    out[0], out[1], out[2] = 1, i, j
                    return _first_below(D, B, lim * lim)
    return -1


@njit(cache=True, fastmath=FM)
def batch_clearance(B, W, P, S, cap, best):  # pragma: no cover - compiled
    """Each lane's smallest distance over obstacles and self-collision pairs, capped at ``cap``: ``best[:B]``.

    The value per lane is ``config_clearance``'s (spheres fixed to the base are not checked
    against the obstacles). A group is looked into for an obstacle (a group pair for self-collision)
    only when their boxes, then its bounding sphere, come closer than some lane's current best.
    """
    batch_groups(B, W, S)
    X, Y, Z, GX, GY, GZ, L, GB = S[2], S[3], S[4], S[5], S[6], S[7], S[8], S[9]
    D = L[2]
    gj, sr, gr, gs, types, params, cd = W[8], W[7], W[10], W[11], W[12], W[13], W[19]
    obox = P[3]
    for b in range(LANES):
        best[b] = cap
    worst = cap  # the largest lane best: a pair at or beyond it cannot lower any lane
    for k in range(gj.shape[0]):
        if gj[k] == 0:
            continue
        for o in range(types.shape[0]):
            if box_gap(GB, k, obox, o) - gr[k] >= worst:
                continue
            _dist(types[o], params[o], GX, GY, GZ, k, B, D)
            need = False
            for b in range(LANES):
                need |= D[b] - gr[k] < best[b]
            if not need:
                continue
            ensure_spheres(k, B, W, S)
            for i in range(gs[k], gs[k + 1]):
                _dist(types[o], params[o], X, Y, Z, i, B, D)
                ri = sr[i]
                for b in range(LANES):
                    best[b] = min(best[b], D[b] - ri)
            worst = -np.inf
            for b in range(LANES):
                worst = max(worst, best[b])
        if cd[0] > 0:
            for b in range(LANES):
                if _aabb_dist(GX[k, b], GY[k, b], GZ[k, b], W) - gr[k] >= best[b]:
                    continue
                ensure_spheres(k, B, W, S)
                for i in range(gs[k], gs[k + 1]):
                    d = _cloud_min(X[i, b], Y[i, b], Z[i, b], best[b] + sr[i], W) - sr[i]
                    best[b] = min(best[b], d)
            worst = -np.inf
            for b in range(LANES):
                worst = max(worst, best[b])
    gpairs, ssr, sgr = W[14], W[21], W[22]
    start, pi, pj, ca, cb, sstart, cr = P[0], P[1], P[2], P[4], P[5], P[6], S[14]
    CX, CY, CZ = S[11], S[12], S[13]
    clustered = False
    for p in range(gpairs.shape[0]):
        a, c = gpairs[p, 0], gpairs[p, 1]
        rr = sgr[a] + sgr[c]
        if box_gap(GB, a, GB, c) - rr >= worst:
            continue
        ax, ay, az, cx, cy, cz = GX[a], GY[a], GZ[a], GX[c], GY[c], GZ[c]
        need = False
        for b in range(LANES):
            dx, dy, dz = ax[b] - cx[b], ay[b] - cy[b], az[b] - cz[b]
            need |= math.sqrt(dx * dx + dy * dy + dz * dz) - rr < best[b]
        if not need:
            continue
        if not clustered:
            place_clusters(W, P, S)
            clustered = True
        ensure_spheres(a, B, W, S)
        ensure_spheres(c, B, W, S)
        for t in range(start[p], start[p + 1]):
            x, y = ca[t], cb[t]
            rr = cr[x] + cr[y]
            need = False
            for b in range(LANES):
                dx, dy, dz = CX[x, b] - CX[y, b], CY[x, b] - CY[y, b], CZ[x, b] - CZ[y, b]
                need |= math.sqrt(dx * dx + dy * dy + dz * dz) - rr < best[b]
            if not need:
                continue
            for s in range(sstart[t], sstart[t + 1]):
                i, j = pi[s], pj[s]
                xi, yi, zi, xj, yj, zj = X[i], Y[i], Z[i], X[j], Y[j], Z[j]
                rr = ssr[i] + ssr[j]
                for b in range(LANES):
                    dx, dy, dz = xi[b] - xj[b], yi[b] - yj[b], zi[b] - zj[b]
                    best[b] = min(best[b], math.sqrt(dx * dx + dy * dy + dz * dz) - rr)
        worst = -np.inf
        for b in range(LANES):
            worst = max(worst, best[b])
