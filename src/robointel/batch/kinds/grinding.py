"""Grinding (Fig. 5.13) as a batch task: demonstrate, learn the GMR force skill, reproduce it.

Params: ``demos`` [1] seeded demonstrations of ``lines`` [4] strokes at ``demo_speed`` [0.1] m/s,
``components`` [6] Gaussians, reproduction ``speed`` [0.05] m/s, ``max_rms_rel`` [0.25]: success
when the RMS force error against the intended profile is at most this fraction of its peak.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from robointel.batch.kinds.params import param
from robointel.batch.registry import TrialKind
from robointel.batch.spec import TaskSpec
from robointel.learning.grinding import GrindingSkill, Plate, demonstrate_grinding, reproduce_grinding
from robointel.learning.insertion import HDDScene
from robointel.outcome import TrialOutcome


def grinding(spec: TaskSpec) -> TrialOutcome:
    """Run one grinding demonstration-learning-reproduction cycle.

    Returns:
        Success when ``rms_rel`` <= ``max_rms_rel``; figures ``rms_rel``, ``rms_rel_setpoint``, ``max_force_n``.
    """
    n = param(spec, "demos", 1, int)
    limit = param(spec, "max_rms_rel", 0.25, float)
    plate = Plate()
    rng = np.random.default_rng(spec.seed)
    t0 = time.perf_counter()
    scene = HDDScene(plate, plate.tool())  # type: ignore[arg-type]  # a Plate builds like a PegHole
    demos = [demonstrate_grinding(plate, rng, scene=scene, lines=param(spec, "lines", 4, int),
                                  speed=param(spec, "demo_speed", 0.1, float)) for _ in range(n)]
    skill = GrindingSkill(plate, param(spec, "components", 6, int)).fit(demos)
    t1 = time.perf_counter()
    res = reproduce_grinding(plate, skill, speed=param(spec, "speed", 0.05, float), seed=spec.seed,
                             max_rms_rel=limit)
    return replace(res.outcome, timings={"learn_s": t1 - t0, "trial_s": time.perf_counter() - t1})


KIND = TrialKind("grinding", grinding, lambda s: "grinding", "learned grinding force reproduction (Fig. 5.13)")
