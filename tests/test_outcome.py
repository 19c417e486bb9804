"""The one trial outcome: its invariants, its record round trip, and the planners' dense-check reason."""
from __future__ import annotations

import pytest

from robointel.outcome import Failure, TrialOutcome
from robointel.planning.motion_check import DenseCheck


def test_success_and_reason_agree():
    with pytest.raises(ValueError, match="Failure.NONE"):
        TrialOutcome(True, Failure.COLLISION)
    with pytest.raises(ValueError, match="other than NONE"):
        TrialOutcome(False)


def test_record_round_trip():
    out = TrialOutcome(False, Failure.SLIP, "slipped in the lift", {"lift_m": 0.05}, {"trial_s": 1.5})
    rec = out.to_record()
    assert rec["reason"] == "slip" and TrialOutcome.from_record(rec) == out


@pytest.mark.parametrize(("kind", "failure"), [("collision", Failure.COLLISION), ("limit", Failure.LIMIT),
                                               ("", Failure.NONE)])
def test_dense_check_names_its_failure(kind, failure):
    assert DenseCheck(kind == "", "", kind, 0.01, 100).failure is failure
