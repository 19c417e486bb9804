"""Compiled (numba) numeric IK on the joint-tree arrays of :mod:`robointel.robot.chain`.

Levenberg-Marquardt on the 6-D pose error (position and the rotation's log, world frame), the
damping adapted to the error (Sugihara's rule, raised tenfold after a step that does not lower the
error), every step clipped to the joint limits; a restart from a uniform random configuration
when the error stalls.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

Arr = NDArray[Any]


@njit(cache=True)
def _fk(q: Arr, parent: Arr, place: Arr, axis: Arr, kind: Arr, qidx: Arr, upto: int,  # pragma: no cover
        T: Arr) -> None:
    """Joint placements T[1..upto] in the world (T[0] is the identity)."""
    for j in range(1, upto + 1):
        P = T[parent[j]]
        M = place[j]
        x = q[qidx[j]]
        ax, ay, az = axis[j, 0], axis[j, 1], axis[j, 2]
        A = np.empty((4, 4))
        for r in range(4):
            for c in range(4):
                A[r, c] = P[r, 0] * M[0, c] + P[r, 1] * M[1, c] + P[r, 2] * M[2, c] + P[r, 3] * M[3, c]
        if kind[j] == 0:
            s, c1 = math.sin(x), 1.0 - math.cos(x)
            R = np.empty((3, 3))
            R[0, 0] = 1.0 - c1 * (ay * ay + az * az)
            R[1, 1] = 1.0 - c1 * (ax * ax + az * az)
            R[2, 2] = 1.0 - c1 * (ax * ax + ay * ay)
            R[0, 1], R[1, 0] = -s * az + c1 * ax * ay, s * az + c1 * ax * ay
            R[0, 2], R[2, 0] = s * ay + c1 * ax * az, -s * ay + c1 * ax * az
            R[1, 2], R[2, 1] = -s * ax + c1 * ay * az, s * ax + c1 * ay * az
            for r in range(3):
                for c in range(3):
                    T[j, r, c] = A[r, 0] * R[0, c] + A[r, 1] * R[1, c] + A[r, 2] * R[2, c]
                T[j, r, 3] = A[r, 3]
        else:
            for r in range(3):
                for c in range(3):
                    T[j, r, c] = A[r, c]
                T[j, r, 3] = A[r, 3] + x * (A[r, 0] * ax + A[r, 1] * ay + A[r, 2] * az)
        T[j, 3, 0], T[j, 3, 1], T[j, 3, 2], T[j, 3, 3] = 0.0, 0.0, 0.0, 1.0


@njit(cache=True)
def chain_placements(q: Arr, parent: Arr, place: Arr, axis: Arr, kind: Arr, qidx: Arr,  # pragma: no cover
                     T: Arr) -> None:
    """Every joint's placement T (nj, 4, 4) in the world at q (T[0] must hold the identity)."""
    _fk(q, parent, place, axis, kind, qidx, parent.shape[0] - 1, T)


@njit(cache=True)
def _log3(R: Arr, w: Arr) -> None:  # pragma: no cover - compiled
    """The rotation vector w (3,) of the rotation matrix R (3, 3)."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    c = min(1.0, max(-1.0, 0.5 * (tr - 1.0)))
    th = math.acos(c)
    vx, vy, vz = R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]
    if th < 1e-5:
        w[0], w[1], w[2] = 0.5 * vx, 0.5 * vy, 0.5 * vz
    elif th < math.pi - 1e-3:
        f = th / (2.0 * math.sin(th))
        w[0], w[1], w[2] = f * vx, f * vy, f * vz
    else:  # near pi: the axis from the symmetric part, its sign from the skew part
        k = 0
        if R[1, 1] > R[k, k]:
            k = 1
        if R[2, 2] > R[k, k]:
            k = 2
        a = np.empty(3)
        for i in range(3):
            a[i] = 0.5 * (R[i, k] + R[k, i]) if i != k else R[k, k] - c
        n = math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
        for i in range(3):
            a[i] /= n
        if a[0] * vx + a[1] * vy + a[2] * vz < 0:
            a = -a
        w[0], w[1], w[2] = th * a[0], th * a[1], th * a[2]


@njit(cache=True)
def _error(q: Arr, parent: Arr, place: Arr, axis: Arr, kind: Arr, qidx: Arr, jt: int, tip: Arr, target: Arr,
           T: Arr, F: Arr, e: Arr) -> float:  # pragma: no cover - compiled
    """Tip pose F (4, 4) at q, and the error e (6,) = [p* - p; log(R* R^T)]; returns |e|^2."""
    _fk(q, parent, place, axis, kind, qidx, jt, T)
    for r in range(4):
        for c in range(4):
            F[r, c] = (T[jt, r, 0] * tip[0, c] + T[jt, r, 1] * tip[1, c] + T[jt, r, 2] * tip[2, c]
                       + T[jt, r, 3] * tip[3, c])
    for r in range(3):
        e[r] = target[r, 3] - F[r, 3]
    Re = np.empty((3, 3))
    for r in range(3):
        for c in range(3):
            Re[r, c] = target[r, 0] * F[c, 0] + target[r, 1] * F[c, 1] + target[r, 2] * F[c, 2]
    w = np.empty(3)
    _log3(Re, w)
    e[3], e[4], e[5] = w[0], w[1], w[2]
    s = 0.0
    for r in range(6):
        s += e[r] * e[r]
    return s


@njit(cache=True)
def _jacobian(parent: Arr, axis: Arr, kind: Arr, qidx: Arr, jt: int, T: Arr, F: Arr,  # pragma: no cover
              J: Arr) -> None:
    """World-aligned 6 x n Jacobian of the tip point F[:3, 3] (columns of joints off the tip's branch: 0)."""
    J[:, :] = 0.0
    px, py, pz = F[0, 3], F[1, 3], F[2, 3]
    j = jt
    while j > 0:
        k = qidx[j]
        ax = T[j, 0, 0] * axis[j, 0] + T[j, 0, 1] * axis[j, 1] + T[j, 0, 2] * axis[j, 2]
        ay = T[j, 1, 0] * axis[j, 0] + T[j, 1, 1] * axis[j, 1] + T[j, 1, 2] * axis[j, 2]
        az = T[j, 2, 0] * axis[j, 0] + T[j, 2, 1] * axis[j, 1] + T[j, 2, 2] * axis[j, 2]
        if kind[j] == 0:
            rx, ry, rz = px - T[j, 0, 3], py - T[j, 1, 3], pz - T[j, 2, 3]
            J[0, k] += ay * rz - az * ry
            J[1, k] += az * rx - ax * rz
            J[2, k] += ax * ry - ay * rx
            J[3, k] += ax
            J[4, k] += ay
            J[5, k] += az
        else:
            J[0, k] += ax
            J[1, k] += ay
            J[2, k] += az
        j = parent[j]


@njit(cache=True)
def ik_solve(target: Arr, seeds: Arr, parent: Arr, place: Arr, axis: Arr, kind: Arr, qidx: Arr,  # pragma: no cover
             jt: int, tip: Arr, lower: Arr, upper: Arr, tol: float, max_iter: int, restarts: int,
             seed: int, out: Arr) -> tuple[int, float]:
    """Solve fk(q) = target within [lower, upper].

    The joint tree ``parent, place, axis, kind, qidx`` is :func:`robointel.robot.chain.chain_arrays`'s.

    Args:
        target: (4, 4) pose of the tip in the world.
        seeds: (S, n) first starts; then uniform random starts.
        parent: joint tree, see above.
        place: joint tree.
        axis: joint tree.
        kind: joint tree.
        qidx: joint tree.
        jt: the joint the tip hangs on.
        tip: (4, 4) the tip in that joint's frame.
        lower: (n,) lower limits.
        upper: (n,) upper limits.
        tol: converged when |e|^2 < tol^2 (e: m and rad).
        max_iter: iterations per start.
        restarts: random starts after the seeds.
        seed: seed of the random starts.
        out: (n,) receives the solution (or the best iterate).

    Returns:
        (number of the start that converged, or -1; the best squared error).
    """
    np.random.seed(seed)
    n = lower.shape[0]
    nj = parent.shape[0]
    T = np.zeros((nj, 4, 4))
    for r in range(4):
        T[0, r, r] = 1.0
    F = np.empty((4, 4))
    e = np.empty(6)
    e2 = np.empty(6)
    J = np.empty((6, n))
    q = np.empty(n)
    qn = np.empty(n)
    best = np.inf
    tol2 = tol * tol
    for r in range(seeds.shape[0] + restarts):
        if r < seeds.shape[0]:
            for i in range(n):
                q[i] = min(max(seeds[r, i], lower[i]), upper[i])
        else:
            for i in range(n):
                q[i] = lower[i] + np.random.random() * (upper[i] - lower[i])
        E = _error(q, parent, place, axis, kind, qidx, jt, tip, target, T, F, e)
        lam = 1e-3
        stall = 0
        for _ in range(max_iter):
            if E < tol2:
                break
            _jacobian(parent, axis, kind, qidx, jt, T, F, J)
            A = J @ J.T
            damp = lam * E + 1e-12
            for i in range(6):
                A[i, i] += damp
            dq = J.T @ np.linalg.solve(A, e)
            for i in range(n):
                qn[i] = min(max(q[i] + dq[i], lower[i]), upper[i])
            En = _error(qn, parent, place, axis, kind, qidx, jt, tip, target, T, F, e2)
            if En < E:
                stall = 0 if En < 0.99 * E else stall + 1
                q[:] = qn
                e[:] = e2
                E = En
                lam = max(lam * 0.3, 1e-6)
            else:
                _error(q, parent, place, axis, kind, qidx, jt, tip, target, T, F, e)
                lam *= 10.0
                stall += 1
            if stall > 6 or lam > 1e6:
                break
        if E < best:
            best = E
            out[:] = q
        if E < tol2:
            return r, E
    return -1, best
