"""The lift-and-shake grasp trial (Table 6.2) as a batch task.

Params: ``category`` [cup], ``source`` [demo] (generated objects with written grasps) or ``ycb``
(the YCB scans with sampled grasps), ``per_category`` [4] instances, ``arm`` [true] (the whole
LR Mate in MuJoCo). The held-out instance (never the category's template) and its placement are
drawn from the seed; :func:`robointel.learning.grasp.grasp_trial` perceives, classifies,
transfers, searches, grasps, lifts and shakes.
"""

from __future__ import annotations

import time
from functools import lru_cache

import numpy as np

from robointel.batch.kinds.params import param
from robointel.batch.registry import TrialKind
from robointel.batch.spec import TaskSpec
from robointel.errors import InvalidInput
from robointel.learning.grasp import (
    GraspPlanner,
    ObjectModel,
    Template,
    demo_objects,
    grasp_trial,
    random_placements,
    sample_points,
    sampled_grasps,
    taught_grasps,
    toy_arm,
    ycb_objects,
)
from robointel.outcome import Failure, TrialOutcome


@lru_cache(maxsize=4)
def _setup(source: str, per_category: int) -> tuple[dict[str, list[ObjectModel]], GraspPlanner]:
    """Objects by category (the first is the template) and the planner (once per process)."""
    if source == "demo":
        objs = demo_objects(per_category, 0)
    elif source == "ycb":
        objs = ycb_objects()
        objs["toy_arm"] = [toy_arm(robot="ur5", rng=100 + i, name=f"toy_ur5_{i}") for i in range(per_category)]
    else:
        raise InvalidInput(f"grasp: source must be 'demo' or 'ycb', got {source!r}", value=source)
    templates = []
    for cat, lst in objs.items():
        o = lst[0]
        grasps = sampled_grasps(o) if source == "ycb" and cat != "toy_arm" else []
        templates.append(Template(o.name, cat, sample_points(o, 800, 0), grasps or taught_grasps(o)))
    return objs, GraspPlanner(templates)


def _failure(reason: str) -> Failure:
    if reason.startswith("no feasible grasp") or reason in ("nothing perceived", "cloud too small"):
        return Failure.NO_GRASP
    if reason.startswith("approach or lift unreachable"):
        return Failure.IK
    if "closed on nothing" in reason:
        return Failure.MISSED
    if "slipped" in reason:
        return Failure.SLIP
    return Failure.ERROR


def grasp(spec: TaskSpec) -> TrialOutcome:
    """Run one grasp trial.

    Returns:
        Success when the object is still held after the shake; figures ``final_height_m`` and
        ``classified_right`` (1 when the planner classified the object into its category).

    Raises:
        InvalidInput: unknown source or category.
    """
    source = param(spec, "source", "demo", str)
    cat = param(spec, "category", "cup", str)
    t0 = time.perf_counter()
    objs, planner = _setup(source, param(spec, "per_category", 4, int))
    if cat not in objs:
        raise InvalidInput(f"grasp: unknown category {cat!r}; known: {', '.join(objs)}", value=cat)
    held = objs[cat][1:] or objs[cat]
    rng = np.random.default_rng(spec.seed)
    obj = held[int(rng.integers(len(held)))]
    t1 = time.perf_counter()
    r = grasp_trial(obj, random_placements([obj], rng)[0], planner, rng=rng, arm=param(spec, "arm", True, bool))
    figures = {"final_height_m": float(r.final_height), "classified_right": float(r.category == cat)}
    timings = {"setup_s": t1 - t0, "trial_s": time.perf_counter() - t1}
    detail = f"{obj.name}: {r.reason}"
    if r.success:
        return TrialOutcome(True, Failure.NONE, detail, figures, timings)
    return TrialOutcome(False, _failure(r.reason), detail, figures, timings)


KIND = TrialKind("grasp", grasp, lambda s: str(s.params.get("category", "cup")),
                 "lift-and-shake grasp trial (Table 6.2)")
