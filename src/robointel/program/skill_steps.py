"""The ``insert`` and ``grind`` steps: a learned skill from a skill file, run through the skill's public API.

``insert`` runs the peg-in-hole skill at the insertion station (the insertion package's
:class:`robointel.learning.insertion.RobotCell`: the LR Mate with the peg tool over the hole, torque-level
impedance; the felt skill feeling the face, turning square with its GMR-learned rotation and pushing in, or the
GMR skill (5.17) mapping the felt wrench to the corrective twist, every 10 ms) over a hole
of the step's fit, from a start pose with the step's pose error budget (drawn from the run's seed).
``grind`` reproduces the grinding skill's force profile along the plate
(:func:`robointel.learning.grinding.reproduce_grinding`). A failed skill (wedged, force limit, time limit,
force off the profile) leaves the arm held still by the joint servo where it stopped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel.learning.grinding import GrindingSkill, reproduce_grinding
from robointel.learning.insertion import (
    FeltSkill,
    InsertionSkill,
    PegHole,
    RobotCell,
    random_start_errors,
    skill_policy,
)
from robointel.outcome import Failure, TrialOutcome

HOLD_S = 0.3  # how long the station's joint servo holds the arm after a skill stopped, s


@dataclass
class SkillResult:
    """What a skill step did.

    Attributes:
        outcome: The step's outcome (the skill's own failure reason when it failed).
        q: (M, n) measured joints of the station's arm (every 10 ms), rad.
        q_stop: (n,) where the arm was held after the skill, rad.
        held_speed: Largest joint speed after the hold, rad/s (the arm stood still when ~0).
    """

    outcome: TrialOutcome
    q: npt.NDArray[np.float64]
    q_stop: npt.NDArray[np.float64]
    held_speed: float


def _hold(station: RobotCell) -> tuple[npt.NDArray[np.float64], float]:
    """Hold the station's arm where it is with the joint servo; return where and the residual speed."""
    q = np.asarray(station.data.qpos[station.qadr], float).copy()
    z = np.zeros(len(q))
    station.controller.reset()
    for _ in range(int(HOLD_S / station.model.opt.timestep)):
        station.servo_step(q, z)
    return q, float(np.max(np.abs(station.data.qvel[station.vadr])))


def run_insert(skill: FeltSkill | InsertionSkill, *, seed: int, time_limit: float = 10.0, clearance: float = 20e-6,
               lateral_error: float = 2e-3, tilt_error: float = np.radians(5.0),
               station: RobotCell | None = None) -> SkillResult:
    """Run the learned insertion skill once at the insertion station.

    The station knows where its hole is (the cell's scene); the start pose error is what the cell's
    calibration and the part's placement leave: a lateral offset uniform in +-``lateral_error`` per axis
    and a tilt uniform in [0, ``tilt_error``] about a random horizontal axis, drawn from ``seed``.

    Args:
        skill: The fitted skill (from a skill file).
        seed: Seed of the start pose error and the sensor noise.
        time_limit: Time the skill gets to seat the peg, s.
        clearance: Diametral clearance of the station's fit (hole minus peg diameter), m, in (0, 2 mm).
        lateral_error: Lateral start error bound per axis, m.
        tilt_error: Tilt start error bound, rad.
        station: The insertion station (default: a new :class:`RobotCell` over a :class:`PegHole` with
            ``clearance``; a given station keeps its own fit).

    Returns:
        The :class:`SkillResult`; success when the peg seated (tip within 1 mm of the bottom, wall
        penetration below half the clearance).

    Raises:
        InvalidInput: ``clearance`` outside (0, 2 mm).
    """
    cell = station if station is not None else RobotCell(PegHole(clearance=clearance))
    lateral, tilt = random_start_errors(np.random.default_rng(seed), 1, lateral=lateral_error, max_tilt=tilt_error)[0]
    policy = skill_policy(skill, cell.tool.tip - cell.tool.radius)
    trial = cell.insert(policy, cell.start_pose(lateral, tilt), time_limit=time_limit, seed=seed)
    q_stop, speed = _hold(cell)
    out = trial.outcome
    figures = {**out.figures, "start_tilt_deg": float(np.degrees(tilt[1])),
               "start_lateral_mm": float(1e3 * np.linalg.norm(lateral)),
               "clearance_um": float(1e6 * cell.task.clearance)}
    detail = out.detail if out.success else f"insertion stopped: {out.detail}"
    outcome = TrialOutcome(out.success, out.reason, detail, figures)
    return SkillResult(outcome, np.zeros((0, len(q_stop))), q_stop, speed)


def run_grind(skill: GrindingSkill, *, seed: int, tolerance: float = 0.15, speed: float = 0.03,
              station: Any = None) -> SkillResult:
    """Reproduce the learned grinding skill along the plate's diagonal.

    Args:
        skill: The fitted skill (from a skill file); its plate is the workpiece.
        seed: Seed of the sensor noise.
        tolerance: Largest RMS of the measured force minus the skill's set-point along the path,
            relative to the peak intended force, for the step to succeed (``rms_rel``, against the
            demonstrator's intended profile, is reported beside it).
        speed: Path speed, m/s.
        station: The grinding station (default: a new :class:`RobotCell` over the skill's plate).

    Returns:
        The :class:`SkillResult`; figures ``rms_rel`` and ``rms_rel_setpoint``.
    """
    cell = station if station is not None else RobotCell(skill.plate, tool=skill.plate.tool())
    res = reproduce_grinding(skill.plate, skill, cell=cell, speed=speed, seed=seed)
    q_stop, held = _hold(cell)
    figures = {"rms_rel": float(res.rms_rel), "rms_rel_setpoint": float(res.rms_rel_setpoint),
               "peak_force_n": float(np.max(res.force)) if len(res.force) else 0.0}
    if not np.all(np.isfinite(res.force)) or res.rms_rel_setpoint > tolerance:
        outcome = TrialOutcome(False, Failure.FORCE_LIMIT, f"the grinding force left the skill's force profile: "
                               f"RMS {res.rms_rel_setpoint:.2f} of the peak > {tolerance}", figures)
    else:
        outcome = TrialOutcome(True, figures=figures)
    return SkillResult(outcome, np.zeros((0, len(q_stop))), q_stop, held)
