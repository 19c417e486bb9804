"""The one outcome record of a trial.

Every trial harness (grasp, insertion, grinding, guidance scenario, planning problem, task program) returns a
:class:`TrialOutcome`.

A failure carries a :class:`Failure` reason from one shared enum (never free text alone), so outcomes
of different kinds can be counted, stored (``robointel.batch``) and compared side by side.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Any


class Failure(str, Enum):  # noqa: UP042 - StrEnum would change str() of the values logs and stores hold
    """Why a trial failed (``NONE`` for a success)."""

    NONE = "none"
    COLLISION = "collision"
    SLIP = "slip"
    NO_GRASP = "no_grasp"
    MISSED = "missed"
    WEDGED = "wedged"
    FORCE_LIMIT = "force_limit"
    TIMEOUT = "timeout"
    LIMIT = "limit"
    IK = "ik"
    INFEASIBLE = "infeasible"
    TRACKING = "tracking"
    FAULT = "fault"
    ERROR = "error"


@dataclass(frozen=True)
class TrialOutcome:
    """What one trial produced.

    Attributes:
        success: Whether the trial met its success criterion.
        reason: ``Failure.NONE`` on success, else why it failed.
        detail: A one-line human-readable explanation (e.g. the phase where a part slipped).
        figures: Named scalar results of the trial in SI units (e.g. ``{"time_s": 7.1}``).
        timings: Named wall-clock durations in seconds.
    """

    success: bool
    reason: Failure = Failure.NONE
    detail: str = ""
    figures: dict[str, float] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.success and self.reason is not Failure.NONE:
            raise ValueError(f"a successful trial has reason Failure.NONE, got {self.reason!r}")
        if not self.success and self.reason is Failure.NONE:
            raise ValueError("a failed trial needs a Failure reason other than NONE")

    def to_record(self) -> dict[str, Any]:
        """Return a flat, JSON/Parquet-friendly dict of this outcome."""
        return {
            "success": bool(self.success),
            "reason": self.reason.value,
            "detail": self.detail,
            "figures": {k: float(v) for k, v in self.figures.items()},
            "timings": {k: float(v) for k, v in self.timings.items()},
        }

    @classmethod
    def from_record(cls, record: dict[str, Any]) -> TrialOutcome:
        """Rebuild an outcome from :meth:`to_record` output."""
        return cls(
            success=bool(record["success"]),
            reason=Failure(record["reason"]),
            detail=str(record.get("detail", "")),
            figures=dict(record.get("figures", {})),
            timings=dict(record.get("timings", {})),
        )
