"""The insertion trial as a batch task: a thin adapter over :mod:`robointel.learning.insertion`.

All knowledge of the insertion package is in this file. Params (defaults in brackets): ``controller``
[impedance] (``impedance``: torque-level Cartesian impedance, :meth:`RobotCell.insert`; ``position``:
the stiff joint servo along the tool axis, :meth:`RobotCell.insert_position_only`), ``policy``
[constant_push] (``constant_push``: :class:`ConstantPush`; ``hand_tuned``: :class:`HandTunedAdmittance`;
``skill``: the GMR skill learned from ``demos`` [20] seeded demonstrations, ``labelled`` [10] of them
labelled, demonstration seed ``demo_seed`` [0]; ``felt_skill``: the feel-align-insert strategy with
the rotation learned (:class:`FeltSkill`) from ``felt_demos`` [10] demonstrations of seed
``demo_seed``), ``gains`` [{}] (:class:`ImpedanceGains` fields),
``interference`` [0] (m), ``time_limit`` [10] (s), ``lateral`` [0.002] (m) and ``max_tilt_deg`` [5]:
the start error is drawn from the task seed by :func:`random_start_errors`. With ``start_seed`` the
start is instead the ``seed``-th of ``random_start_errors(default_rng(start_seed), seed + 1)``: the
start list of ``benchmarks/rltt.py`` (one generator for all trials), with the sensor noise seeded by
``seed`` as there.
"""

from __future__ import annotations

import time
from functools import lru_cache

import numpy as np

from robointel.batch.registry import TrialKind
from robointel.batch.spec import TaskSpec
from robointel.errors import InvalidInput
from robointel.learning.demonstration import Demonstration
from robointel.learning.insertion import (
    ConstantPush,
    FeltSkill,
    HandTunedAdmittance,
    HDDScene,
    ImpedanceGains,
    PegHole,
    Policy,
    RobotCell,
    demonstrate,
    demonstrate_felt,
    random_start_errors,
)
from robointel.learning.rltt import LearnedInsertion, learn_insertion
from robointel.outcome import TrialOutcome

__all__ = ["felt_skill", "insertion_category", "insertion_trial", "learned_skill"]

CONTROLLERS = ("impedance", "position")
POLICIES = ("constant_push", "hand_tuned", "skill", "felt_skill")


@lru_cache(maxsize=4)
def _cell(interference: float) -> RobotCell:
    """The LR Mate with the HDD tool over the hole (built once per process; each run resets it)."""
    return RobotCell(PegHole(), interference=interference)


_LEARNED: dict[tuple[int, int, int], tuple[list[Demonstration], LearnedInsertion]] = {}


def learned_skill(demos: int, labelled: int, demo_seed: int, *,
                  rng: np.random.Generator | None = None) -> tuple[list[Demonstration], LearnedInsertion]:
    """The demonstrations and the skill learned from them, made once per process for these arguments.

    The benchmark calls this too, so its figures and the batch trials share one skill.

    Args:
        demos: Number of demonstrations by the scripted person.
        labelled: How many of the first ones carry hand labels.
        demo_seed: Seed of the demonstrations' generator.
        rng: The generator to draw them from (default ``default_rng(demo_seed)``); a caller that goes on
            drawing from it passes a fresh ``default_rng(demo_seed)`` (used only when nothing is cached yet).

    Returns:
        The demonstrations and the learned insertion (skill, segmenter, timings).
    """
    key = (demos, labelled, demo_seed)
    if key not in _LEARNED:
        task = PegHole()
        gen = rng if rng is not None else np.random.default_rng(demo_seed)
        scene = HDDScene(task)
        ds = [demonstrate(task, gen, scene=scene, name=f"demo_{i:02d}") for i in range(demos)]
        _LEARNED.clear()  # one skill per process at a time
        _LEARNED[key] = ds, learn_insertion(ds, n_labelled=labelled, centre=scene.tool.tip - scene.tool.radius)
    return _LEARNED[key]


_FELT: dict[tuple[int, int], tuple[list[Demonstration], FeltSkill]] = {}


def felt_skill(demos: int, demo_seed: int) -> tuple[list[Demonstration], FeltSkill]:
    """The felt-strategy demonstrations and the skill learned from them, made once per process.

    Args:
        demos: Number of demonstrations by the scripted person (:func:`demonstrate_felt`).
        demo_seed: Seed of their generator.

    Returns:
        The demonstrations and the fitted :class:`FeltSkill`.
    """
    key = (demos, demo_seed)
    if key not in _FELT:
        task = PegHole()
        gen = np.random.default_rng(demo_seed)
        scene = HDDScene(task)
        ds = [demonstrate_felt(task, gen, scene=scene, name=f"felt_{i:02d}") for i in range(demos)]
        _FELT.clear()
        _FELT[key] = ds, FeltSkill().fit(ds)
    return _FELT[key]


def _skill(demos: int, labelled: int, demo_seed: int) -> Policy:
    """The learned skill's policy (wrench -> tool twist)."""
    return learned_skill(demos, labelled, demo_seed)[1].skill.policy()


def insertion_category(spec: TaskSpec) -> str:
    """The report group of an insertion spec: ``controller/policy``."""
    return f"{spec.params.get('controller', 'impedance')}/{spec.params.get('policy', 'constant_push')}"


def insertion_trial(spec: TaskSpec) -> TrialOutcome:
    """Run one peg-in-hole insertion from a start error drawn from ``spec.seed``.

    Args:
        spec: An ``insertion`` task spec (params in the module docstring).

    Returns:
        The trial's :class:`TrialOutcome` (success when the peg is seated without excessive wall
        penetration); figures ``time_s``, ``max_force_n``, ``max_penetration_m``, ``depth_error_m``,
        ``tilt_rad``, ``lateral_m``.

    Raises:
        InvalidInput: unknown controller or policy, or impedance gains on the position controller.
    """
    p = spec.params
    controller, policy = str(p.get("controller", "impedance")), str(p.get("policy", "constant_push"))
    if controller not in CONTROLLERS:
        raise InvalidInput(f"insertion: controller must be one of {CONTROLLERS}, got {controller!r}", value=controller)
    if policy not in POLICIES:
        raise InvalidInput(f"insertion: policy must be one of {POLICIES}, got {policy!r}", value=policy)
    gains = dict(p.get("gains") or {})
    if gains and controller != "impedance":
        raise InvalidInput("insertion: gains apply to the impedance controller only", value=gains)
    t0 = time.perf_counter()
    cell = _cell(float(p.get("interference", 0.0)))
    pol: Policy
    if policy == "skill":
        pol = _skill(int(p.get("demos", 20)), int(p.get("labelled", 10)), int(p.get("demo_seed", 0)))
    elif policy == "felt_skill":
        pol = felt_skill(int(p.get("felt_demos", 10)), int(p.get("demo_seed", 0)))[1].policy(
            cell.tool.tip - cell.tool.radius)
    elif policy == "hand_tuned":
        pol = HandTunedAdmittance(centre=cell.tool.tip - cell.tool.radius)
    else:
        pol = ConstantPush()
    bounds = {"lateral": float(p.get("lateral", 2e-3)), "max_tilt": np.radians(float(p.get("max_tilt_deg", 5.0)))}
    if "start_seed" in p:
        rng = np.random.default_rng(int(p["start_seed"]))
        lateral, tilt = random_start_errors(rng, spec.seed + 1, **bounds)[spec.seed]
    else:
        lateral, tilt = random_start_errors(np.random.default_rng(spec.seed), 1, **bounds)[0]
    T0 = cell.start_pose(lateral, tilt)
    t1 = time.perf_counter()
    limit = float(p.get("time_limit", 10.0))
    if controller == "impedance":
        r = cell.insert(pol, T0, seed=spec.seed, gains=ImpedanceGains(**gains), time_limit=limit)
    else:
        r = cell.insert_position_only(T0, seed=spec.seed, time_limit=limit)
    figures = {**r.outcome.figures, "time_s": float(r.time), "max_force_n": float(r.max_force),
               "max_penetration_m": float(r.max_penetration), "depth_error_m": float(r.depth_error),
               "tilt_rad": float(tilt[1]), "lateral_m": float(np.linalg.norm(lateral))}
    timings = {"setup_s": t1 - t0, "trial_s": time.perf_counter() - t1}
    return TrialOutcome(r.outcome.success, r.outcome.reason, r.outcome.detail, figures, timings)


KIND = TrialKind("insertion", insertion_trial, insertion_category, "peg-in-hole insertion with the LR Mate (Ch. 5)",
                 cost=lambda s: 1.5)  # 1-2 s on an idle core
