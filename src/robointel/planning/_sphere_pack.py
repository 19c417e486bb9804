"""Robot-side arrays of the planning environment: levers of the spheres and the self-collision pairs worth checking.

Packed once per robot and sphere set by :class:`~robointel.planning.environment.Environment`.
"""
from __future__ import annotations

import weakref
from typing import Any

import numpy as np

from robointel.planning import _collision_kernels as K
from robointel.robot.model import Robot

#: per robot (weakly held): spherized-URDF reads and packed sphere models, keyed by their content
_ROBOT_CACHE: weakref.WeakKeyDictionary[Robot, dict[tuple, Any]] = weakref.WeakKeyDictionary()


def robot_cache(robot: Robot) -> dict[tuple, Any]:
    """The cache of ``robot``'s sphere reads and packed arrays (gone with the robot)."""
    return _ROBOT_CACHE.setdefault(robot, {})


def _variable_pairs(W: tuple, robot: Robot, smask: np.ndarray, samples: int = 500) -> np.ndarray:
    """Mask of the self-collision pairs whose distance changes with the configuration.

    Pairs whose
    distance stays within 0.1 mm over random configurations (a kinematic invariant, such as a
    sphere on a joint axis facing a sphere on the base) can never collide and are not checked.
    """
    m = len(W[5])
    T = np.zeros((W[0].shape[0], 4, 4))
    T[0] = np.eye(4)
    C, G = np.empty((m, 3)), np.empty((W[8].shape[0], 3))
    i, k = np.nonzero(np.triu(smask))
    lo, hi = np.full(len(i), np.inf), np.full(len(i), -np.inf)
    for q in robot.random_configuration(np.random.default_rng(0), samples):
        K.sphere_centres(q, W, T, C, G)
        d = np.linalg.norm(C[i] - C[k], axis=1)
        lo, hi = np.minimum(lo, d), np.maximum(hi, d)
    keep = np.zeros_like(smask)
    var = (hi - lo) > 1e-4
    keep[i[var], k[var]] = keep[k[var], i[var]] = 1
    return keep


def _chain_arrays(robot: Robot) -> tuple:
    """Joint tree of the robot's Pinocchio model for :func:`chain_fk` (see :mod:`robointel.robot.chain`)."""
    return tuple(robot.chain)


def _sphere_levers(robot: Robot, chain: tuple, sj: np.ndarray, sp: np.ndarray) -> np.ndarray:
    """(m, nj, n) bound of sphere i's speed relative to joint J's body per unit speed of joint k, m/rad.

    Non-zero only for the joints k that move sphere i but not joint J (so the relative distance of
    sphere i to any sphere fixed to J's body changes at most by sum_k L[i, J, k] |dq_k|).
    """
    parent, place, _, kind, qidx = chain
    anc = robot._ancestor
    m, nj = len(sj), len(parent)
    lev = np.zeros((m, robot.nq))
    for i in range(m):
        j, reach = int(sj[i]), float(np.linalg.norm(sp[i]))
        while j > 0:
            lev[i, qidx[j]] = 1.0 if kind[j] == 1 else reach
            reach += float(np.linalg.norm(place[j][:3, 3]))
            j = int(parent[j])
    out = lev[:, None, :] * (anc[sj][:, None, :] & ~anc[None, :, :])
    return np.ascontiguousarray(out, dtype=float).reshape(m, nj, robot.nq)


def _levers(robot: Robot, chain: tuple, sj: np.ndarray, sp: np.ndarray) -> np.ndarray:
    """Upper bound (m per rad, or 1 for prismatic) of the speed of any sphere centre per unit joint speed."""
    parent, place, _, kind, qidx = chain
    lever = np.zeros(robot.nq)
    for i in range(len(sj)):
        j, reach = int(sj[i]), float(np.linalg.norm(sp[i]))
        while j > 0:
            k = qidx[j]
            lever[k] = max(lever[k], 1.0 if kind[j] == 1 else reach)
            reach += float(np.linalg.norm(place[j][:3, 3]))
            j = int(parent[j])
    return lever


#: a joint's spheres whose bounding sphere is wider than this (m) are split into several culling groups
SPLIT_RADIUS = 0.25
#: ... into at most one group per this many spheres (a small group's bounding-sphere test saves about what it
#: costs: the UR5's 9-sphere forearm split in two made its plans 5 % slower)
SPLIT_MIN = 8


def culling_groups(joints: np.ndarray, centres: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                                       list[int]]:
    """The packed order of the spheres and their culling groups: (order (m,), group joints (g,), group starts).

    The spheres are sorted by joint; a joint whose spheres' bounding sphere is wider than
    :data:`SPLIT_RADIUS` (the Fetch's torso with its held head, 0.64 m) has them split by k-means on
    their centres into ceil(radius / SPLIT_RADIUS) groups (at most one per :data:`SPLIT_MIN` spheres),
    each a contiguous run. Every check tests a group's bounding sphere before its spheres: one wide group
    reaches every link near it and culls nothing (the Fetch's torso passed the group test against the
    upper arm, elbow and forearm on every edge). The spheres and their verdicts are the same.

    Args:
        joints: (m,) joint of each sphere.
        centres: (m, 3) sphere centres in their joint's frame, m.
        radii: (m,) sphere radii, m.

    Returns:
        The sphere model's index of each packed sphere, the joint of each group (a joint may hold
        several), and the first packed sphere of each group followed by m.
    """
    order0 = np.argsort(joints, kind="stable")
    runs: list[np.ndarray] = []
    gj: list[int] = []
    for j in np.unique(joints):
        idx = order0[joints[order0] == j]
        P = centres[idx]
        c = P.mean(0)
        R = float(np.max(np.linalg.norm(P - c, axis=1) + radii[idx]))
        k = max(1, min(len(idx) // SPLIT_MIN, int(np.ceil(R / SPLIT_RADIUS)))) if R > SPLIT_RADIUS else 1
        parts = [idx]
        if k > 1:
            C = P[np.random.default_rng(0).choice(len(idx), k, replace=False)]
            for _ in range(30):
                lab = np.argmin(((P[:, None] - C[None]) ** 2).sum(-1), 1)
                C = np.array([P[lab == t].mean(0) if np.any(lab == t) else C[t] for t in range(k)])
            parts = [idx[lab == t] for t in range(k) if np.any(lab == t)]
        runs += parts
        gj += [int(j)] * len(parts)
    starts = np.cumsum([0] + [len(r) for r in runs]).tolist()
    return np.concatenate(runs), np.array(gj, np.int64), starts
