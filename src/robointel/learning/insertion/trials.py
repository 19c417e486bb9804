"""Insertion trials of a strategy at the robot cell: the learned skills and the baselines, by name.

:func:`learn_felt_skill` has the scripted person demonstrate the feel-align-insert strategy with the hand-held
device and fits the :class:`~robointel.learning.insertion.FeltSkill` on them; :func:`run_trials` runs a
strategy (a fitted skill or a baseline's name, :data:`~robointel.learning.insertion.STRATEGIES`) from random
start errors at a :class:`~robointel.learning.insertion.RobotCell` over a chamferless hole (the learning
benchmark's task by default: 20 um diametral clearance, up to +-2 mm and 5 deg off, no probe). The same starts
and sensor noise as ``benchmarks/rltt.py`` for the same seed: trial ``k`` is the ``k``-th start drawn from
``default_rng(seed)``, its noise seeded by ``k``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from robointel.errors import InvalidInput
from robointel.learning.demonstration import Demonstration
from robointel.learning.insertion.felt_skill import FeltSkill, demonstrate_felt
from robointel.learning.insertion.hdd_scene import HDDScene
from robointel.learning.insertion.peg_hole import PegHole
from robointel.learning.insertion.policies import STRATEGIES, TIME_LIMIT_S, baseline_policy, skill_policy
from robointel.learning.insertion.robot_cell import InsertionTrial, RobotCell, random_start_errors
from robointel.learning.insertion.skill import InsertionSkill

__all__ = ["learn_felt_skill", "run_trials", "strategy_name"]

#: a progress callback: fraction done in [0, 1] and a message
Progress = Callable[[float, str], None]


def learn_felt_skill(demos: int = 10, seed: int = 0, *, progress: Progress | None = None,
                     task: PegHole | None = None) -> tuple[list[Demonstration], FeltSkill]:
    """Demonstrate the feel-align-insert strategy ``demos`` times and learn the felt skill from them.

    Args:
        demos: Number of demonstrations by the scripted person (>= 2: the held-out check folds over them).
        seed: Seed of the demonstrations (the person's variation, start errors, tremor, sensor noise).
        progress: Called with the fraction done and a message before each demonstration.
        task: The peg-hole task of the demonstrations (default :class:`PegHole`, 20 um).

    Returns:
        The demonstrations and the fitted :class:`FeltSkill`.

    Raises:
        InvalidInput: ``demos`` < 2.
    """
    if isinstance(demos, bool) or not isinstance(demos, (int, np.integer)) or demos < 2:
        raise InvalidInput(f"the felt skill needs at least 2 demonstrations, got {demos!r}", value=demos)
    task = task or PegHole()
    step = progress or (lambda frac, msg: None)
    gen = np.random.default_rng(seed)
    scene = HDDScene(task)
    out = []
    for i in range(int(demos)):
        step(i / demos, f"demonstration {i + 1}/{demos}")
        out.append(demonstrate_felt(task, gen, scene=scene, name=f"felt_{i:02d}"))
    step(1.0, "learn the rotation (GMR)")
    return out, FeltSkill(cv_folds=min(3, int(demos))).fit(out)


def strategy_name(strategy: str | FeltSkill | InsertionSkill) -> str:
    """The name (:data:`STRATEGIES`) of a strategy given by name or as a fitted skill.

    Raises:
        InvalidInput: An unknown name or object.
    """
    if isinstance(strategy, FeltSkill):
        return "felt"
    if isinstance(strategy, InsertionSkill):
        return "gmr"
    if isinstance(strategy, str) and strategy in STRATEGIES[2:]:
        return strategy
    raise InvalidInput(f"unknown insertion strategy {strategy!r}: give a fitted skill or one of "
                       f"{', '.join(STRATEGIES[2:])}", value=strategy)


def run_trials(strategy: str | FeltSkill | InsertionSkill, trials: int, *, seed: int = 0, clearance: float = 20e-6,
               time_limit: float | None = None, lateral: float = 2e-3, max_tilt_deg: float = 5.0,
               on_trial: Callable[[int, InsertionTrial | None], None] | None = None,
               cell: RobotCell | None = None) -> list[InsertionTrial]:
    """Run ``trials`` insertions of a strategy from random start errors at the robot cell.

    Args:
        strategy: A fitted :class:`FeltSkill` or :class:`InsertionSkill`, or a baseline's name
            (``constant-push``, ``hand-tuned``, ``position-only``).
        trials: Number of trials (>= 1).
        seed: Seed of the start errors (trial ``k``: the ``k``-th of ``random_start_errors(default_rng(seed))``,
            sensor noise seeded by ``k``).
        clearance: Diametral clearance of the fit (hole minus peg diameter), m, in (0, 2 mm).
        time_limit: Robot time per trial, s (default :data:`TIME_LIMIT_S` of the strategy).
        lateral: Lateral start error bound per axis, m.
        max_tilt_deg: Tilt start error bound, deg.
        on_trial: Called before each trial with its index (and the previous trial, None before the first).
        cell: The robot cell (default: the LR Mate over a :class:`PegHole` of ``clearance``).

    Returns:
        One :class:`InsertionTrial` per start: success when the peg seated (tip within 1 mm of the bottom)
        with the wall penetration below half the clearance, within the time limit.

    Raises:
        InvalidInput: A bad count, clearance, bound, time limit or strategy.
    """
    name = strategy_name(strategy)
    if isinstance(trials, bool) or not isinstance(trials, (int, np.integer)) or trials < 1:
        raise InvalidInput(f"trials must be an integer >= 1, got {trials!r}", value=trials)
    if not (np.isfinite(clearance) and 0 < clearance < 2e-3):
        raise InvalidInput(f"clearance must be in (0, 2 mm), got {clearance!r} m", value=clearance)
    limit = TIME_LIMIT_S[name] if time_limit is None else float(time_limit)
    if not (np.isfinite(limit) and limit > 0):
        raise InvalidInput(f"time limit must be > 0 s, got {time_limit!r}", value=time_limit)
    if not (np.isfinite(lateral) and 0 <= lateral <= 0.01 and np.isfinite(max_tilt_deg) and 0 <= max_tilt_deg <= 10):
        raise InvalidInput(f"start error bounds must be in [0, 10 mm] and [0, 10 deg], got {lateral!r} m, "
                           f"{max_tilt_deg!r} deg", value=(lateral, max_tilt_deg))
    cell = cell if cell is not None else RobotCell(PegHole(clearance=clearance))
    centre = cell.tool.tip - cell.tool.radius
    starts = random_start_errors(np.random.default_rng(seed), int(trials), lateral=lateral,
                                 max_tilt=np.radians(max_tilt_deg))
    out: list[InsertionTrial] = []
    for k, (lat, tilt) in enumerate(starts):
        if on_trial is not None:
            on_trial(k, out[-1] if out else None)
        T0 = cell.start_pose(lat, tilt)
        if name == "position-only":
            out.append(cell.insert_position_only(T0, seed=k, time_limit=limit))
            continue
        policy = (skill_policy(strategy, centre) if isinstance(strategy, (FeltSkill, InsertionSkill))
                  else baseline_policy(name, centre))
        out.append(cell.insert(policy, T0, seed=k, time_limit=limit))
    return out
