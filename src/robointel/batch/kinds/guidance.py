"""A guidance scenario (Table 4.1) with the simulated operator as a batch task.

Params: ``scenario`` [1] (1, 2 or 3), ``method`` [qp], ``physics`` [true] (MuJoCo workcell with
the F/T sensor in the loop), ``duration`` [null: the operator's whole path]. The F/T noise is
drawn from the seed. Success: the robot never touched the obstacle.
"""

from __future__ import annotations

import time
from dataclasses import replace

from robointel.batch.kinds.params import param
from robointel.batch.registry import TrialKind
from robointel.batch.spec import TaskSpec
from robointel.outcome import TrialOutcome
from robointel.teach.scenarios import run_scenario

TIMINGS = ("step_us_median", "step_us_p99", "step_cpu_us_median", "step_cpu_us_p99")  # wall clock, not outcome


def guidance(spec: TaskSpec) -> TrialOutcome:
    """Run one guidance scenario.

    Returns:
        Success without obstacle contact or penetration; figures: every ``ScenarioResult.metrics``
        entry except the control-step timings, which go to the timings (with ``trial_s``).

    Raises:
        InvalidInput: unknown scenario number or method.
    """
    t0 = time.perf_counter()
    r = run_scenario(param(spec, "scenario", 1, int), param(spec, "method", "qp", str),
                     duration=param(spec, "duration", None, float), physics=param(spec, "physics", True, bool),
                     seed=spec.seed)
    m = r.metrics()
    figures = {k: float(v) for k, v in m.items() if k not in TIMINGS}
    timings = {k: float(m[k]) for k in TIMINGS if k in m}
    return replace(r.outcome, figures=figures, timings={**timings, "trial_s": time.perf_counter() - t0})

KIND = TrialKind("guidance", guidance, lambda s: f"scenario {s.params.get('scenario', 1)}",
                 "guidance scenario with a simulated operator (Table 4.1)")
