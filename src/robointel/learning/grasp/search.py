"""Orientation search (6.21) and the local position refinement before it.

Orientation search (6.21): turn the transferred grasp about its closing axis to a reachable,
collision-free, high-quality pose.

For each angle ``a`` in a fan around the transferred grasp, the cost is
``J(a) = -Q(a) + w_a |a| + P_ik + P_col``: ``Q`` is the isotropy (6.20) of the turned grasp,
``w_a`` keeps it near the taught orientation, ``P_ik`` is a large penalty when the robot core's IK
(closed form for the LR Mate) has no solution within joint limits, ``P_col`` a large penalty when the
gripper (at full opening) intersects the cloud or the table. The best angle wins.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from robointel.errors import IKFailure, InvalidInput
from robointel.learning.grasp.quality import NARROW_GRIPPER, GraspQuality, ParallelGripper, grasp_quality
from robointel.learning.grasp.transfer import Grasp, grasp_from_axis

if TYPE_CHECKING:
    from robointel.robot import Robot

__all__ = ["SearchResult", "orientation_search", "refine_position", "PENALTY", "PRE_GRASP"]

PENALTY = 10.0

#: Distance (m) of the pre-grasp pose back along the approach from the grasp: the trial moves the jaws
#: in from there (:func:`robointel.learning.grasp.grasp_trial`), so the search requires it reachable.
PRE_GRASP = 0.08


#: Default turns of :func:`refine_position` (rad): -30, -15, 0, 15, 30 deg.
REFINE_YAWS: tuple[float, ...] = tuple(float(a) for a in np.radians([-30, -15, 0, 15, 30]))


@dataclass
class SearchResult:
    """Best grasp of the orientation search.

    Best grasp of the search: ``grasp`` (world frame), joint solution ``q`` (None if none reachable),
    ``quality`` (6.20), ``angle`` (rad), ``cost``, ``feasible`` (IK ok, no collision, quality > 0) and
    per-angle ``table`` rows (angle, quality, ik_ok, collision_free, cost).
    """

    grasp: Grasp
    q: np.ndarray | None
    quality: float
    angle: float
    cost: float
    feasible: bool
    table: np.ndarray | None = field(repr=False, default=None)
    detail: GraspQuality | None = field(repr=False, default=None)


def orientation_search(grasp: Grasp, cloud: npt.ArrayLike, robot: Robot | None = None, *,
                       gripper: ParallelGripper = NARROW_GRIPPER, angles: npt.ArrayLike | None = None,
                       weight: float = 0.05, table_z: float | None = None, q_ref: npt.ArrayLike | None = None,
                       base_pose: np.ndarray | None = None, lift: float = 0.10,
                       pre_grasp: float | None = PRE_GRASP, tree: cKDTree | None = None,
                       observed: cKDTree | None = None, edge_normals: bool = False,
                       pad_reach: float | None = None) -> SearchResult:
    """(6.21) search rotations of ``grasp`` about its closing axis.

    Args:
        grasp: transferred grasp in the world frame.
        cloud: object points (n, 3), world frame (m).
        robot: a :class:`robointel.robot.Robot` whose tool is the gripper's grasp frame
            (``Robot.load("lrmate200id7l", tool=gripper.tool_transform())``); None skips IK.
        angles: candidate turns (rad); default -90..90 deg in 10 deg steps.
        weight: cost per radian away from the transferred orientation.
        table_z: table plane height (world) for the gripper-table check.
        q_ref: preferred joint configuration (IK solutions sorted by distance to it).
        base_pose: 4x4 world pose of the robot root (default identity).
        lift: the grasp is only feasible if the pose ``lift`` metres above is reachable too.
        pre_grasp: ... and the pre-grasp pose ``pre_grasp`` metres back along the approach, from which
            the jaws move in (None: not checked).
        observed: KD-tree of the perceived points when ``cloud`` is completed (see
            :func:`grasp_quality`: contacts must have been seen).
        edge_normals: rim normals at contacts on thin parts seen face-on (see :func:`grasp_quality`).
        pad_reach: contacts only where the finger pads reach (see :func:`grasp_quality`).
        gripper: the jaw model (opening, finger and palm boxes).
        tree: KD-tree of ``cloud`` (built when None).

    Returns:
        The lowest-cost turn; ``feasible`` False (and ``q`` None) when no turn is reachable, collision-free
        and of positive quality.
    """
    P = np.asarray(cloud, float)
    tree = tree or cKDTree(P)
    angles = np.radians(np.arange(-90, 91, 10)) if angles is None else np.asarray(angles, float)
    Tb_inv = np.linalg.inv(base_pose) if base_pose is not None else np.eye(4)
    rows: list[tuple[float, float, bool, bool, float]] = []
    best: tuple[float, Grasp, np.ndarray | None, GraspQuality, float, bool] | None = None
    cache: dict = {}
    for a in angles:
        g = grasp.rotated_about_axis(float(a))
        if table_z is not None:  # raise the grasp until the fingertips clear the table
            tips = g.centre[2] + min(((np.array([sx, sy, sz]) * s / 2 + c) @ g.rotation[2])
                                     for c, s in gripper.boxes()[:2]
                                     for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1))
            deficit = table_z + 0.003 - tips
            if deficit > 0:
                g = Grasp(g.centre + np.array([0, 0, deficit]), g.rotation, g.width, g.name)
        key = tuple(np.round(g.centre, 6))
        if key not in cache:  # turning about the closing axis leaves the contacts unchanged
            cache[key] = grasp_quality(P, g, gripper=gripper, tree=tree, observed=observed,
                                       edge_normals=edge_normals, pad_reach=pad_reach,
                                       table_z=table_z)
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
                if pre_grasp is not None:
                    pre = g.pose.copy()
                    pre[:3, 3] -= pre_grasp * g.approach
                    robot.ik(Tb_inv @ pre, q_ref=sols[0])
                q = sols[0]
            except IKFailure:
                ik_ok = False
        cost = -gq.quality + weight * abs(a) + (0 if ik_ok else PENALTY) + (PENALTY if col else 0)
        rows.append((a, gq.quality, ik_ok, not col, cost))
        if best is None or cost < best[0]:
            best = (cost, g, q, gq, a, ik_ok and not col and gq.quality > 0)
    if best is None:
        raise InvalidInput("orientation_search needs at least one candidate angle", value=angles)
    cost, g, q, gq, a, ok = best
    return SearchResult(g, q, float(gq.quality), float(a), float(cost), bool(ok), np.array(rows, float), gq)


def refine_position(grasp: Grasp, cloud: npt.ArrayLike, *, gripper: ParallelGripper = NARROW_GRIPPER,
                    step: float = 0.006, yaws: Sequence[float] = REFINE_YAWS,
                    dz: Sequence[float] = (0.0, 0.005, -0.005, -0.01), weight: float = 2.0,
                    keep: int = 3, tree: cKDTree | None = None, table_z: float | None = None,
                    column_radius: float = 0.008, clearance: float = 0.003,
                    slide: Sequence[float] = (-0.018, -0.012, 0.012, 0.018), observed: npt.ArrayLike | None = None,
                    edge_normals: bool = False,
                    pad_reach: float | None = None, rest_height: bool = False,
                    toward: npt.ArrayLike | None = None, com_weight: float = 0.0,
                    com_reach: float = 0.06) -> list[Grasp]:
    """Refine a transferred grasp's position locally (our addition before (6.21)).

    Our addition before (6.21): a small local search around a transferred grasp, for when the warp
    lands it a few millimetres off a thin feature (a cup's rim, a tool's handle). Centres on a
    3 x 3 grid (``step`` m) in the plane normal to the approach, heights ``dz``, turns of the closing
    axis about the approach by ``yaws``, for the grasp as transferred and turned upright (approach
    along gravity, when it was within 60 deg of it); scored by isotropy (6.20) minus ``weight`` per metre of offset.
    Returns the ``keep`` best (the unmodified grasp is always a candidate).

    With ``table_z`` (world, m) the upright grasp is also tried at the height found from the cloud
    itself: the middle of the cloud's column within ``column_radius`` (m, horizontally) of the centre,
    cut below where the fingertips clear the table by ``clearance`` (m). A warp fitted to a cloud that
    lacks the object's underside (the cameras never see it) can put a flat object's grasps at or below
    the table (forks and knives lying flat: every transferred grasp missed the handle, 'off-axis');
    the object's own visible surface (``observed``, default ``cloud``: pass the perceived points
    when ``cloud`` is completed by a warped template; contacts must then also have been seen, see
    :func:`grasp_quality`) says at which height the jaws meet it. These re-heighted grasps
    are also tried slid by ``slide`` (m) horizontally across the closing axis (along a handle), for
    thin parts whose graspable spots are a few millimetres long (the offset is penalised like the
    grid's). ``edge_normals``, ``pad_reach``: as in :func:`grasp_quality`.

    ``rest_height``: the re-heighted grasps are also tried at half the column's top height above
    the table (not below the fingertip clearance): the middle of a part lying on the table, whose
    underside the cameras never see (the lowest seen point of a fork's 12 mm thick scan was 4 mm up,
    which put the jaws 1 mm over its widest section).

    ``toward`` (world, m; the perceived cloud's centroid, a stand-in for the centre of mass) with
    ``com_weight`` > 0: the re-heighted grasps are also tried slid along the part toward it (by at most
    ``com_reach`` m), and every candidate's score loses ``com_weight`` per metre of horizontal distance
    between its centre and ``toward`` (gravity's lever on the grip).
    """
    P = np.asarray(cloud, float)
    Pobs = P if observed is None else np.asarray(observed, float)
    obs_tree = None if observed is None else cKDTree(Pobs)
    tree = tree or cKDTree(P)
    scored = []
    bases = [grasp]
    ax_h = np.array([grasp.axis[0], grasp.axis[1], 0.0])
    if np.linalg.norm(ax_h) > 0.5 and grasp.approach[2] < -0.5:  # also try it upright (gravity known)
        up = grasp_from_axis(grasp.centre, ax_h, [0.0, 0.0, -1.0], grasp.width, grasp.name)
        bases.append(up)
        if table_z is not None:
            z_clear = table_z + gripper.tip_depth + clearance
            along = np.cross([0.0, 0.0, 1.0], up.axis)  # horizontal, across the closing axis
            slides = (0.0,) + tuple(slide)
            if toward is not None and com_weight > 0:
                b_com = float(np.clip((np.asarray(toward, float) - grasp.centre) @ along, -com_reach, com_reach))
                if min(abs(b_com - b_) for b_ in slides) > 0.003:
                    slides += (b_com,)
            for b in slides:
                c = grasp.centre + b * along
                col = Pobs[np.linalg.norm(Pobs[:, :2] - c[:2], axis=1) < column_radius]
                if len(col) >= 3 and np.percentile(col[:, 2], 95) > z_clear:
                    z_hi = float(np.percentile(col[:, 2], 95))
                    z_mid = 0.5 * (max(float(col[:, 2].min()), z_clear) + z_hi)
                    bases.append(Grasp(np.array([c[0], c[1], z_mid]), up.rotation, grasp.width, grasp.name))
                    # the middle of a part lying on the table (its unseen underside on the table)
                    z_rest = max(0.5 * (table_z + z_hi), z_clear)
                    if rest_height and abs(z_rest - z_mid) > 0.002:
                        bases.append(Grasp(np.array([c[0], c[1], z_rest]), up.rotation, grasp.width, grasp.name))
    for base, yaw in [(b_, y_) for b_ in bases for y_ in yaws]:
        z = base.approach
        u = base.axis
        v = np.cross(z, u)
        c, s_ = np.cos(yaw), np.sin(yaw)
        Rz = np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]])
        R = base.rotation @ Rz
        for a in (-step, 0.0, step):
            for b in (-step, 0.0, step):
                for h in dz:
                    off = a * u + b * v - h * z
                    g = Grasp(base.centre + off, R, base.width, base.name)
                    off = g.centre - grasp.centre
                    q = grasp_quality(P, g, gripper=gripper, tree=tree, observed=obs_tree, edge_normals=edge_normals,
                                      pad_reach=pad_reach, table_z=table_z)
                    score = q.quality - weight * float(np.linalg.norm(off)) - 0.05 * abs(yaw)
                    if toward is not None and com_weight > 0:
                        gc = q.grasp.centre if q.grasp is not None else g.centre
                        score -= com_weight * float(np.linalg.norm(gc[:2] - np.asarray(toward, float)[:2]))
                    scored.append((score, q.grasp if q.grasp is not None and q.quality > 0 else g))
    scored.sort(key=lambda t: -t[0])
    out = [grasp]
    for _, g in scored:
        if len(out) > keep:
            break
        if all(np.linalg.norm(g.centre - h.centre) > 1e-4 or not np.allclose(g.rotation, h.rotation) for h in out):
            out.append(g)
    return out
