"""Compiled (numba) inner loops of the robot core.

Pinocchio computes the joint placements and the joint Jacobians; these kernels only combine them
for many points at once (point positions and point Jacobians) and evaluate the closed-form
LR Mate IK, where per-call Python overhead would dominate.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from robointel.robot._ik_kernels import chain_placements

#: any numpy array (the compiled kernels take contiguous float64/int64/bool arrays)
Arr = NDArray[Any]


@njit(cache=True, fastmath=False)
def points_jacobians(T: Arr, Jw: Arr, joints: Arr, pts: Arr, anc: Arr,  # pragma: no cover - compiled
                     P: Arr, J: Arr) -> None:
    """P[i] = R_j pts[i] + t_j ; J[i] = [v_k + w_k x P[i]; w_k] over ancestor columns k.

    T: (nj, 4, 4) joint placements; Jw: (6, n) joint Jacobians in the WORLD frame
    (spatial velocity at the world origin); anc: (nj, n) ancestry mask. Writes P (m, 3) and
    J (m, 6, n).
    """
    m = joints.shape[0]
    n = Jw.shape[1]
    for i in range(m):
        j = joints[i]
        for r in range(3):
            P[i, r] = T[j, r, 0] * pts[i, 0] + T[j, r, 1] * pts[i, 1] + T[j, r, 2] * pts[i, 2] + T[j, r, 3]
        px, py, pz = P[i, 0], P[i, 1], P[i, 2]
        for k in range(n):
            if anc[j, k]:
                wx, wy, wz = Jw[3, k], Jw[4, k], Jw[5, k]
                J[i, 0, k] = Jw[0, k] + wy * pz - wz * py
                J[i, 1, k] = Jw[1, k] + wz * px - wx * pz
                J[i, 2, k] = Jw[2, k] + wx * py - wy * px
                J[i, 3, k] = wx
                J[i, 4, k] = wy
                J[i, 5, k] = wz
            else:
                for r in range(6):
                    J[i, r, k] = 0.0


@njit(cache=True)
def _wrap(a: float) -> float:  # pragma: no cover - compiled
    return (a + np.pi) % (2.0 * np.pi) - np.pi


@njit(cache=True)
def lrmate_ik(T6: Arr, d1: float, a1: float, a2: float, a3: float, d4: float,  # pragma: no cover - compiled
              d6: float, lower: Arr, upper: Arr, tol: float) -> Arr:
    """Closed-form IK of the z, y, -y | -x, -y, -x arm with spherical wrist.

    T6: (4, 4) pose of the last link frame. Returns (k, 6) solutions (principal angles, and for
    joints whose principal angle is outside limits, the 2*pi turn inside them) within limits.
    """
    out = np.empty((8, 6))
    k = 0
    L3 = np.hypot(d4, a3)
    phi = np.arctan2(a3, d4)
    wx_ = T6[0, 3] - d6 * T6[0, 0]
    wy_ = T6[1, 3] - d6 * T6[1, 0]
    wz_ = T6[2, 3] - d6 * T6[2, 0]
    base = np.arctan2(wy_, wx_)
    r = np.hypot(wx_, wy_)
    z = wz_ - d1
    for sh in range(2):
        q1 = base if sh == 0 else base + np.pi
        x = r - a1 if sh == 0 else -r - a1
        s = (x * x + z * z - a2 * a2 - L3 * L3) / (2.0 * a2 * L3)
        if abs(s) > 1.0 + 1e-12:
            continue
        s = min(1.0, max(-1.0, s))
        for el in range(2):
            t = np.arcsin(s) if el == 0 else np.pi - np.arcsin(s)
            q3 = t - phi
            c3, s3 = np.cos(q3), np.sin(q3)
            wx = d4 * c3 - a3 * s3
            wz = a2 + d4 * s3 + a3 * c3
            q2 = np.arctan2(x, z) - np.arctan2(wx, wz)
            # R03 = Rz(q1) Ry(q2 - q3); W = R03^T R
            c1, s1 = np.cos(q1), np.sin(q1)
            cb_, sb_ = np.cos(q2 - q3), np.sin(q2 - q3)
            R03 = np.empty((3, 3))
            R03[0, 0] = c1 * cb_
            R03[0, 1] = -s1
            R03[0, 2] = c1 * sb_
            R03[1, 0] = s1 * cb_
            R03[1, 1] = c1
            R03[1, 2] = s1 * sb_
            R03[2, 0] = -sb_
            R03[2, 1] = 0.0
            R03[2, 2] = cb_
            W = np.empty((3, 3))
            for a in range(3):
                for b in range(3):
                    W[a, b] = R03[0, a] * T6[0, b] + R03[1, a] * T6[1, b] + R03[2, a] * T6[2, b]
            cb = W[0, 0]
            sb = np.hypot(W[1, 0], W[2, 0])
            if sb < 1e-10:
                # wrist singular: J4 = 0, J6 takes the whole rotation about x
                if cb > 0:
                    c = np.arctan2(W[2, 1], W[1, 1])
                    cand = (q1, q2, q3, 0.0, 0.0, -c)
                else:
                    c = np.arctan2(-W[2, 1], W[1, 1])
                    cand = (q1, q2, q3, 0.0, -np.pi, -c)
                nw = 1
            else:
                nw = 2
            for w in range(nw):
                if nw == 2:
                    sg = 1.0 if w == 0 else -1.0
                    b = np.arctan2(sg * sb, cb)
                    a = np.arctan2(sg * W[1, 0], -sg * W[2, 0])
                    c = np.arctan2(sg * W[0, 1], sg * W[0, 2])
                    cand = (q1, q2, q3, -a, -b, -c)
                ok = True
                for j in range(6):
                    v = _wrap(cand[j])
                    if v < lower[j] - tol or v > upper[j] + tol:
                        if v + 2 * np.pi <= upper[j] + tol:
                            v = v + 2 * np.pi
                        elif v - 2 * np.pi >= lower[j] - tol:
                            v = v - 2 * np.pi
                        else:
                            ok = False
                            break
                    out[k, j] = min(max(v, lower[j]), upper[j])
                if ok:
                    k += 1
    return out[:k]


@njit(cache=True)
def points_jacobians_batch(T: Arr, Jw: Arr, joints: Arr, pts: Arr,  # pragma: no cover - compiled
                           anc: Arr, P: Arr, J: Arr) -> None:
    """:func:`points_jacobians` for a batch: T (B, nj, 4, 4), Jw (B, 6, n) -> P (B, m, 3), J (B, m, 6, n)."""
    for b in range(T.shape[0]):
        points_jacobians(T[b], Jw[b], joints, pts, anc, P[b], J[b])


@njit(cache=True)
def chain_jacobians_batch(Q: Arr, parent: Arr, place: Arr, axis: Arr, kind: Arr, qidx: Arr,  # pragma: no cover
                          T: Arr, Jw: Arr) -> None:
    """Every joint's placement T (B, nj, 4, 4) and the joint Jacobians Jw (B, 6, n) at each Q[b].

    Jw is Pinocchio's ``computeJointJacobians`` (WORLD frame: the spatial velocity at the world
    origin): a revolute joint with world axis a through o contributes [o x a; a] to its column, a
    prismatic one [a; 0]. The chain arrays are :func:`~robointel.robot.chain.chain_arrays`' (each
    joint its own configuration index); T[b, 0] is set to the identity.
    """
    nj = parent.shape[0]
    for b in range(Q.shape[0]):
        Tb = T[b]
        for r in range(4):
            for c in range(4):
                Tb[0, r, c] = 1.0 if r == c else 0.0
        chain_placements(Q[b], parent, place, axis, kind, qidx, Tb)
        for k in range(Jw.shape[2]):
            for r in range(6):
                Jw[b, r, k] = 0.0
        for j in range(1, nj):
            k = qidx[j]
            ax, ay, az = axis[j, 0], axis[j, 1], axis[j, 2]
            a0 = Tb[j, 0, 0] * ax + Tb[j, 0, 1] * ay + Tb[j, 0, 2] * az
            a1 = Tb[j, 1, 0] * ax + Tb[j, 1, 1] * ay + Tb[j, 1, 2] * az
            a2 = Tb[j, 2, 0] * ax + Tb[j, 2, 1] * ay + Tb[j, 2, 2] * az
            if kind[j] == 0:
                o0, o1, o2 = Tb[j, 0, 3], Tb[j, 1, 3], Tb[j, 2, 3]
                Jw[b, 0, k] = o1 * a2 - o2 * a1
                Jw[b, 1, k] = o2 * a0 - o0 * a2
                Jw[b, 2, k] = o0 * a1 - o1 * a0
                Jw[b, 3, k], Jw[b, 4, k], Jw[b, 5, k] = a0, a1, a2
            else:
                Jw[b, 0, k], Jw[b, 1, k], Jw[b, 2, k] = a0, a1, a2
