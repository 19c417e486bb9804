"""A cheap deterministic trial for tests and overhead measurements.

Params: ``p_success`` [0.7]: success when u < p_success with u ~ U(0, 1) drawn from the seed;
``work_s`` [0]: seconds of CPU work (a busy loop, so it occupies a core like a real trial);
``raise_on`` [[]]: seeds whose trial raises (error rows); ``category`` [synthetic].
"""

from __future__ import annotations

import time

import numpy as np

from robointel.batch.kinds.params import param
from robointel.batch.registry import TrialKind
from robointel.batch.spec import TaskSpec
from robointel.outcome import Failure, TrialOutcome


def synthetic(spec: TaskSpec) -> TrialOutcome:
    """Run the synthetic trial of ``spec``.

    Returns:
        Success when u < ``p_success``; figures ``u`` and ``value`` (a normal draw), both from the seed.

    Raises:
        RuntimeError: the seed is in ``raise_on``.
    """
    p = param(spec, "p_success", 0.7, float)
    work = param(spec, "work_s", 0.0, float)
    if spec.seed in (spec.params.get("raise_on") or []):
        raise RuntimeError(f"synthetic failure requested for seed {spec.seed}")
    t0 = time.perf_counter()
    x = 0.0
    while time.perf_counter() - t0 < work:
        x += float(np.sin(x + 1.0))
    rng = np.random.default_rng(spec.seed)
    u = float(rng.random())
    ok = u < p
    return TrialOutcome(ok, Failure.NONE if ok else Failure.MISSED, f"u = {u:.6f}",
                        {"u": u, "value": float(rng.normal())}, {"trial_s": time.perf_counter() - t0})


KIND = TrialKind("synthetic", synthetic, lambda s: str(s.params.get("category", "synthetic")),
                 "cheap deterministic trial (tests, overhead)", cost=lambda s: float(s.params.get("work_s", 0.0)))
