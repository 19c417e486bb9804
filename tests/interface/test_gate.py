"""The safety gate's per-target path in plain floats decides exactly as its numpy checks do."""
import numpy as np
import pytest

from robointel.errors import UnsafeCommand
from robointel.interface import SafetyGate

LOWER, UPPER = np.array([-2.9, -1.7, -1.2, -3.3, -2.1, -6.2]), np.array([2.9, 2.5, 3.7, 3.3, 2.1, 6.2])
VMAX = np.array([6.4, 5.4, 7.1, 9.6, 9.5, 17.4])


def _numpy_only(gate: SafetyGate, q, prev):
    """The gate with its plain-float path switched off (every target through the numpy checks)."""
    gate._bounds = None
    try:
        return gate.check(q, prev)
    finally:
        gate._bounds = SafetyGate(gate.joint_names, gate.lower, gate.upper, gate.velocity_limit, gate.period)._bounds


def _outcome(fn):
    try:
        return ("ok", fn())
    except UnsafeCommand as exc:
        return ("refused", str(exc))


def test_the_fast_path_accepts_and_refuses_as_the_numpy_checks():
    gate = SafetyGate([f"j{i}" for i in range(6)], LOWER, UPPER, VMAX, 0.008)
    rng = np.random.default_rng(24)
    prev_pool = rng.uniform(LOWER, UPPER, size=(400, 6))
    cases = []
    for prev in prev_pool:
        step = rng.normal(0, 1, 6) * gate.max_step * rng.choice([0.3, 0.9, 1.01, 2.0])
        q = prev + step
        cases.append((q, prev))
        cases.append((q.tolist(), prev))  # a list target
        cases.append((tuple(q), None))  # no previous command: limits only
        bad = q.copy()
        bad[rng.integers(6)] = rng.choice([np.nan, np.inf, -np.inf, 10.0, -10.0])
        cases.append((bad, prev))
        edge = prev.copy()
        j = rng.integers(6)
        edge[j] = prev[j] + gate.max_step[j] * rng.choice([1.0, -1.0])  # exactly one step away
        cases.append((edge, prev))
    cases += [(UPPER.copy(), UPPER.copy()), (LOWER.copy(), None), (np.zeros(5), None), (np.zeros((6, 1)), None),
              ([[0.0] * 6], None), (["0.1"] * 6, None), (np.zeros(6, dtype=int), np.zeros(6)),
              (np.zeros(6), np.full(6, np.nan)), ("abcdef", None), (np.float64(0.1), None),
              (np.array(0.1), None)]
    accepted = refused = 0
    for q, prev in cases:
        fast = _outcome(lambda q=q, prev=prev: gate.check(q, prev))
        slow = _outcome(lambda q=q, prev=prev: _numpy_only(gate, q, prev))
        assert fast[0] == slow[0], (q, prev, fast, slow)
        if fast[0] == "ok":
            accepted += 1
            assert isinstance(fast[1], np.ndarray) and fast[1].dtype == np.float64 and fast[1].shape == (6,)
            np.testing.assert_array_equal(fast[1], slow[1])
            if isinstance(q, np.ndarray):
                assert fast[1] is not q  # a fresh array
        else:
            refused += 1
            assert fast[1] == slow[1]  # the same refusal, worded the same
    assert accepted > 500 and refused > 500  # both outcomes well covered


def test_a_gate_with_an_unbounded_joint_keeps_the_numpy_checks():
    gate = SafetyGate(["a", "b"], [-np.inf, -1.0], [np.inf, 1.0], [1.0, 1.0], 0.008)
    assert gate._bounds is None
    with pytest.raises(UnsafeCommand, match="NaN or inf"):
        gate.check([np.inf, 0.0], None)
    np.testing.assert_array_equal(gate.check([5.0, 0.5], None), [5.0, 0.5])
