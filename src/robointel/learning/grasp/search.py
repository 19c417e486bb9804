"""Orientation search (6.21): turn the transferred grasp about its closing axis to a reachable,
collision-free, high-quality pose.

For each angle ``a`` in a fan around the transferred grasp, the cost is
``J(a) = -Q(a) + w_a |a| + P_ik + P_col``: ``Q`` is the isotropy (6.20) of the turned grasp,
``w_a`` keeps it near the taught orientation, ``P_ik`` is a large penalty when the robot core's IK
(closed form for the LR Mate) has no solution within joint limits, ``P_col`` a large penalty when the
gripper (at full opening) intersects the cloud or the table. The best angle wins.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from robointel.errors import IKFailure
from robointel.learning.grasp.quality import GraspQuality, ParallelGripper, grasp_quality
from robointel.learning.grasp.transfer import Grasp

__all__ = ["SearchResult", "orientation_search", "PENALTY"]

PENALTY = 10.0


@dataclass
class SearchResult:
    """Best grasp of the search: ``grasp`` (world frame), joint solution ``q`` (None if none reachable),
    ``quality`` (6.20), ``angle`` (rad), ``cost``, ``feasible`` (IK ok, no collision, quality > 0) and
    per-angle ``table`` rows (angle, quality, ik_ok, collision_free, cost)."""

    grasp: Grasp
    q: np.ndarray | None
    quality: float
    angle: float
    cost: float
    feasible: bool
    table: np.ndarray = field(repr=False, default=None)
    detail: GraspQuality | None = field(repr=False, default=None)


def orientation_search(grasp: Grasp, cloud, robot=None, *, gripper: ParallelGripper = ParallelGripper(),
                       angles=None, weight: float = 0.05, table_z: float | None = None, q_ref=None,
                       base_pose: np.ndarray | None = None, lift: float = 0.10,
                       tree: cKDTree | None = None) -> SearchResult:
    """(6.21) search rotations of ``grasp`` about its closing axis.

    Args:
        grasp: transferred grasp in the world frame. cloud: object points (n, 3), world frame.
        robot: a :class:`robointel.robot.Robot` whose tool is the gripper's grasp frame
            (``Robot.load("lrmate200id7l", tool=gripper.tool_transform())``); None skips IK.
        angles: candidate turns (rad); default -90..90 deg in 10 deg steps.
        weight: cost per radian away from the transferred orientation.
        table_z: table plane height (world) for the gripper-table check.
        q_ref: preferred joint configuration (IK solutions sorted by distance to it).
        base_pose: 4x4 world pose of the robot root (default identity).
        lift: the grasp is only feasible if the pose ``lift`` metres above is reachable too.
    """
    P = np.asarray(cloud, float)
    tree = tree or cKDTree(P)
    angles = np.radians(np.arange(-90, 91, 10)) if angles is None else np.asarray(angles, float)
    Tb_inv = np.linalg.inv(base_pose) if base_pose is not None else np.eye(4)
    rows, best = [], None
    cache: dict = {}
    for a in angles:
        g = grasp.rotated_about_axis(float(a))
        if table_z is not None:  # raise the grasp until the fingertips clear the table
            tips = g.centre[2] + min(((np.array([sx, sy, sz]) * s / 2 + c) @ g.rotation[2])
                                     for c, s in gripper.boxes()[:2] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1))
            deficit = table_z + 0.003 - tips
            if deficit > 0:
                g = Grasp(g.centre + np.array([0, 0, deficit]), g.rotation, g.width, g.name)
        key = tuple(np.round(g.centre, 6))
        if key not in cache:  # turning about the closing axis leaves the contacts unchanged
            cache[key] = grasp_quality(P, g, gripper=gripper, tree=tree)
        gq = cache[key]
        if gq.grasp is not None:
            g = Grasp(gq.grasp.centre, g.rotation, gq.width, g.name)
        col = gripper.collides(g, P, table_z=table_z)
        q, ik_ok = None, True
        if robot is not None:
            try:
                sols = robot.ik(Tb_inv @ g.pose, q_ref=q_ref)
                up = g.pose.copy()
                up[2, 3] += lift
                robot.ik(Tb_inv @ up, q_ref=sols[0])
                q = sols[0]
            except IKFailure:
                ik_ok = False
        cost = -gq.quality + weight * abs(a) + (0 if ik_ok else PENALTY) + (PENALTY if col else 0)
        rows.append((a, gq.quality, ik_ok, not col, cost))
        if best is None or cost < best[0]:
            best = (cost, g, q, gq, a, ik_ok and not col and gq.quality > 0)
    cost, g, q, gq, a, ok = best
    return SearchResult(g, q, float(gq.quality), float(a), float(cost), bool(ok), np.array(rows, float), gq)
