"""Compiled (numba) signed-distance kernels for the primitive obstacles.

Every primitive is packed into one row of a parameter array so that one compiled call evaluates
all (sphere, obstacle) pairs of a configuration, whatever the mix of shape types:

========  ====  =============================================================================
type      code  params row (float64, length :data:`NPARAM`)
========  ====  =============================================================================
sphere    0     centre (0:3), radius (3)
capsule   1     a (0:3), unit axis u (3:6), length L (6), radius (7), unit e0 perp. to u (8:11)
cylinder  2     mid-point m (0:3), unit axis u (3:6), half length h (6), radius (7), e0 (8:11)
box       3     centre (0:3), half extents (3:6), rotation R row-major (6:15)
========  ====  =============================================================================

``e0`` is a fixed unit vector perpendicular to the axis, the normal chosen for points exactly on
the axis (where every radial direction is equally valid).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

#: any numpy array (the compiled kernels take contiguous float64/int64/bool arrays)
Arr = NDArray[Any]

SPHERE, CAPSULE, CYLINDER, BOX = 0, 1, 2, 3
NPARAM = 16
_EPS = 1e-12


@njit(cache=True, inline="always")
def _one(t: int, p: Arr, x: float, y: float,
         z: float) -> tuple[float, float, float, float, float, float, float]:
    """Signed distance of point (x, y, z) to primitive (t, p): (d, closest xyz, normal xyz)."""
    if t == SPHERE:
        vx, vy, vz = x - p[0], y - p[1], z - p[2]
        L = math.sqrt(vx * vx + vy * vy + vz * vz)
        if L > _EPS:
            nx, ny, nz = vx / L, vy / L, vz / L
        else:
            nx, ny, nz = 0.0, 0.0, 1.0
        r = p[3]
        return L - r, p[0] + r * nx, p[1] + r * ny, p[2] + r * nz, nx, ny, nz
    if t == CAPSULE:
        ux, uy, uz, L, r = p[3], p[4], p[5], p[6], p[7]
        vx, vy, vz = x - p[0], y - p[1], z - p[2]
        s = vx * ux + vy * uy + vz * uz
        if s < 0.0:
            s = 0.0
        elif s > L:
            s = L
        fx, fy, fz = p[0] + s * ux, p[1] + s * uy, p[2] + s * uz
        wx, wy, wz = x - fx, y - fy, z - fz
        rho = math.sqrt(wx * wx + wy * wy + wz * wz)
        if rho > _EPS:
            nx, ny, nz = wx / rho, wy / rho, wz / rho
        else:
            nx, ny, nz = p[8], p[9], p[10]
        return rho - r, fx + r * nx, fy + r * ny, fz + r * nz, nx, ny, nz
    if t == CYLINDER:
        ux, uy, uz, h, r = p[3], p[4], p[5], p[6], p[7]
        vx, vy, vz = x - p[0], y - p[1], z - p[2]
        a = vx * ux + vy * uy + vz * uz  # axial coordinate from the mid-point
        wx, wy, wz = vx - a * ux, vy - a * uy, vz - a * uz  # radial vector
        rho = math.sqrt(wx * wx + wy * wy + wz * wz)
        if rho > _EPS:
            ex, ey, ez = wx / rho, wy / rho, wz / rho
        else:
            ex, ey, ez = p[8], p[9], p[10]
        sg = 1.0 if a >= 0.0 else -1.0
        dx = abs(a) - h
        dr = rho - r
        # cap-plane centre on the point's side
        kx, ky, kz = p[0] + sg * h * ux, p[1] + sg * h * uy, p[2] + sg * h * uz
        if dx > 0.0 and dr > 0.0:  # nearest feature: the rim circle
            d = math.sqrt(dx * dx + dr * dr)
            nx = (dx * sg * ux + dr * ex) / d
            ny = (dx * sg * uy + dr * ey) / d
            nz = (dx * sg * uz + dr * ez) / d
            return d, kx + r * ex, ky + r * ey, kz + r * ez, nx, ny, nz
        if dx > 0.0 or (dr <= 0.0 and dx >= dr):  # cap (outside above it, or inside nearer to it)
            return dx, kx + wx, ky + wy, kz + wz, sg * ux, sg * uy, sg * uz
        # side (outside beside it, or inside nearer to it)
        return (dr, p[0] + a * ux + r * ex, p[1] + a * uy + r * ey, p[2] + a * uz + r * ez,
                ex, ey, ez)
    # BOX
    vx, vy, vz = x - p[0], y - p[1], z - p[2]
    # local coordinates l = R^T v (R row-major in p[6:15])
    l0 = p[6] * vx + p[9] * vy + p[12] * vz
    l1 = p[7] * vx + p[10] * vy + p[13] * vz
    l2 = p[8] * vx + p[11] * vy + p[14] * vz
    h0, h1, h2 = p[3], p[4], p[5]
    q0, q1, q2 = abs(l0) - h0, abs(l1) - h1, abs(l2) - h2
    if q0 > 0.0 or q1 > 0.0 or q2 > 0.0:
        c0 = min(max(l0, -h0), h0)
        c1 = min(max(l1, -h1), h1)
        c2 = min(max(l2, -h2), h2)
        g0, g1, g2 = l0 - c0, l1 - c1, l2 - c2
        d = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
        n0, n1, n2 = g0 / d, g1 / d, g2 / d
    else:
        c0, c1, c2 = l0, l1, l2
        n0, n1, n2 = 0.0, 0.0, 0.0
        if q0 >= q1 and q0 >= q2:
            d = q0
            n0 = 1.0 if l0 >= 0.0 else -1.0
            c0 = n0 * h0
        elif q1 >= q2:
            d = q1
            n1 = 1.0 if l1 >= 0.0 else -1.0
            c1 = n1 * h1
        else:
            d = q2
            n2 = 1.0 if l2 >= 0.0 else -1.0
            c2 = n2 * h2
    cx = p[0] + p[6] * c0 + p[7] * c1 + p[8] * c2
    cy = p[1] + p[9] * c0 + p[10] * c1 + p[11] * c2
    cz = p[2] + p[12] * c0 + p[13] * c1 + p[14] * c2
    nx = p[6] * n0 + p[7] * n1 + p[8] * n2
    ny = p[9] * n0 + p[10] * n1 + p[11] * n2
    nz = p[12] * n0 + p[13] * n1 + p[14] * n2
    return d, cx, cy, cz, nx, ny, nz


@njit(cache=True)
def point_distances(t: int, p: Arr, P: Arr) -> tuple[Arr, Arr, Arr]:
    """Signed distances (m,), closest points (m, 3), normals (m, 3) of points P (m, 3)."""
    m = P.shape[0]
    d = np.empty(m)
    C = np.empty((m, 3))
    N = np.empty((m, 3))
    for i in range(m):
        d[i], C[i, 0], C[i, 1], C[i, 2], N[i, 0], N[i, 1], N[i, 2] = _one(t, p, P[i, 0], P[i, 1], P[i, 2])
    return d, C, N


@njit(cache=True)
def sphere_pairs(C: Arr, J: Arr, radii: Arr, rows: Arr, types: Arr,
                 params: Arr, cols: Arr, D: Arr, N: Arr, RP: Arr,
                 OP: Arr, G: Arr) -> None:
    """Fill the outputs for all (robot sphere rows[ii], primitive j) pairs.

    C (M, 3) sphere centres; J (M, >=3, n) their Jacobians (first 3 rows linear); radii (M,);
    rows (m,) the spheres to use; types (k,), params (k, NPARAM); cols (k,) output column of each
    primitive. Outputs: D (m, K), N, RP, OP (m, K, 3), G (m, K, n) with dd/dq = n^T J.
    """
    n = J.shape[2]
    for ii in range(rows.shape[0]):
        i = rows[ii]
        x, y, z, r = C[i, 0], C[i, 1], C[i, 2], radii[i]
        for j in range(types.shape[0]):
            c = cols[j]
            d, ox, oy, oz, nx, ny, nz = _one(types[j], params[j], x, y, z)
            D[ii, c] = d - r
            N[ii, c, 0], N[ii, c, 1], N[ii, c, 2] = nx, ny, nz
            OP[ii, c, 0], OP[ii, c, 1], OP[ii, c, 2] = ox, oy, oz
            RP[ii, c, 0], RP[ii, c, 1], RP[ii, c, 2] = x - r * nx, y - r * ny, z - r * nz
            for a in range(n):
                G[ii, c, a] = nx * J[i, 0, a] + ny * J[i, 1, a] + nz * J[i, 2, a]


@njit(cache=True, inline="always")
def _rep_into(c: Arr, J: Arr, r: float, nrm: Arr, p: Arr, g: Arr,
              Jr: Arr) -> None:
    n = J.shape[1]
    nx, ny, nz = nrm[0], nrm[1], nrm[2]
    p[0], p[1], p[2] = c[0] - r * nx, c[1] - r * ny, c[2] - r * nz
    for a in range(n):
        wx, wy, wz = J[3, a], J[4, a], J[5, a]
        g[a] = nx * J[0, a] + ny * J[1, a] + nz * J[2, a]
        # p - c = -r n, so -[p - c]x w = r (n x w)
        Jr[0, a] = J[0, a] + r * (ny * wz - nz * wy)
        Jr[1, a] = J[1, a] + r * (nz * wx - nx * wz)
        Jr[2, a] = J[2, a] + r * (nx * wy - ny * wx)


@njit(cache=True)
def rep_terms(c: Arr, J: Arr, r: float,
              nrm: Arr) -> tuple[Arr, Arr, Arr]:
    """Closest robot point p = c - r n, gradient n^T J_v and J_rep = J_v - [p - c]x J_w (4.6).

    c (3,) sphere centre, J (6, n) its Jacobian [v; w], r radius, nrm (3,) unit normal.
    """
    n = J.shape[1]
    p = np.empty(3)
    g = np.empty(n)
    Jr = np.empty((3, n))
    _rep_into(c, J, r, nrm, p, g, Jr)
    return p, g, Jr


@njit(cache=True)
def sphere_pairs_min(C: Arr, radii: Arr, rows: Arr, types: Arr,
                     params: Arr) -> tuple[Any, ...]:
    """Minimum over all (sphere in rows, primitive) pairs.

    (d, i, j, closest (3,), normal (3,)); i (an index into C) = -1 when there is no pair.
    """
    best = np.inf
    bi, bj = -1, -1
    bo = np.zeros(3)
    bn = np.zeros(3)
    for ii in range(rows.shape[0]):
        i = rows[ii]
        x, y, z, r = C[i, 0], C[i, 1], C[i, 2], radii[i]
        for j in range(types.shape[0]):
            d, ox, oy, oz, nx, ny, nz = _one(types[j], params[j], x, y, z)
            d -= r
            if d < best or bi < 0:
                best, bi, bj = d, i, j
                bo[0], bo[1], bo[2] = ox, oy, oz
                bn[0], bn[1], bn[2] = nx, ny, nz
    return best, bi, bj, bo, bn


@njit(cache=True)
def per_obstacle_min(C: Arr, J: Arr, radii: Arr, rows: Arr, types: Arr,
                     params: Arr, cols: Arr, D: Arr, S: Arr, O: Arr,
                     N: Arr, P: Arr, G: Arr, JR: Arr) -> None:
    """For each primitive j (output column cols[j]), the closest robot sphere among ``rows``.

    Distance D, sphere S (index into C), obstacle point O, normal N, robot point P (.., 3), gradient G (.., n) and
    J_rep JR (.., 3, n); J: (M, 6, n) [v; w]. Columns stay untouched when there is no sphere.
    """
    for j in range(types.shape[0]):
        c = cols[j]
        best = np.inf
        bi = -1
        for ii in range(rows.shape[0]):
            i = rows[ii]
            d, ox, oy, oz, nx, ny, nz = _one(types[j], params[j], C[i, 0], C[i, 1], C[i, 2])
            d -= radii[i]
            if d < best or bi < 0:
                best, bi = d, i
                O[c, 0], O[c, 1], O[c, 2] = ox, oy, oz
                N[c, 0], N[c, 1], N[c, 2] = nx, ny, nz
        if bi >= 0:
            D[c], S[c] = best, bi
            _rep_into(C[bi], J[bi], radii[bi], N[c], P[c], G[c], JR[c])
