"""The settings of :func:`robointel.planning.plan_motion`: everything a user may tune, with defaults."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, kw_only=True)
class MotionSettings:
    """Everything a user may tune; the defaults work on the MotionBenchMaker problems.

    Attributes:
        d_min: required clearance to the environment and between links, m.
        time_budget_s: budget of the call (on ``budget_clock``) after the input checks, s: the search, and the
            shortcut, timing and checks of each attempt (a path whose checks cannot finish within it
            is a failure, ``Failure.TIMEOUT``; the overshoot is one stage step, e.g. one chunk of
            the collision-mesh check).
        seed: seed of the sampler and the shortcutter.
        jerk_limited: time the path with ruckig (rest to rest per straight segment) instead of
            temporal optimization.
        rrt_range: longest RRT edge, rad (Euclidean in joint space); each tree steps shorter while its
            extensions mostly fail (down to 1/2 rad), longer again (up to this) when they succeed.
        rrt_domain: dynamic-domain radius of the RRT (Yershova et al., ICRA 2005), rad: a node whose
            extension has failed is extended afterwards only toward samples within this distance of
            it (samples beyond cost a nearest-neighbour scan, no collision check); inf: every sample.
        resolution: largest sphere-centre travel between two checks of a path edge, m (so the
            edge keeps clearance >= d_min - resolution / 2 between the checked points).
        search_resolution: the same during the tree search (coarser, faster); the found path's
            edges are re-checked at ``resolution`` (the search is repeated finer if one fails).
        smooth: time a spline through knots along the path (no stop at the vertices); when that
            spline fails the dense check (it leaves the checked polyline near a corner), knots 4x
            closer, then time-optimal rest-to-rest motion along the polyline itself (neither when
            the collision meshes fail the polyline itself where they failed the spline: the next
            attempt changes the path).
        timing: how the smooth path is timed: ``"topp"``, time-optimal along the spline
            (:func:`robointel.planning.topp.topp_spline`, knots every ``spline_step``), or
            ``"temporal"``, temporal optimization (7.7)-(7.9) of the knots every ``knot_step``.
        spline_step: largest joint step between the TOPP spline's knots, rad.
        max_nodes: capacity of each RRT tree (full trees are started over within the budget).
        shortcut_iters: random shortcut attempts after the greedy pass.
        knot_step: largest joint step between knots of the time-optimised spline, rad.
        velocity_scale: fraction of the robot's velocity limits to use.
        acceleration_limit: (n,) rad/s^2, or None for ``robot.acceleration_limit``.
        jerk_limit: (n,) rad/s^3, or None for 10 x the acceleration limit.
        check_dt: step of the dense check, s.
        root_relaxed_rad: when the start or a goal is free only in the relaxed (partially grown)
            spheres, an edge leaving it is checked in them for its first ``root_relaxed_rad`` rad
            (max |dq|) and in the mesh-covering spheres beyond.
        fitted_fallback: fraction of ``time_budget_s`` after which a search in the mesh-covering
            spheres that has found no path gives way to a search in the spheres as given, grown
            toward the covering ones as far as the start and every goal stay free (they may leave
            parts of the meshes uncovered, so every sample of that trajectory the covering spheres
            leave in doubt is checked on the collision meshes); the search gives way sooner when
            neither tree has gained a node in its last few thousand iterations (a root walled in by
            the covering spheres), and in the fallback a search that stalls so starts again with the
            spheres grown half as far (down to the spheres as given); 1: never. Not with a point
            cloud (the mesh check measures primitives only).
        budget_clock: the clock ``time_budget_s`` is counted on: ``"wall"`` (what the caller
            waits for) or ``"cpu"``, the process's CPU time (on a machine shared with other busy
            processes the same budget then buys the same work as on an idle one;
            :mod:`robointel.planning.budget_clock`). ``plan_ms`` is wall time either way.
    """

    d_min: float = 0.0
    time_budget_s: float = 1.0
    seed: int = 0
    jerk_limited: bool = False
    rrt_range: float = 1.0
    rrt_domain: float = 4.0
    resolution: float = 0.002
    search_resolution: float = 0.02
    max_nodes: int = 20000
    shortcut_iters: int = 60
    smooth: bool = True
    timing: str = "topp"
    spline_step: float = 0.1
    knot_step: float = 0.2
    velocity_scale: float = 1.0
    acceleration_limit: tuple[float, ...] | None = None
    jerk_limit: tuple[float, ...] | None = None
    check_dt: float = 1e-3
    root_relaxed_rad: float = 0.2
    fitted_fallback: float = 0.3
    budget_clock: str = "wall"
