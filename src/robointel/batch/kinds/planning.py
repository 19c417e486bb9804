"""One FRMP planning problem (Ch. 7) as a batch task.

Params: ``scene`` [table71]: a built-in scene name or a scene YAML path. FRMP is deterministic;
the seed only numbers repetitions. Success: the dense check finds positive clearance and no limit
violation.
"""

from __future__ import annotations

import time
from dataclasses import replace

from robointel.batch.kinds.params import param
from robointel.batch.registry import TrialKind
from robointel.batch.spec import TaskSpec
from robointel.outcome import TrialOutcome
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
    return replace(res.outcome, timings={"trial_s": time.perf_counter() - t0})


KIND = TrialKind("planning", planning, lambda s: str(s.params.get("scene", "table71")),
                 "one FRMP planning problem (Ch. 7)")
