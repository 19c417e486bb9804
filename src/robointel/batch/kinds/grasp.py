"""The lift-and-shake grasp trial (Table 6.2) as a batch task.

Params: ``category`` [cup]; ``source`` [demo] (generated objects with written grasps,
``per_category`` [4] instances each) or ``ycb`` (the YCB scans and toy arms of
:func:`robointel.learning.grasp.ycb_teaching_set`, ``class_templates`` [1] classifying templates per
category); ``instance`` [drawn from the seed]: which held-out instance (an index, taken modulo their
count; with ``ycb`` only the instances one of the grippers can hold from above); ``arm`` [true] (the
whole LR Mate in MuJoCo). The held-out instance is never the category's template; the placement and
the perception noise are drawn from the seed. :func:`robointel.learning.grasp.grasp_trial` perceives,
classifies, transfers, searches, grasps, lifts and shakes.
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
    classifying_templates,
    demo_objects,
    grasp_trial,
    holdable,
    random_placements,
    seen_template,
    ycb_teaching_set,
)
from robointel.outcome import Failure, TrialOutcome


@lru_cache(maxsize=4)
def setup(source: str, per_category: int = 4,
          class_templates: int = 1) -> tuple[dict[str, list[ObjectModel]], GraspPlanner]:
    """The held-out targets by category and the planner of a source, made once per process.

    A driver that forks worker processes calls it before the fork, so the workers share it.

    Args:
        source: "demo" or "ycb" (see the module docstring).
        per_category: Generated instances per category ("demo").
        class_templates: Classifying templates per category ("ycb").

    Returns:
        ``(targets, planner)``: the held-out instances by category and the grasp planner.

    Raises:
        InvalidInput: an unknown source.
    """
    if source == "demo":
        objs = demo_objects(per_category, 0)
        templates = [seen_template(lst[0]) for lst in objs.values()]
        return {cat: lst[1:] or lst for cat, lst in objs.items()}, GraspPlanner(templates)
    if source == "ycb":
        objs, templates = ycb_teaching_set()
        planner = GraspPlanner(templates, classifiers=classifying_templates(objs, templates, class_templates))
        return {cat: [o for o in lst[1:] if holdable(o)] for cat, lst in objs.items()}, planner
    raise InvalidInput(f"grasp: source must be 'demo' or 'ycb', got {source!r}", value=source)


def _failure(reason: str) -> Failure:
    if reason.startswith(("no feasible grasp", "nothing perceived")) or reason == "cloud too small":
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

    Args:
        spec: The task (params above; the seed draws the instance unless ``instance`` is given, the
            placement and the sensor noise).

    Returns:
        Success when the object is still held after the shake; figures ``final_height_m``,
        ``classified_right`` (1 when the planner classified the object into its category),
        ``wide_gripper`` (1 when the plan chose the 85 mm gripper), ``gripper_fallback`` (1 when the
        wide one was taken because the narrow one had no feasible grasp) and ``grip_width_m`` (the
        jaw opening after the last close, NaN when nothing was grasped), ``settle_s`` (simulated time the
        object took to come to rest before the cameras looked) and ``attempts`` (grasp attempts made:
        the hand's checks let go of the others). ``detail``: the object, the gripper, the category it
        was read as when wrong, the trial's reason and why each earlier attempt was let go. Timings:
        ``setup_s``, ``trial_s`` and ``plan_s`` (the planner's classify-register-transfer-score-search
        time, when it ran).

    Raises:
        InvalidInput: unknown source or category, or a category with no holdable instance.
    """
    source = param(spec, "source", "demo", str)
    cat = param(spec, "category", "cup", str)
    t0 = time.perf_counter()
    objs, planner = setup(source, param(spec, "per_category", 4, int), param(spec, "class_templates", 1, int))
    if cat not in objs:
        raise InvalidInput(f"grasp: unknown category {cat!r}; known: {', '.join(objs)}", value=cat)
    held = objs[cat]
    if not held:
        raise InvalidInput(f"grasp: category {cat!r} has no held-out instance a gripper can hold", value=cat)
    rng = np.random.default_rng(spec.seed)
    k = param(spec, "instance", None, int)
    obj = held[(int(rng.integers(len(held))) if k is None else k) % len(held)]
    t1 = time.perf_counter()
    r = grasp_trial(obj, random_placements([obj], rng)[0], planner, rng=rng, arm=param(spec, "arm", True, bool))
    closed = next((s["opening"] for s in reversed(r.log) if s["phase"] == "close"), float("nan"))
    figures = {"final_height_m": float(r.final_height), "classified_right": float(r.category == cat),
               "wide_gripper": float(r.gripper == "wide_85mm"),
               "gripper_fallback": float(r.plan is not None and r.plan.gripper_fallback),
               "grip_width_m": float(closed), "settle_s": float(r.settle_s), "attempts": float(r.attempts)}
    timings = {"setup_s": t1 - t0, "trial_s": time.perf_counter() - t1}
    if r.plan is not None:
        timings["plan_s"] = float(r.plan.timings["total"])
    read = "" if r.category in (None, cat) else f" read as {r.category}"
    detail = f"{obj.name} [{r.gripper or 'none'}]{read}: {r.reason}" + "".join(f"; {w}" for w in r.let_go)
    if r.success:
        return TrialOutcome(True, Failure.NONE, detail, figures, timings)
    return TrialOutcome(False, _failure(r.reason), detail, figures, timings)


KIND = TrialKind("grasp", grasp, lambda s: str(s.params.get("category", "cup")),
                 "lift-and-shake grasp trial (Table 6.2)", cost=lambda s: 10.0)  # 6-17 s on an idle core
