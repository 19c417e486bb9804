"""The CFS segment problem (7.1)-(7.3): settings, result, straight reference and clearances.

The solver is :class:`robointel.planning.waypoints.TrajectoryPlanner`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from robointel.errors import CollisionAtStart, InvalidInput
from robointel.geometry import sphere_distances_batch
from robointel.planning._self_kernels import pair_clearances, pair_distances

if TYPE_CHECKING:  # pragma: no cover
    from robointel.geometry.distance import SphereDistances
    from robointel.robot import Robot

__all__ = ["Clearances", "PlannerSettings", "SegmentPlan", "all_clearances", "check_self_clear", "self_clearances",
           "sphere_clearances", "straight_reference"]


@dataclass
class PlannerSettings:
    """Weights and tolerances of :class:`TrajectoryPlanner`.

    Attributes:
        d_min: required clearance between robot spheres and obstacles (m).
        safety: extra clearance planned for on top of ``d_min`` (m), absorbing the interpolation
            between samples.
        margin: sphere/obstacle pairs farther than ``d_min + margin`` are not constrained (m).
        slots: constraint rows per sample (the closest pairs within the margin).
        substeps: extra samples on each interval between knots.
        w1, w2: weights of reference tracking and acceleration (7.1).
        Q, R: diagonal joint weights (n,) of the two terms (default ones).
        eps: CFS stops when ||z(k+1) - z(k)||_inf <= eps (rad) ...
        ftol: ... or when the cost of a feasible iterate fell by less than ``ftol`` (relative).
        max_iter: CFS iteration cap.
        backtracks: step halvings when an iterate leaves the feasible set.
        merit: while the reference is in collision, halve steps that increase the exact-penalty
            merit (cost + elastic * clearance shortfall).
        reach: clearance rows within this distance of active (m) enter the QP's working set at
            once; farther ones are added only if the solution violates them.
        elastic: penalty (per metre) on the clearance slacks used while the reference is still in
            collision (the straight line through an obstacle); zero slack once it is clear.
        self_collision: also keep the robot's self-collision sphere pairs (``robot.spheres.self_pairs``:
            spheres on non-adjacent links) ``self_d_min`` apart, as constraints of the same QP.
        self_d_min: required clearance between the spheres of a self-collision pair (m); 0 is what the
            interface's collision guard accepts (the spheres already cover the links conservatively).
    """

    d_min: float = 0.05
    safety: float = 0.005
    margin: float = 0.15
    slots: int = 8
    substeps: int = 1
    w1: float = 1.0
    w2: float = 0.02
    Q: np.ndarray | None = None
    R: np.ndarray | None = None
    eps: float = 1e-3
    ftol: float = 5e-3
    max_iter: int = 30
    backtracks: int = 4
    elastic: float = 1e2
    reach: float = 0.03
    merit: bool = True
    self_collision: bool = True
    self_d_min: float = 0.0

    def __post_init__(self) -> None:
        for name in ("d_min", "safety", "margin", "w1", "w2", "eps", "self_d_min"):
            v = float(getattr(self, name))
            if not np.isfinite(v) or v < 0:
                raise InvalidInput(f"planner setting {name} must be finite and >= 0, got {v}", value=v)
        if self.w2 <= 0 and self.w1 <= 0:
            raise InvalidInput("w1 and w2 cannot both be zero (the cost must be strictly convex)")
        if int(self.slots) < 1 or int(self.substeps) < 0 or int(self.max_iter) < 1:
            raise InvalidInput("slots >= 1, substeps >= 0 and max_iter >= 1 are required",
                               value=(self.slots, self.substeps, self.max_iter))


@dataclass
class SegmentPlan:
    """One planned segment.

    Attributes:
        path: (N+1, n) joint positions at the knots (rad).
        iterations: CFS iterations.
        costs: cost at the initial guess and after each iteration.
        status: ``"converged"``, ``"max_iter"`` (best feasible iterate returned) or ``"qp_failed"``.
        feasible: every sample clear of every obstacle by ``d_min`` (and of itself by ``self_d_min``).
        min_distance: smallest clearance over the samples (m): a sphere/obstacle distance, or a self pair's
            distance + ``d_min`` - ``self_d_min`` (its clearance counted against the obstacles' requirement).
        seconds: wall time of the CFS loop.
        blocked: the reference (straight) path violated the clearance.
    """

    path: np.ndarray
    iterations: int
    costs: list[float]
    status: str
    feasible: bool
    min_distance: float
    seconds: float
    blocked: bool
    iterates: list[np.ndarray] = field(default_factory=list)


def sphere_clearances(robot: Robot, Q: np.ndarray, obstacles: Any) -> SphereDistances:
    """Signed distances (4.3) between the movable collision spheres and each obstacle, with gradients.

    At configurations Q (B, n): d (B, m', k) and their gradients n^T J (4.4), grad (B, m', k, n), for
    the movable spheres (m',).

    The planner's name for :func:`robointel.geometry.sphere_distances_batch` with
    ``movable_only=True`` (one batched kinematics pass, one compiled distance call); returns its
    :class:`robointel.geometry.SphereDistances`.
    """
    return sphere_distances_batch(robot, Q, tuple(obstacles), movable_only=True)


def straight_reference(start: np.ndarray, goal: np.ndarray, N: int) -> np.ndarray:
    """Joint-space straight line x^r, (N+1, n), from ``start`` to ``goal``."""
    s = np.linspace(0.0, 1.0, N + 1)[:, None]
    return start[None] + s * (goal - start)[None]


@dataclass
class Clearances:
    """Every clearance CFS constrains at B configurations, with its gradient.

    Attributes:
        d: (B, C) clearances (m): the movable spheres' distances to the obstacles (m' x k of them), then each
            self-collision pair's distance shifted by ``d_min - self_d_min`` so that one requirement
            (>= ``d_min``) holds for all.
        grad: (B, C, n) their gradients d d / d q.
        n_obstacle: how many of the C columns are sphere/obstacle distances (the rest are self pairs).
    """

    d: np.ndarray
    grad: np.ndarray
    n_obstacle: int


def self_clearances(robot: Robot, Q: np.ndarray, pairs: np.ndarray | None = None, *,
                    kinematics: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Signed distances between the spheres of each self-collision pair, and their gradients.

    d_ik = ||p_i(q) - p_k(q)|| - r_i - r_k, grad = u^T (J_i - J_k) with u the unit vector from p_k to p_i.

    Args:
        robot: The robot (its ``spheres`` and their ``self_pairs``: spheres on non-adjacent links).
        Q: (B, n) configurations, rad.
        pairs: (P, 2) sphere index pairs (default ``robot.spheres.self_pairs``).
        kinematics: ``robot.spheres.kinematics_batch(Q)`` when the caller has it already.

    Returns:
        d (B, P) in m and grad (B, P, n) in m/rad.
    """
    sm = robot.spheres
    pr = np.asarray(sm.self_pairs if pairs is None else pairs, int).reshape(-1, 2)
    B, n = len(Q), robot.nq
    if not len(pr) or not B:
        return np.zeros((B, 0)), np.zeros((B, 0, n))
    C, J = sm.kinematics_batch(np.asarray(Q, float)) if kinematics is None else kinematics
    d, g = np.empty((B, len(pr))), np.empty((B, len(pr), n))
    pair_clearances(np.ascontiguousarray(C, dtype=float), np.ascontiguousarray(J, dtype=float),
                    np.ascontiguousarray(pr[:, 0]), np.ascontiguousarray(pr[:, 1]),
                    np.ascontiguousarray(sm.radii, dtype=float), d, g)
    return d, g


def all_clearances(robot: Robot, Q: np.ndarray, obstacles: Any, settings: PlannerSettings, *,
                   cull: bool = True) -> Clearances:
    """The obstacle and (with ``settings.self_collision``) self clearances CFS constrains, at Q (B, n).

    The sphere kinematics are computed once for both. A self pair whose (shifted) clearance is at
    least ``d_min + safety + margin`` at every one of the B configurations cannot enter the QP (a
    row is constrained only within ``margin`` of the requirement ``d_min + safety``): such pairs
    are left out, and one column with their smallest clearance per configuration (gradient zero)
    stands for them, so that every minimum over the columns (feasibility, the elastic merit, the
    reported clearance) is the same as with all pairs. ``cull=False`` keeps every pair (a solver that
    needs the same constraints at every call, SLSQP).

    Args:
        robot: The robot.
        Q: (B, n) configurations, rad.
        obstacles: The obstacles.
        settings: ``self_collision``, ``d_min``, ``self_d_min``, ``safety`` and ``margin``.
        cull: leave out the self pairs that cannot enter the QP (see above).

    Returns:
        The :class:`Clearances`.
    """
    B, n = len(Q), robot.nq
    sm = robot.spheres
    kin = None
    if B and settings.self_collision and len(sm.self_pairs) and hasattr(sm, "kinematics_batch"):
        kin = sm.kinematics_batch(np.asarray(Q, float))
    if obstacles:
        D = sphere_distances_batch(robot, Q, tuple(obstacles), movable_only=True, kinematics=kin)
        d, g = D.d.reshape(B, -1), D.grad.reshape(B, -1, n)
    else:
        d, g = np.zeros((B, 0)), np.zeros((B, 0, n))
    k = d.shape[1]
    if kin is not None and cull:
        shift = settings.d_min - settings.self_d_min
        pr = np.asarray(sm.self_pairs, np.int64).reshape(-1, 2)
        C = np.ascontiguousarray(kin[0], dtype=float)
        dall = np.empty((B, len(pr)))
        pair_distances(C, np.ascontiguousarray(pr[:, 0]), np.ascontiguousarray(pr[:, 1]),
                       np.ascontiguousarray(sm.radii, dtype=float), dall)
        dall += shift
        keep = dall.min(axis=0) < settings.d_min + settings.safety + settings.margin
        ds, gs = self_clearances(robot, Q, pr[keep], kinematics=(C, kin[1]))
        ds += shift
        if not keep.all():  # the far pairs: one column of their minimum, never a QP row
            ds = np.concatenate([ds, dall[:, ~keep].min(axis=1, keepdims=True)], axis=1)
            gs = np.concatenate([gs, np.zeros((B, 1, n))], axis=1)
        d = np.concatenate([d, ds], axis=1)
        g = np.concatenate([g, gs], axis=1)
    elif settings.self_collision:
        ds, gs = self_clearances(robot, Q, kinematics=kin)
        d = np.concatenate([d, ds + (settings.d_min - settings.self_d_min)], axis=1)
        g = np.concatenate([g, gs], axis=1)
    return Clearances(d, g, k)


def check_self_clear(robot: Robot, W: np.ndarray, self_d_min: float, names: list[str] | None = None) -> None:
    """Raise if a configuration of W (B, n) has a self-collision pair of spheres closer than ``self_d_min`` (m).

    Raises:
        CollisionAtStart: naming the configuration (``names[i]`` or "waypoint i") and the two links.
    """
    sm = robot.spheres
    if not len(sm.self_pairs):
        return
    ds, _ = self_clearances(robot, np.asarray(W, float))
    for i in range(len(ds)):
        p = int(np.argmin(ds[i]))
        if ds[i, p] < self_d_min:
            label = names[i] if names else f"waypoint {i}"
            la, lb = (sm.links[int(j)] for j in sm.self_pairs[p])
            raise CollisionAtStart(f"{label} is in self-collision: link {la!r} is {ds[i, p] * 1000:.1f} mm from link "
                                   f"{lb!r} (required {self_d_min * 1000:.1f} mm); move the waypoint",
                                   value={"waypoint": i, "link": la, "obstacle": lb, "distance": float(ds[i, p])})
