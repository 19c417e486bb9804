"""One FRMP planning problem (Ch. 7) as a batch task.

Params: ``scene`` [table71]: a built-in scene name or a scene YAML path. FRMP is deterministic;
the seed only numbers repetitions. Success: the dense check finds positive clearance and no limit
violation.
"""

from __future__ import annotations

import time

from robointel.batch.kinds.params import param
from robointel.batch.registry import TrialKind
from robointel.batch.spec import TaskSpec
from robointel.outcome import Failure, TrialOutcome
from robointel.planning.frmp import plan_scene
from robointel.planning.scene import load_scene


def planning(spec: TaskSpec) -> TrialOutcome:
    """Plan and check one scene.

    Returns:
        Figures ``min_clearance_m``, ``limit_violations``, ``duration_s`` (cycle time) and ``plan_ms``.

    Raises:
        InvalidInput: the scene cannot be loaded.
        InfeasibleProblem: a waypoint is in collision or a segment is infeasible (an ``infeasible`` row).
    """
    t0 = time.perf_counter()
    res = plan_scene(load_scene(param(spec, "scene", "table71", str)))
    c = res.check
    figures = {"min_clearance_m": float(c.min_clearance), "limit_violations": float(c.limit_violations),
               "duration_s": float(res.trajectory.t[-1] - res.trajectory.t[0]), "plan_ms": float(sum(res.cfs_ms))}
    timings = {"trial_s": time.perf_counter() - t0}
    if c.min_clearance <= 0.0:
        return TrialOutcome(False, Failure.COLLISION, f"clearance {c.min_clearance:.4f} m", figures, timings)
    if c.limit_violations:
        return TrialOutcome(False, Failure.LIMIT, f"{c.limit_violations} limit violations", figures, timings)
    return TrialOutcome(True, Failure.NONE, f"clearance {1000 * c.min_clearance:.1f} mm", figures, timings)


KIND = TrialKind("planning", planning, lambda s: str(s.params.get("scene", "table71")),
                 "one FRMP planning problem (Ch. 7)")
