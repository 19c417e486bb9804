"""The Ch. 6 grasp pipeline (the lift-and-shake trials are in :mod:`.trial`).

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
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from robointel.errors import InvalidInput, RobointelError
from robointel.learning.grasp.classify import Classification, ComposedWarp, Fit, Template, classify, fit_template
from robointel.learning.grasp.cpd import RigidWarp, cpd_rigid, single_thread_blas
from robointel.learning.grasp.hand import between_jaws
from robointel.learning.grasp.hold import Hold, PartEstimate, Shake, estimate_part, hold, hull_volume
from robointel.learning.grasp.objects import ObjectModel
from robointel.learning.grasp.perception import DepthCamera, default_cameras, depth_image, perceive
from robointel.learning.grasp.quality import (
    NARROW_GRIPPER,
    WIDE_GRIPPER,
    ParallelGripper,
    choose_gripper,
    grasp_quality,
)
from robointel.learning.grasp.scene import Placement, scene_xml
from robointel.learning.grasp.search import PENALTY, SearchResult, orientation_search, refine_position
from robointel.learning.grasp.shape import ShapeClass, box_sides, shape_class, shape_cost, shape_grasps
from robointel.learning.grasp.transfer import Grasp, transfer_grasp
from robointel.robot import Robot

__all__ = ["AVOID_COST", "COM_WEIGHT", "HOLD_WEIGHT", "SHAPE_WEIGHT", "TILT_WEIGHT", "GraspPlan", "GraspPlanner",
           "carve_above_seen", "closing_tilt", "lrmate_with_gripper", "perceived_template"]


#: Default :attr:`GraspPlanner.com_weight` (cost per metre of a grasp's horizontal distance from the
#: perceived centroid).
COM_WEIGHT = 0.0

#: Default :attr:`GraspPlanner.tilt_weight` (cost per radian of a grasp's closing axis above or below
#: the horizontal).
TILT_WEIGHT = 0.0

#: Default :attr:`GraspPlanner.hold_weight`: cost of a grasp's hold shortfall (:meth:`Hold.cost`, 0..1)
#: added to its (6.21) cost.
HOLD_WEIGHT = 1.0

#: Default :attr:`GraspPlanner.shape_weight`: weight of :func:`~robointel.learning.grasp.shape.shape_cost` (0..2)
#: in a candidate's (6.21) cost.
SHAPE_WEIGHT = 0.5

#: Cost added to a candidate within 10 mm and 30 deg of a grasp that failed on this part before
#: (:meth:`GraspPlanner.plan`'s ``avoid``): another grasp is taken when one of comparable cost exists.
AVOID_COST = 1.0


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
    the contact ``widths`` (m) of the transferred grasps that chose it, ``gripper_fallback``: True
    when the width chose the narrow gripper, it had no feasible grasp and the wide one did, the chosen
    grasp's ``hold`` and the ``part`` estimate it was rated on (:mod:`robointel.learning.grasp.hold`), and
    the perceived part's ``shape`` class (:mod:`robointel.learning.grasp.shape`).
    """

    classification: Classification
    transferred: list[Grasp]
    search: SearchResult
    timings: dict[str, float] = field(default_factory=dict)
    gripper: ParallelGripper = NARROW_GRIPPER
    widths: list[float] = field(default_factory=list)
    gripper_fallback: bool = False
    hold: Hold | None = None
    part: PartEstimate | None = None
    shape: ShapeClass | None = None

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
        com_weight: cost per metre of horizontal distance between a grasp's centre and the perceived
            cloud's centroid (the centre of mass as far as the cameras tell; gravity's lever on the grip),
            added to the (6.21) cost of each candidate; :func:`refine_position` also slides the
            re-heighted grasps along the part toward the centroid. 0: off.
        tilt_weight: cost per radian of elevation of a grasp's closing axis from the horizontal
            (:func:`closing_tilt`), added to the (6.21) cost of each candidate: jaws closing level on a
            part lying on the table rather than one above and one under it. 0: off.
        hold_weight: cost of each candidate's hold shortfall (:func:`robointel.learning.grasp.hold.hold`:
            the pads' friction against the part's estimated weight and the shake's inertia, about the
            closing axis above all; :meth:`Hold.cost`), added to its (6.21) cost. 0: off.
        shake: the motion the hold is rated for (default :class:`~robointel.learning.grasp.hold.Shake`,
            the trial's).
        shape_weight: weight of each candidate's :func:`~robointel.learning.grasp.shape.shape_cost` for the
            perceived part's shape class (a rectangular tin across its short side, near its middle; a
            long part near its centre of mass, where it is thickest), added to its (6.21) cost; the
            class's own grasps (:func:`~robointel.learning.grasp.shape.shape_grasps`) join the
            transferred ones, and a "box"'s short side chooses its gripper. 0: off.
        check_between: a candidate is feasible only when the perceived cloud (not the completion) puts
            the part between its open jaws (:func:`robointel.learning.grasp.hand.between_jaws`), and its
            width is within the gripper's :attr:`~ParallelGripper.grip_range`.
    """

    def __init__(self, templates: list[Template], *, gripper: ParallelGripper = NARROW_GRIPPER,
                 robot: Robot | str | None = "lrmate", base_pose: np.ndarray | None = None, table_z: float = 0.0,
                 n_points: int = 200, q_ref: npt.ArrayLike | None = None, local_radius: float = 0.04,
                 refine: bool = True, seen_contacts: bool = False,
                 classifiers: list[Template] | None = None, edge_normals: bool = True, carve: bool = True,
                 pad_reach: float | None = 0.003, rest_height: bool = True,
                 wide_gripper: ParallelGripper | None = WIDE_GRIPPER, com_weight: float = COM_WEIGHT,
                 tilt_weight: float = TILT_WEIGHT, hold_weight: float = HOLD_WEIGHT, shake: Shake | None = None,
                 shape_weight: float = SHAPE_WEIGHT, check_between: bool = True) -> None:
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
        self.com_weight = com_weight
        self.tilt_weight = tilt_weight
        self.hold_weight = hold_weight
        self.shake = shake or Shake()
        self.shape_weight = shape_weight
        self.check_between = check_between
        self._volumes: dict[str, float] = {}
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

    def plan(self, cloud: npt.ArrayLike, exclude: Iterable[str] = (), *, gripper: ParallelGripper | None = None,
             avoid: Sequence[Grasp] = ()) -> GraspPlan:
        """Plan a grasp on a perceived cloud.

        Args:
            cloud: The perceived part (n, 3), m, world frame.
            exclude: Classifying templates left out by name (a held-out target is never its own template).
            gripper: Plan for this one of :attr:`grippers` only (the one on the flange when a grasp is
                tried again); None: chosen by the part's width (see the class).
            avoid: Grasps that failed on this part (world frame): candidates within 10 mm and 30 deg of
                one pay :data:`AVOID_COST`.

        Returns:
            The :class:`GraspPlan`.

        Raises:
            InvalidInput: ``gripper`` is not one of the planner's, or every template is excluded.
        """
        if gripper is not None:
            self.robot_for(gripper)
        with single_thread_blas():
            return self._plan(cloud, set(exclude), gripper, list(avoid))

    def _grasp_template(self, cls: Classification) -> Template:
        t = cls.best.template
        if t.grasps:
            return t
        for u in self.templates:
            if u.category == cls.category and u.grasps:
                return u
        raise InvalidInput(f"no template of category {cls.category!r} has taught grasps", value=cls.category)

    def _plan(self, cloud: npt.ArrayLike, exclude: set[str] | frozenset[str] = frozenset(),
              only: ParallelGripper | None = None, avoid: Sequence[Grasp] = ()) -> GraspPlan:
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
        # the warped template completes the sides the cameras do not see (a box's sides also come from
        # its seen top, :func:`box_sides`); it also tells the part's mass and centre of mass (the hold,
        # :mod:`.hold`)
        shape = shape_class(cloud, table_z=self.table_z)
        sides = box_sides(shape, table_z=self.table_z) if self.shape_weight else np.zeros((0, 3))
        fulls, parts = [], []
        for fit in fits:
            W = fit.warp(fit.template.points)
            parts.append(self._part(fit.template, W))
            if self.carve:
                W = carve_above_seen(W, cloud)
            full = np.vstack([cloud, W, sides])
            fulls.append((full, cKDTree(full)))
        # the transferred grasps' widths (line search of the widest gripper) choose the gripper
        widest = max(self.grippers, key=lambda g_: g_.max_width)
        widths = [grasp_quality(full, g, gripper=widest, tree=tree, pad_reach=self.pad_reach,
                                table_z=self.table_z).width
                  for (full, tree), gs in zip(fulls, per_fit) for g in gs]
        # a rectangular tin or box is taken across its short side: that side's width chooses the gripper
        gripper = only or choose_gripper([float(shape.extents[1])] if self.shape_weight and shape.kind == "box"
                                         else widths, self.grippers)
        best, bi = self._search(fulls, per_fit, cloud, gripper, parts, shape, avoid)
        fallback = False
        if not best.feasible and gripper != widest and only is None:
            wide, wi = self._search(fulls, per_fit, cloud, widest, parts, shape, avoid)
            if wide.feasible:
                best, bi, gripper, fallback = wide, wi, widest, True
        t3 = time.perf_counter()
        h = (hold(best.grasp, best.detail.contacts, fulls[bi][0], parts[bi], gripper, shake=self.shake,
                  base=self.base_pose[:2, 3])
             if best.detail is not None and np.all(np.isfinite(best.detail.contacts)) else None)
        return GraspPlan(cls, grasps, best, {"classify_register": t1 - t0, "transfer": t2 - t1,
                                             "score_search": t3 - t2, "total": t3 - t0},
                         gripper, [float(w) for w in widths], fallback, h, parts[bi], shape)

    def _part(self, template: Template, warped: np.ndarray) -> PartEstimate:
        """The part's mass and centre of mass from ``template`` warped onto it (see :func:`estimate_part`)."""
        vol: float | None = None
        if template.mass is not None:
            if template.name not in self._volumes:
                self._volumes[template.name] = hull_volume(template.points)
            vol = self._volumes[template.name] or None
        return estimate_part(warped, mass=template.mass, template_volume=vol)

    def _search(self, fulls: Sequence[tuple[np.ndarray, cKDTree]], per_fit: Sequence[Sequence[Grasp]],
                cloud: np.ndarray, gripper: ParallelGripper, parts: Sequence[PartEstimate],
                shape: ShapeClass | None = None, avoid: Sequence[Grasp] = ()) -> tuple[SearchResult, int]:
        """Refine and search (6.21) the transferred grasps with ``gripper``; the lowest cost wins.

        Each fit's grasps are refined (:func:`refine_position`) and searched on that fit's completed
        cloud, the IK with the robot carrying ``gripper``; each candidate's cost then gains the hold
        shortfall (``hold_weight``), the shape class's cost (``shape_weight``), the centroid and tilt
        terms and :data:`AVOID_COST` near a failed
        grasp; with ``check_between`` a candidate whose width is outside the gripper's range or whose
        jaws would not have perceived points between them is infeasible (cost + :data:`PENALTY`).
        Returns the best result and the index of its fit.
        """
        robot = self.robot_for(gripper)
        best: SearchResult | None = None
        bi = 0
        centroid = cloud.mean(axis=0)
        # contacts on perceived points only (off by default, see ``seen_contacts``)
        seen = cKDTree(cloud) if self.seen_contacts else None
        cos_avoid = np.cos(np.radians(30.0))
        for fi, ((full, tree), gs) in enumerate(zip(fulls, per_fit)):
            cands: list[Grasp] = []
            for g in gs:
                cands += (refine_position(g, full, gripper=gripper, tree=tree, table_z=self.table_z,
                                          observed=cloud, edge_normals=self.edge_normals,
                                          pad_reach=self.pad_reach, rest_height=self.rest_height,
                                          toward=centroid, com_weight=self.com_weight)
                          if self.refine else [g])
            if self.shape_weight and shape is not None:  # the grasps the shape class's rule asks for
                cands += shape_grasps(shape, cloud, gripper, table_z=self.table_z, com=parts[fi].com)
            for g in cands:
                r = orientation_search(g, full, robot, gripper=gripper, table_z=self.table_z,
                                       base_pose=self.base_pose, q_ref=self.q_ref, tree=tree, observed=seen,
                                       edge_normals=self.edge_normals, pad_reach=self.pad_reach)
                extra = 0.0
                if self.com_weight:
                    extra += self.com_weight * float(np.linalg.norm(r.grasp.centre[:2] - centroid[:2]))
                if self.tilt_weight:
                    extra += self.tilt_weight * closing_tilt(r.grasp)
                gq = r.detail
                if self.hold_weight and gq is not None and r.quality > 0:
                    h = hold(r.grasp, gq.contacts, full, parts[fi], gripper, shake=self.shake,
                             base=self.base_pose[:2, 3])
                    extra += self.hold_weight * h.cost()
                if self.shape_weight and shape is not None:
                    extra += self.shape_weight * shape_cost(r.grasp, shape, com=parts[fi].com, observed=cloud)
                if any(np.linalg.norm(r.grasp.centre - a.centre) < 0.01 and abs(r.grasp.axis @ a.axis) > cos_avoid
                       for a in avoid):
                    extra += AVOID_COST
                feasible = r.feasible
                if self.check_between and feasible:
                    if (gq is not None and gq.width > gripper.grip_range[1]) or \
                            not between_jaws(r.grasp, cloud, gripper).ok:
                        feasible, extra = False, extra + PENALTY
                if extra or feasible != r.feasible:
                    r = replace(r, cost=r.cost + extra, feasible=feasible)
                if best is None or r.cost < best.cost:
                    best, bi = r, fi
        if best is None:
            raise InvalidInput("the template has no taught grasps to transfer", value=len(per_fit))
        return best, bi


def closing_tilt(grasp: Grasp) -> float:
    """The elevation (rad, 0..pi/2) of ``grasp``'s closing axis (:attr:`Grasp.axis`) from the horizontal."""
    return float(np.arcsin(min(1.0, abs(float(grasp.axis[2])))))


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
