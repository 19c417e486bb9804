"""Algorithm settings of temporal optimization (7.7)-(7.9), passed to :func:`temporal_optimize`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from robointel.errors import InvalidInput

__all__ = ["TemporalSettings"]


@dataclass(frozen=True)
class TemporalSettings:
    """How temporal optimization solves (7.7)-(7.9); the defaults are the tuned ones.

    Attributes:
        max_cuts: tangent-cut rounds per CFS iteration for the curved acceleration sets (7.6).
        ridge: ridge on tau (times w3 / tau_max) making the cost strictly convex; it only favours
            shorter steps.
        refine_mode: limit rescaling between refinement rounds: ``"tighten"`` (only where the
            spline exceeds the limits), ``"spread"`` (as tighten, and the knot's neighbours by the
            factor ** ``spread``), ``"sqrt"`` (damped) or ``"both"`` (also relax where there is slack).
        refine_power: exponent of the tightening factor in ``"tighten"`` mode (1: divide by the
            excess ratio).
        spread: exponent on the neighbours' factor in ``"spread"`` mode.
        start: starting schedule of every CFS solve: ``"pass"`` (forward/backward pass,
            :func:`robointel.planning.temporal_start.pass_start`), ``"scaled"`` (velocity-shaped,
            :func:`robointel.planning.temporal_start.scaled_start`) or ``"uniform"``.
        ub_factor: upper bound of every step = this factor x the largest starting step.
        solver: CFS implementation: ``"dedicated"`` (Algorithm 2 written for this problem's
            two-variable constraint rows, :func:`robointel.planning.temporal_cfs.cfs_tau`) or
            ``"general"`` (:func:`robointel.planning.cfs.cfs`); the same iteration.
        local_ub: per-step upper bound = this factor x the start's step (and neighbours);
            0: one bound for all steps.
        working_set: QP working set of the dedicated CFS: rows whose acceleration at the reference
            is at least this fraction of the limit, plus the last active ones; the others enter
            when violated (0: all rows).
        refine_tol: refinement stops once the spline is within this fraction of the limits.
        ftol: CFS also stops when the total time fell by less than this fraction in one iteration
            (0: stop on the step length only).

    Raises:
        InvalidInput: an unknown mode name or a negative number.
    """

    max_cuts: int = 2
    ridge: float = 1e-2
    refine_mode: Literal["tighten", "spread", "sqrt", "both"] = "spread"
    refine_power: float = 1.0
    spread: float = 0.25
    start: Literal["pass", "scaled", "uniform"] = "pass"
    ub_factor: float = 1.5
    solver: Literal["dedicated", "general"] = "dedicated"
    local_ub: float = 0.0
    working_set: float = 0.5
    refine_tol: float = 0.01
    ftol: float = 1e-3

    def __post_init__(self) -> None:
        choices = {"refine_mode": ("tighten", "spread", "sqrt", "both"), "start": ("pass", "scaled", "uniform"),
                   "solver": ("dedicated", "general")}
        for name, allowed in choices.items():
            if getattr(self, name) not in allowed:
                raise InvalidInput(f"{name} must be one of {allowed}, got {getattr(self, name)!r}",
                                   value=getattr(self, name))
        for name in ("max_cuts", "ridge", "refine_power", "spread", "local_ub", "working_set", "refine_tol", "ftol"):
            if not getattr(self, name) >= 0:
                raise InvalidInput(f"{name} must be >= 0, got {getattr(self, name)}", value=getattr(self, name))
        if not self.ub_factor >= 1:
            raise InvalidInput(f"ub_factor must be >= 1, got {self.ub_factor}", value=self.ub_factor)
