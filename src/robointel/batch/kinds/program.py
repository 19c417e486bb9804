"""A task program run as a batch task: check, then run on its simulated cell.

Params: ``program`` [pick_place] (a built-in program name or a file); the task seed places the objects
of a program with objects (:class:`robointel.program.GraspCell`) and seeds its sensor noise; a program
without objects runs on the workcell (:class:`robointel.program.SimCell`).
"""

from __future__ import annotations

import time

from robointel.batch.registry import TrialKind
from robointel.batch.spec import TaskSpec
from robointel.outcome import Failure, TrialOutcome
from robointel.program import GraspCell, ProgramRejected, SimCell, check_program, load_program, run_program


def _sim_time(cell: GraspCell | SimCell) -> float:
    """Simulated time of the cell (s)."""
    return float(cell.data.time if isinstance(cell, GraspCell) else cell.workcell.time)


def program_trial(spec: TaskSpec) -> TrialOutcome:
    """Check and run one task program on its simulated cell.

    Returns:
        The run's outcome (the failed step named in ``detail``); figures ``check_ms``, ``cycle_time_s``
        (simulated time from the first step to the end of the run), ``motion_s``
        (planned motion time of the checked steps) and one ``step_<i>_<name>_ok`` per step run; timings
        per step.
    """
    prog = load_program(str(spec.params.get("program", "pick_place")))
    q0 = prog.initial_configuration()
    t0 = time.perf_counter()
    try:
        chk = check_program(prog, q0)
    except ProgramRejected as exc:
        return TrialOutcome(False, Failure.INFEASIBLE, f"refused before moving: {exc}",
                            timings={"check_s": time.perf_counter() - t0})
    cell = GraspCell(prog, q0, seed=spec.seed) if prog.objects else SimCell(prog, q0)
    t_sim0 = _sim_time(cell)
    run = run_program(prog, cell, check=chk)
    out = run.outcome
    figures = dict(out.figures)
    skill_s = sum(r.outcome.figures.get("time_s", 0.0) for r in run.steps if r.kind in ("insert", "grind"))
    figures["cell_time_s"] = _sim_time(cell) - t_sim0
    figures["cycle_time_s"] = figures["cell_time_s"] + skill_s  # the skill stations keep their own clocks
    figures["motion_s"] = float(sum(p.trajectory.duration for p in chk.plans if p.trajectory is not None))
    for r in run.steps:
        figures[f"step_{r.index}_{r.name}_ok"] = float(r.outcome.success)
    timings = {**out.timings, "total_s": time.perf_counter() - t0}
    return TrialOutcome(out.success, out.reason, out.detail, figures, timings)


KIND = TrialKind("program", program_trial, lambda s: str(s.params.get("program", "pick_place")),
                 "a task program checked and run on its simulated cell (robointel.program)")
