"""The Ch. 6 grasp pipeline and MuJoCo lift-and-shake trials (Table 6.2).

:class:`GraspPlanner` classifies a perceived cloud against the templates (6.17)-(6.19), transfers the
taught grasps through the fitted CPD warp (6.14)-(6.16), scores them (6.20) and refines the best by the
orientation search (6.21) with the LR Mate's IK. :func:`grasp_trial` places an object at a random pose,
perceives it with the two simulated depth cameras, plans, then has the whole LR Mate in MuJoCo (joint
servos, links colliding, the gripper on its flange) follow the joint path (park, pre-grasp, grasp,
close, lift 10 cm, shake with J1 and J6) and reports success when the object is still between the
fingers at the end (``arm=False``: the earlier simplification, the gripper alone on the path's forward
kinematics).
"""
from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from robointel.errors import IKFailure, InvalidInput, RobointelError
from robointel.learning.grasp.classify import Classification, ComposedWarp, Fit, Template, classify, fit_template
from robointel.learning.grasp.cpd import RigidWarp, cpd_rigid, single_thread_blas
from robointel.learning.grasp.objects import ObjectModel
from robointel.learning.grasp.perception import DepthCamera, default_cameras, depth_image, perceive
from robointel.learning.grasp.quality import (
    NARROW_GRIPPER,
    WIDE_GRIPPER,
    ParallelGripper,
    choose_gripper,
    grasp_quality,
)
from robointel.learning.grasp.scene import ARM_KP, ARM_KV, Placement, arm_scene, scene_xml
from robointel.learning.grasp.search import SearchResult, orientation_search, refine_position
from robointel.learning.grasp.transfer import Grasp, transfer_grasp
from robointel.robot import Robot

__all__ = ["GraspPlanner", "GraspPlan", "GraspTrialResult", "carve_above_seen", "grasp_trial", "lrmate_with_gripper",
           "perceived_template"]


def lrmate_with_gripper(gripper: ParallelGripper = NARROW_GRIPPER) -> Robot:
    """The LR Mate 200iD/7L with the gripper's grasp frame as its tool (for :func:`orientation_search`)."""
    return Robot.load("lrmate200id7l", tool=gripper.tool_transform())


def carve_above_seen(completion: np.ndarray, observed: np.ndarray, *, radius: float = 0.008,
                     margin: float = 0.006, footprint: float | None = 0.008) -> np.ndarray:
    """The completion points (k, 3) that do not contradict the perceived cloud ``observed`` (n, 3).

    The cameras look down on the table from above the workspace, so the top of every object resting
    on the table is in view and its footprint is the vertical projection of what they see. Dropped:
    a completion point (the warped template's) higher than ``margin`` (m) above every observed point
    within ``radius`` (m, horizontally): it lies in space the cameras saw empty; and (``footprint``
    not None) a point with no observed point within ``footprint`` (m, horizontally): it lies beside
    the object, where the cameras saw the table. Points under the seen surface (the sides and the
    underside the cameras miss) are kept. A warp of a thick template (the screwdriver) onto a thin
    target (a fork) otherwise left template points floating above and beside the handle, and jaws
    planned on them closed on nothing. ``margin`` and ``footprint`` cover the 5 mm voxels (a voxel
    mean sits up to 2.5 mm inside the surface) and the depth noise. Assumes no undercut wider than
    the object's top (objects lying or standing on the table).
    """
    W = np.asarray(completion, float)
    X = np.asarray(observed, float)
    if len(W) == 0 or len(X) == 0:
        return W
    tree = cKDTree(X[:, :2])
    keep = np.ones(len(W), bool)
    for i, nb in enumerate(tree.query_ball_point(W[:, :2], radius)):
        if nb and W[i, 2] > X[nb, 2].max() + margin:
            keep[i] = False
    if footprint is not None:
        d, _ = tree.query(W[:, :2])
        keep &= d <= footprint
    return W[keep]


@dataclass
class GraspPlan:
    """A planned grasp: classification, transferred grasps, search result, gripper, timings.

    A planned grasp: the classification, the transferred grasps, the chosen search result, the
    wall-clock time of each step (s), the ``gripper`` the grasp is planned for (its tool in the IK),
    the contact ``widths`` (m) of the transferred grasps that chose it, and ``gripper_fallback``: True
    when the width chose the narrow gripper, it had no feasible grasp and the wide one did.
    """

    classification: Classification
    transferred: list[Grasp]
    search: SearchResult
    timings: dict[str, float] = field(default_factory=dict)
    gripper: ParallelGripper = NARROW_GRIPPER
    widths: list[float] = field(default_factory=list)
    gripper_fallback: bool = False

    @property
    def feasible(self) -> bool:
        """Whether the search found a reachable, collision-free grasp of positive quality."""
        return self.search.feasible


class GraspPlanner:
    """Templates + gripper + robot; :meth:`plan` runs classify -> register -> transfer -> score -> search.

    Args:
        templates: taught objects (points + grasps in their frames).
        robot: robot with the gripper tool (default the LR Mate); None skips IK.
        base_pose: 4x4 world pose of the robot root. table_z: table height (world).
        n_points: points per cloud used in registration.
        seen_contacts: require both contacts on perceived points (quality code UNSEEN otherwise, see
            :func:`grasp_quality`), not only on the warped-template completion. Off: on validation
            placements (seed 11, arm trials) it turned two forks dropped from grasps on the completion
            into infeasible plans and cost long tools 18/20 -> 13/20 overall (thin handles are sparsely seen).
        classifiers: the K templates of (6.17)-(6.19) (default ``templates``): several instances per
            category may classify (nearest template wins) while the grasps are transferred from the
            category's taught template in ``templates`` (the classifying template itself when it has
            grasps). :meth:`plan` can exclude templates by name (held-out targets).
        edge_normals: contact normals on thin parts seen face-on are their rims' (see
            :func:`grasp_quality`); False = PCA normals everywhere (the earlier behaviour).
        carve: drop completion points (warped template) that lie above the perceived surface, in
            space the cameras saw empty (:func:`carve_above_seen`).
        pad_reach: contacts must lie this far (m) inside the finger pads (see :func:`grasp_quality`;
            None = the whole line-search cylinder, the earlier test).
        rest_height: re-heighted upright grasps also at mid-height of a part lying on the table
            (see :func:`refine_position`).
        wide_gripper: a second, wider gripper (default the 85 mm :data:`WIDE_GRIPPER`; None: ``gripper``
            only), chosen per object by the transferred grasps' widths (:func:`choose_gripper`: the
            narrow ``gripper`` when the part fits it, else the wide one) and tried as well when the
            narrow one finds no feasible grasp. Used only with ``robot="lrmate"`` or ``robot=None``
            (the LR Mate is loaded with each gripper's tool).
    """

    def __init__(self, templates: list[Template], *, gripper: ParallelGripper = NARROW_GRIPPER,
                 robot: Robot | str | None = "lrmate", base_pose: np.ndarray | None = None, table_z: float = 0.0,
                 n_points: int = 200, q_ref: npt.ArrayLike | None = None, local_radius: float = 0.04,
                 refine: bool = True, seen_contacts: bool = False,
                 classifiers: list[Template] | None = None, edge_normals: bool = True, carve: bool = True,
                 pad_reach: float | None = 0.003, rest_height: bool = True,
                 wide_gripper: ParallelGripper | None = WIDE_GRIPPER) -> None:
        if not templates:
            raise InvalidInput("GraspPlanner needs at least one template", value=templates)
        self.templates = templates
        self.classifiers = list(classifiers) if classifiers else list(templates)
        self.gripper = gripper
        if isinstance(robot, str) and robot != "lrmate":
            raise InvalidInput(f"robot must be 'lrmate', a Robot or None, got {robot!r}", value=robot)
        self.robot: Robot | None = lrmate_with_gripper(gripper) if robot == "lrmate" else robot  # type: ignore[assignment]
        self.grippers = [gripper]
        self._robots: dict[ParallelGripper, Robot | None] = {gripper: self.robot}
        if wide_gripper is not None and wide_gripper != gripper and (robot == "lrmate" or robot is None):
            self.grippers.append(wide_gripper)
            self._robots[wide_gripper] = lrmate_with_gripper(wide_gripper) if robot == "lrmate" else None
        self.base_pose = np.eye(4) if base_pose is None else np.asarray(base_pose, float)
        self.table_z = table_z
        self.n_points = n_points
        self.local_radius = local_radius
        self.refine = refine
        self.seen_contacts = seen_contacts
        self.edge_normals = edge_normals
        self.carve = carve
        self.pad_reach = pad_reach
        self.rest_height = rest_height
        self.q_ref = np.radians([0, 20, -10, 0, -70, 0]) if q_ref is None else np.asarray(q_ref, float)

    def robot_for(self, gripper: ParallelGripper) -> Robot | None:
        """The robot whose tool is ``gripper``'s grasp frame (one of :attr:`grippers`; None: no IK).

        Raises:
            InvalidInput: ``gripper`` is not one of the planner's.
        """
        if gripper not in self._robots:
            raise InvalidInput(f"gripper {gripper.name!r} is not one of the planner's", value=gripper.name)
        return self._robots[gripper]

    def _transfer(self, fit: Fit, g: Grasp, cloud: np.ndarray) -> Grasp:
        """Transfer one taught grasp (6.14)-(6.16), locally refined by a rigid CPD.

        (6.14)-(6.16) through the fitted warp, optionally followed by a local rigid CPD of the
        template's neighbourhood of the grasp (radius ``local_radius``) onto the target's, which keeps
        grasps on articulated or locally different parts where a smooth global warp lags.
        """
        h = transfer_grasp(fit.warp, g)
        r = self.local_radius
        if not r:
            return h
        Y = fit.template.points
        local = Y[np.linalg.norm(Y - g.centre, axis=1) < r]
        Xl = cloud[np.linalg.norm(cloud - h.centre, axis=1) < 1.5 * r]
        if len(local) < 20 or len(Xl) < 20:
            return h
        Wl = fit.warp(local)
        try:
            rr = cpd_rigid(Xl, Wl, scale=False, w=0.1, tolerance=1e-3, max_iterations=30, method="fast")
        except RobointelError:
            return h
        rw = rr.warp
        assert isinstance(rw, RigidWarp)
        ang = np.arccos(np.clip((np.trace(rw.R) - 1) / 2, -1, 1))
        if ang > np.radians(20) or np.linalg.norm(rw.t + rw.R @ h.centre - h.centre) > r:
            return h  # the local fit jumped to another part: keep the global transfer
        return transfer_grasp(ComposedWarp(fit.warp, rr.warp), g)

    def plan(self, cloud: npt.ArrayLike, exclude: Iterable[str] = ()) -> GraspPlan:
        """Plan a grasp on a perceived cloud.

        Plan a grasp on ``cloud`` (n, 3) in the world frame; classifying templates named in
        ``exclude`` are left out (a held-out target is never its own template).
        """
        with single_thread_blas():
            return self._plan(cloud, set(exclude))

    def _grasp_template(self, cls: Classification) -> Template:
        t = cls.best.template
        if t.grasps:
            return t
        for u in self.templates:
            if u.category == cls.category and u.grasps:
                return u
        raise InvalidInput(f"no template of category {cls.category!r} has taught grasps", value=cls.category)

    def _plan(self, cloud: npt.ArrayLike, exclude: set[str] | frozenset[str] = frozenset()) -> GraspPlan:
        t0 = time.perf_counter()
        cands = [t for t in self.classifiers if t.name not in exclude]
        if not cands:
            raise InvalidInput("every classifying template is excluded", value=sorted(exclude))
        cls = classify(cloud, cands, n_points=self.n_points)
        tmpl = self._grasp_template(cls)
        # the bounded per-axis scale of the template init separates categories (classification) but
        # its stretched warp moved transferred grasps off cup rims (cups 20/20 -> 14/20). The grasps
        # are transferred through two fits of the chosen template: one that rests on the table (base
        # on the table, height scaled to the observed height, x-y scaled isotropically; it keeps flat
        # tools' grasps above the table) and one with an isotropic, centroid-matched init (the earlier
        # transfer fit). Each fit's transferred grasps are refined and searched against that fit's
        # completed cloud; the lowest (6.21) cost wins.
        cloud = np.asarray(cloud, float)
        fits = [fit_template(cloud, tmpl, n_points=self.n_points, rest_z=self.table_z, starts=1),
                fit_template(cloud, tmpl, n_points=self.n_points, anisotropic=0.0, starts=1)]
        t1 = time.perf_counter()
        per_fit = [[self._transfer(fit, g, cloud) for g in fit.template.grasps] for fit in fits]
        grasps = per_fit[0]
        t2 = time.perf_counter()
        # the warped template completes the sides the cameras do not see
        fulls = []
        for fit in fits:
            W = fit.warp(fit.template.points)
            if self.carve:
                W = carve_above_seen(W, cloud)
            full = np.vstack([cloud, W])
            fulls.append((full, cKDTree(full)))
        # the transferred grasps' widths (line search of the widest gripper) choose the gripper
        widest = max(self.grippers, key=lambda g_: g_.max_width)
        widths = [grasp_quality(full, g, gripper=widest, tree=tree, pad_reach=self.pad_reach,
                                table_z=self.table_z).width
                  for (full, tree), gs in zip(fulls, per_fit) for g in gs]
        gripper = choose_gripper(widths, self.grippers)
        best = self._search(fulls, per_fit, cloud, gripper)
        fallback = False
        if not best.feasible and gripper != widest:
            wide = self._search(fulls, per_fit, cloud, widest)
            if wide.feasible:
                best, gripper, fallback = wide, widest, True
        t3 = time.perf_counter()
        return GraspPlan(cls, grasps, best, {"classify_register": t1 - t0, "transfer": t2 - t1,
                                             "score_search": t3 - t2, "total": t3 - t0},
                         gripper, [float(w) for w in widths], fallback)

    def _search(self, fulls: Sequence[tuple[np.ndarray, cKDTree]], per_fit: Sequence[Sequence[Grasp]],
                cloud: np.ndarray, gripper: ParallelGripper) -> SearchResult:
        """Refine and search (6.21) the transferred grasps with ``gripper``; the lowest cost wins.

        Each fit's grasps are refined (:func:`refine_position`) and searched on that fit's completed
        cloud, the IK with the robot carrying ``gripper``.
        """
        robot = self.robot_for(gripper)
        best: SearchResult | None = None
        # contacts on perceived points only (off by default, see ``seen_contacts``)
        seen = cKDTree(cloud) if self.seen_contacts else None
        for (full, tree), gs in zip(fulls, per_fit):
            cands: list[Grasp] = []
            for g in gs:
                cands += (refine_position(g, full, gripper=gripper, tree=tree, table_z=self.table_z,
                                          observed=cloud, edge_normals=self.edge_normals,
                                          pad_reach=self.pad_reach, rest_height=self.rest_height)
                          if self.refine else [g])
            for g in cands:
                r = orientation_search(g, full, robot, gripper=gripper, table_z=self.table_z,
                                       base_pose=self.base_pose, q_ref=self.q_ref, tree=tree, observed=seen,
                                       edge_normals=self.edge_normals, pad_reach=self.pad_reach)
                if best is None or r.cost < best.cost:
                    best = r
        if best is None:
            raise InvalidInput("the template has no taught grasps to transfer", value=len(per_fit))
        return best


@dataclass
class GraspTrialResult:
    """One lift-and-shake trial's result.

    One lift-and-shake trial: ``success``, the planned ``plan`` (None if perception failed),
    the predicted ``category``, the object's final height (m), a ``reason`` and a ``log``: the state at
    the end of each phase (:data:`PHASES`; see :func:`_phase_state`).
    """

    success: bool
    reason: str
    category: str | None = None
    plan: GraspPlan | None = None
    final_height: float = float("nan")
    cloud: np.ndarray | None = None
    log: list[dict[str, Any]] = field(default_factory=list)

    @property
    def gripper(self) -> str | None:
        """Name of the gripper the trial used (None when nothing was planned)."""
        return self.plan.gripper.name if self.plan is not None else None


#: The phases of a trial's joint path, in order.
PHASES = ("approach", "descend", "close", "lift", "shake", "hold")


def _phase_state(m: mujoco.MjModel, d: mujoco.MjData, phase: str, body: int, gbody: int, fingers: set[int], fp: int,
                 g: ParallelGripper) -> dict[str, Any]:
    """Diagnostics at the end of a trial phase.

    Diagnostics at the end of a trial phase: ``phase``; the object's position in the gripper's
    frame ``obj_in_gripper`` (m, (3,)); its height ``obj_z`` (m); the lowest fingertip corner's height
    ``fingertip_z`` (m, world); the jaw opening ``opening`` (m); the
    summed normal force of the finger-object contacts ``grip_normal_N`` (N) and their summed
    tangential (friction) force ``grip_tangential_N`` (N); ``contacts`` (count).
    """
    R = d.xmat[gbody].reshape(3, 3)
    rel = R.T @ (d.xpos[body] - d.xpos[gbody])
    fn = ft = 0.0
    n = 0
    f6 = np.zeros(6)
    for i in range(d.ncon):
        c = d.contact[i]
        b1, b2 = m.geom_bodyid[c.geom1], m.geom_bodyid[c.geom2]
        if (b1 == body and b2 in fingers) or (b2 == body and b1 in fingers):
            mujoco.mj_contactForce(m, d, i, f6)
            fn += abs(f6[0])
            ft += float(np.hypot(f6[1], f6[2]))
            n += 1
    tips = min(float((d.geom_xpos[j] + d.geom_xmat[j].reshape(3, 3) @ (np.array([sx, sy, sz]) * m.geom_size[j]))[2])
               for j in range(m.ngeom) if m.geom_bodyid[j] in fingers
               for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1))
    return {"phase": phase, "obj_in_gripper": rel.round(4).tolist(), "obj_z": round(float(d.xpos[body][2]), 4),
            "fingertip_z": round(tips, 4),
            "opening": round(float(g.max_width - 2 * d.qpos[m.jnt_qposadr[fp]]), 4),
            "grip_normal_N": round(fn, 2), "grip_tangential_N": round(ft, 2), "contacts": n}


def _smooth(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    s = 0.5 - 0.5 * np.cos(np.linspace(0, np.pi, n))
    return a + (b - a) * s[:, None]


#: Least rise (m) of a held object over its resting height at the end of a trial (the lift is 10 cm).
LIFT_MIN = 0.05

#: Height (m) of the pre-grasp pose's grasp centre above the perceived top of the object on the way in:
#: the arm swings from :data:`Q_PARK` to that pose, then moves straight down to the pre-grasp (half the
#: height when that pose is out of reach, the pre-grasp itself when neither is reachable).
HOVER_CLEARANCE = 0.15

#: Where the arm waits while the cameras look (joint angles, rad): turned 90 deg away from the table
#: and folded up, out of the cameras' view of the workspace.
Q_PARK = np.radians([90.0, -20.0, 10.0, 0.0, -60.0, 0.0])


def grasp_trial(obj: ObjectModel, placement: Placement, planner: GraspPlanner, *,
                rng: np.random.Generator | int | None = None, cameras: list[DepthCamera] | None = None,
                shake_amplitude: float = 0.15, settle: float = 0.3, arm: bool = True) -> GraspTrialResult:
    """Run one lift-and-shake trial (Table 6.2) in MuJoCo.

    Place ``obj`` (free body), perceive, plan, approach, close, lift 10 cm, shake; success if the
    object is still held: raised by more than :data:`LIFT_MIN` over its height before the jaws closed,
    touching a finger, and within 3 cm of where it sat in the gripper after the lift.

    ``arm=True`` (default): the whole LR Mate is in the MuJoCo scene (:func:`scene.arm_scene`): its
    joint servos track the planned joint path (park -> the pre-grasp pose raised to
    :data:`HOVER_CLEARANCE` above the perceived top of the object -> down to the pre-grasp 8 cm back
    along the approach -> grasp -> close -> lift 10 cm -> shake with J1 and J6), its links collide
    with the table and the object, and the held object loads its joints. ``arm=False``: the gripper
    alone follows the forward kinematics of the path from the pre-grasp on (a mocap weld), no arm
    links. The gripper on the flange is the one the plan chose (:class:`GraspPlanner`: the 48 mm one,
    or the 85 mm one for wide parts), driven with its own ``grip_force``.

    Args:
        obj: The object (a free body in the scene).
        placement: Where it rests on the table.
        planner: The grasp planner (its robot at the world origin with ``arm=True``).
        rng: Seed or generator of the sensor noise.
        cameras: The depth cameras (default :func:`default_cameras`).
        shake_amplitude: Amplitude of the J6 shake (rad; J1 shakes by 0.06 rad), both at 2 Hz for 1.5 s.
        settle: Time the object settles before the cameras look (s).
        arm: Simulate the whole arm (else the gripper alone).

    Returns:
        The trial's result (``success``, ``reason``, the plan, the state at the end of each phase).

    Raises:
        InvalidInput: the planner has no robot, or (``arm``) its base is not at the world origin.
    """
    rng = np.random.default_rng(rng)
    cams = cameras or default_cameras()
    Tb = planner.base_pose
    # the scene is built before the plan (the cameras look at it); the plan may choose the wide gripper
    # (then the scene is rebuilt with it, the object and the noise draws as they were)
    return _trial(obj, placement, planner, planner.gripper, rng, cams, shake_amplitude, settle, arm, Tb,
                  dict(rng.bit_generator.state))


def _trial(obj: ObjectModel, placement: Placement, planner: GraspPlanner, g: ParallelGripper, rng: np.random.Generator,
           cams: list[DepthCamera], shake_amplitude: float, settle: float, arm: bool, Tb: np.ndarray,
           rng_state: dict[str, Any],
           plan: GraspPlan | None = None) -> GraspTrialResult:
    robot = planner.robot_for(g)
    if robot is None:
        raise InvalidInput("grasp_trial needs a planner with a robot (robot='lrmate')", value=None)
    if arm:
        if robot is None or not np.allclose(Tb, np.eye(4)):
            raise InvalidInput("grasp_trial(arm=True) needs the planner's robot at the world origin", value=Tb)
        m = arm_scene([placement], robot, g)
        jadr = np.array([m.jnt_qposadr[m.joint("arm/" + n).id] for n in robot.joint_names])
        gbody = m.body("arm/gripper").id
        fp = m.joint("arm/fp").id
    else:
        m = mujoco.MjModel.from_xml_string(scene_xml([placement], dynamic=True, gripper=g))
        gbody = m.body("gripper").id
        fp = m.joint("fp").id
    d = mujoco.MjData(m)
    d.ctrl[:] = 0.0
    if arm:
        d.qpos[jadr] = Q_PARK
        d.ctrl[:6] = Q_PARK
    else:
        d.mocap_pos[0] = np.array([0.5, 0.0, 1.6])
    mujoco.mj_forward(m, d)
    # background: the same scene with the object moved far away (the empty workspace)
    qadr = m.jnt_qposadr[m.joint("obj0").id]
    saved = d.qpos[qadr:qadr + 7].copy()
    d.qpos[qadr:qadr + 3] = [5.0, 5.0, -5.0]
    mujoco.mj_forward(m, d)
    bgs = [depth_image(m, d, c, rng) for c in cams]
    d.qpos[qadr:qadr + 7] = saved
    mujoco.mj_forward(m, d)
    for _ in range(int(settle / m.opt.timestep)):
        mujoco.mj_step(m, d)
    clouds = perceive(m, d, cams, bgs, rng=rng)
    if not clouds:
        return GraspTrialResult(False, "nothing perceived")
    cloud = clouds[0]
    if len(cloud) < 20:
        return GraspTrialResult(False, "cloud too small", cloud=cloud)
    if plan is None:
        plan = planner.plan(cloud, exclude=(obj.name,))
        if plan.gripper != g:  # the same placement and draws, the chosen gripper on the flange
            rng.bit_generator.state = rng_state
            return _trial(obj, placement, planner, plan.gripper, rng, cams, shake_amplitude, settle, arm, Tb,
                          rng_state, plan)
    cat = plan.classification.category
    res = plan.search
    if not res.feasible or res.q is None:
        why = plan.search.detail.reason if plan.search.detail else "-"
        return GraspTrialResult(False, f"no feasible grasp ({why})",
                           cat, plan, cloud=cloud)
    G = res.grasp.pose
    pre = G.copy()
    pre[:3, 3] -= 0.08 * res.grasp.approach
    # the gripper comes in from above: the pre-grasp pose raised to HOVER_CLEARANCE above the
    # perceived top of the object, then straight down to the pre-grasp
    up = G.copy()
    up[2, 3] += 0.10
    try:
        q_grasp = res.q
        q_pre = robot.ik(np.linalg.inv(Tb) @ pre, q_ref=q_grasp)[0]
        q_up = robot.ik(np.linalg.inv(Tb) @ up, q_ref=q_grasp)[0]
    except IKFailure:
        return GraspTrialResult(False, "approach or lift unreachable", cat, plan, cloud=cloud)
    q_hover = q_pre  # when no raised pose is reachable, the swing ends at the pre-grasp itself
    for clearance in (HOVER_CLEARANCE, HOVER_CLEARANCE / 2):
        hover = pre.copy()
        hover[2, 3] = max(pre[2, 3], float(cloud[:, 2].max()) + clearance)
        try:
            q_hover = robot.ik(np.linalg.inv(Tb) @ hover, q_ref=q_pre)[0]
            break
        except IKFailure:
            continue
    dt = m.opt.timestep
    open_w = g.max_width / 2 - 0.0  # finger joint 0 = open
    approach = (np.vstack([_smooth(Q_PARK, q_hover, int(1.5 / dt)), _smooth(q_hover, q_pre, int(0.5 / dt))]) if arm
                else _smooth(q_pre, q_pre, int(0.1 / dt)))
    path = [(approach, 0.0)]
    path.append((_smooth(q_pre, q_grasp, int(0.8 / dt)), 0.0))
    path.append((_smooth(q_grasp, q_grasp, int(0.6 / dt)), open_w))
    path.append((_smooth(q_grasp, q_up, int(1.0 / dt)), open_w))
    n_sh = int(1.5 / dt)
    tt = np.arange(n_sh) * dt
    shake = np.tile(q_up, (n_sh, 1))
    shake[:, 0] += 0.06 * np.sin(2 * np.pi * 2.0 * tt)
    shake[:, 5] += shake_amplitude * np.sin(2 * np.pi * 2.0 * tt)
    path.append((shake, open_w))
    path.append((_smooth(q_up, q_up, int(0.4 / dt)), open_w))
    body = m.body("obj0").id
    if not arm:
        gadr = m.jnt_qposadr[m.joint("gripper").id]
        T0 = Tb @ robot.fk(q_pre)
        q0 = np.empty(4)
        mujoco.mju_mat2Quat(q0, T0[:3, :3].ravel())
        d.qpos[gadr:gadr + 3] = T0[:3, 3]
        d.qpos[gadr + 3:gadr + 7] = q0
        d.qvel[m.jnt_dofadr[m.joint("gripper").id]:][:6] = 0.0
    kv_over_kp = np.asarray(ARM_KV) / np.asarray(ARM_KP)
    rel_after_lift = None
    fingers = {m.body("arm/fp" if arm else "fp").id, m.body("arm/fn" if arm else "fn").id}
    log: list[dict] = []
    for k, (qs, ctrl) in enumerate(path):
        qd = np.gradient(qs, dt, axis=0) if len(qs) > 1 else np.zeros_like(qs)
        for q, v in zip(qs, qd):
            if arm:
                # servo torque kp (ctrl - q) - kv qdot = kp (q_ref - q) + kv (qdot_ref - qdot)
                d.ctrl[:6] = q + kv_over_kp * v
            else:
                T = Tb @ robot.fk(q)
                d.mocap_pos[0] = T[:3, 3]
                qw = np.empty(4)
                mujoco.mju_mat2Quat(qw, T[:3, :3].ravel())
                d.mocap_quat[0] = qw
            d.ctrl[-2:] = ctrl
            mujoco.mj_step(m, d)
        log.append(_phase_state(m, d, PHASES[k], body, gbody, fingers, fp, g))
        if k == 1:
            z_rest = float(d.xpos[body][2])  # the object's height before the jaws close
        if k == 2:
            closed = float(d.qpos[m.jnt_qposadr[fp]])  # finger travel after closing (m)
        if k == 3:
            rel_after_lift = (d.xpos[body] - d.xpos[gbody]).copy()
            h_lift = float(d.xpos[body][2])
    rel = d.xpos[body] - d.xpos[gbody]
    h = float(d.xpos[body][2])
    moved = float(np.linalg.norm(rel - rel_after_lift))
    # held: raised by at least LIFT_MIN above where it rested, still in the jaws (touching a finger,
    # where it sat after the lift); an object's frame can rest above 5 cm (a toy arm lying on its side)
    held = h - z_rest > LIFT_MIN and moved < 0.03 and log[-1]["contacts"] > 0
    if held:
        reason = "held"
    elif closed > g.max_width / 2 - 0.002:
        reason = "dropped: fingers closed on nothing"
    elif h_lift - z_rest < LIFT_MIN:
        reason = f"dropped: slipped during lift (height {h_lift:.3f} m, grip {2 * (g.max_width / 2 - closed):.3f} m)"
    else:
        reason = (f"dropped: slipped during shake (moved {moved:.3f} m in hand, "
                  f"grip {2 * (g.max_width / 2 - closed):.3f} m)")
    return GraspTrialResult(bool(held), reason, cat, plan, h, cloud, log)


def perceived_template(obj: ObjectModel, *, rng: np.random.Generator | int | None = 0,
                       cameras: list[DepthCamera] | None = None, placement: Placement | None = None) -> np.ndarray:
    """The template cloud as the cameras see it at teach time.

    The template cloud as the cameras see it at teach time: ``obj`` placed at ``placement``
    (default: workspace centre, heading 0), perceived (Fig. 6.4 pipeline) and mapped back into the
    object frame (n, 3). Templates and targets then share the cameras' viewpoints and sampling.
    """
    rng = np.random.default_rng(rng)
    cams = cameras or default_cameras()
    p = placement or Placement(obj, 0.5, 0.0, 0.0)
    m0 = mujoco.MjModel.from_xml_string(scene_xml([]))
    d0 = mujoco.MjData(m0)
    mujoco.mj_forward(m0, d0)
    bgs = [depth_image(m0, d0, c, rng) for c in cams]
    m = mujoco.MjModel.from_xml_string(scene_xml([p]))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    clouds = perceive(m, d, cams, bgs, rng=rng)
    if not clouds:
        raise InvalidInput(f"the cameras do not see template {obj.name}", value=obj.name)
    T = np.linalg.inv(p.pose)
    return clouds[0] @ T[:3, :3].T + T[:3, 3]
