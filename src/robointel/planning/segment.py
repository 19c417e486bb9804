"""The CFS segment problem (7.1)-(7.3): settings, result, straight reference and clearances.

The solver is :class:`robointel.planning.waypoints.TrajectoryPlanner`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from robointel.errors import InvalidInput
from robointel.geometry import sphere_distances_batch

if TYPE_CHECKING:  # pragma: no cover
    from robointel.geometry.distance import SphereDistances
    from robointel.robot import Robot

__all__ = ["PlannerSettings", "SegmentPlan", "sphere_clearances", "straight_reference"]


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

    def __post_init__(self) -> None:
        for name in ("d_min", "safety", "margin", "w1", "w2", "eps"):
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
        feasible: every sample clear of every obstacle by ``d_min``.
        min_distance: smallest sphere/obstacle distance over the samples (m).
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
