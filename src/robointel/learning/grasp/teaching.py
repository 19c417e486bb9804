"""The taught set of the YCB grasp trials (Table 6.2): objects by category, templates and their grasps.

One template per category is taught: the first instance on which at least 3 distinct top-down grasps
can be sampled with the 48 mm gripper (the toy arms: the first, with the hand-written grasps), its
grasps those of :func:`robointel.learning.grasp.objects.sampled_grasps` with the 48 mm gripper, else
with the 85 mm one (cans, boxes and balls wider than 48 mm), else the hand-written
:func:`robointel.learning.grasp.objects.taught_grasps`. The other instances are the held-out targets.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

from robointel.learning.grasp.classify import Template
from robointel.learning.grasp.objects import (
    ObjectModel,
    sample_points,
    sampled_grasps,
    taught_grasps,
    top_down_grasps,
    toy_arm,
    ycb_objects,
)
from robointel.learning.grasp.pipeline import perceived_template
from robointel.learning.grasp.quality import NARROW_GRIPPER, WIDE_GRIPPER, ParallelGripper
from robointel.learning.grasp.transfer import Grasp

__all__ = ["TeachingSet", "classifying_templates", "holdable", "seen_template", "ycb_teaching_set"]

#: Objects by category (each list's first object is the category's template) and the templates, in the
#: categories' order.
TeachingSet = tuple[dict[str, list[ObjectModel]], list[Template]]


@lru_cache(maxsize=2)
def ycb_teaching_set(toy_arms: int = 6, template_points: int = 800) -> TeachingSet:
    """The YCB objects and toy arms by category, each category's template first and taught.

    The objects of :data:`robointel.learning.grasp.objects.YCB_CATEGORIES` plus ``toy_arms`` toy UR5
    arms. Cached per process (the same lists and templates on every call: do not modify them).

    Args:
        toy_arms: Toy UR5 arms in the ``toy_arm`` category (random poses, seeds 100, 101, ...).
        template_points: Points sampled on each template's surface (object frame).

    Returns:
        ``(objects, templates)``: objects by category (template first), one template per category.

    Raises:
        DataMissing: the YCB scans or ``example-robot-data`` are missing.
    """
    objs = ycb_objects()
    objs["toy_arm"] = [toy_arm(robot="ur5", rng=100 + i, name=f"toy_ur5_{i}") for i in range(toy_arms)]
    templates = []
    for cat, lst in objs.items():
        # the medium clamp fits the 48 mm gripper at one place only: the large clamp teaches the clamps
        i = next((j for j, o in enumerate(lst) if cat == "toy_arm" or len(sampled_grasps(o)) >= 3), 0)
        lst.insert(0, lst.pop(i))
        o = lst[0]
        grasps = (sampled_grasps(o) or sampled_grasps(o, gripper=WIDE_GRIPPER)) if cat != "toy_arm" else []
        templates.append(Template(o.name, cat, sample_points(o, template_points, 0), grasps or taught_grasps(o),
                                  o.mass))
    return objs, templates


def classifying_templates(objs: dict[str, list[ObjectModel]], templates: Sequence[Template],
                          per_category: int = 1, template_points: int = 800) -> list[Template]:
    """The K templates of (6.17)-(6.19): per category the taught template, then the next instances.

    Args:
        objs: Objects by category, template first (from :func:`ycb_teaching_set`).
        templates: The taught templates, one per category in ``objs``' order.
        per_category: Classifying instances per category (0: every instance, leave-one-out nearest
            template; the planner excludes a target's own instance by name).
        template_points: Points sampled on each added instance.

    Returns:
        The classifying templates; the added ones carry no grasps (the category's taught ones transfer).
    """
    out: list[Template] = []
    for t, (cat, lst) in zip(templates, objs.items()):
        out.append(t)
        more = lst[1:] if per_category <= 0 else lst[1:per_category]
        out += [Template(o.name, cat, sample_points(o, template_points, 0), [], o.mass) for o in more]
    return out


def holdable(obj: ObjectModel, grippers: Sequence[ParallelGripper] = (NARROW_GRIPPER, WIDE_GRIPPER)) -> bool:
    """Whether one of ``grippers`` can hold ``obj`` from above at all.

    Args:
        obj: The object (its full model).
        grippers: The candidate grippers.

    Returns:
        True when :func:`robointel.learning.grasp.objects.top_down_grasps` finds a positive-quality (6.20),
        collision-free top-down grasp on the model for one of them (the same test as a non-empty
        :func:`robointel.learning.grasp.objects.sampled_grasps`, stopped at the first grasp found).
    """
    return any(next(top_down_grasps(obj, gripper=g), None) is not None for g in grippers)


def seen_template(obj: ObjectModel, grasps: Sequence[Grasp] | None = None, *, rng: int = 0) -> Template:
    """A template taught as the cameras see its object: the points of :func:`perceived_template`.

    Classification (6.17)-(6.19) compares the template with a perceived target: the cameras see the
    top and the near sides of an object, never its underside or the far sides of a narrow opening.
    A template sampled on the whole model carries those unseen parts, which no target point matches;
    with one generated template per category a cup's template (inner and outer wall, both sides of
    the bottom) then scored worse on a perceived cup than the can's.

    Args:
        obj: The teaching object (object frame).
        grasps: Its taught grasps (default :func:`robointel.learning.grasp.objects.taught_grasps`).
        rng: Seed of the cameras' noise at teach time.

    Returns:
        The template (object frame).

    Raises:
        InvalidInput: the cameras do not see the object.
    """
    return Template(obj.name, obj.category, perceived_template(obj, rng=rng),
                    list(grasps) if grasps is not None else taught_grasps(obj), obj.mass)
