"""The quintic move to a trajectory's start (robointel.interface.approach) and Backend.move_to on sim."""
import numpy as np
import pytest

from robointel.errors import InvalidInput, UnsafeCommand
from robointel.interface import approach_trajectory, open_robot


def test_quintic_stays_within_the_fraction_of_the_limits_and_rests_at_both_ends():
    v, a = np.array([1.0, 2.0, 3.0]), np.array([3.0, 6.0, 9.0])
    q0, q1 = np.array([0.0, 0.5, -1.0]), np.array([1.0, -0.5, 0.0])
    tr = approach_trajectory(q0, q1, v, a, fraction=0.2, period=0.001)
    np.testing.assert_allclose(tr.q[0], q0, atol=1e-12)
    np.testing.assert_allclose(tr.q[-1], q1, atol=1e-12)
    np.testing.assert_allclose(tr.qd[[0, -1]], 0.0, atol=1e-12)
    assert np.all(np.abs(tr.qd) <= 0.2 * v + 1e-9) and np.all(np.abs(tr.qdd) <= 0.2 * a + 1e-9)
    assert np.max(np.abs(tr.qd) / (0.2 * v)) > 0.95 or np.max(np.abs(tr.qdd) / (0.2 * a)) > 0.95  # not slower
    np.testing.assert_allclose(np.diff(tr.q, axis=0) / 0.001, 0.5 * (tr.qd[1:] + tr.qd[:-1]), atol=1e-3)
    still = approach_trajectory(q0, q0, v, a)
    assert len(still.t) == 2 and np.all(still.q == q0)
    with pytest.raises(InvalidInput):
        approach_trajectory(q0, q1[:2], v, a)
    with pytest.raises(InvalidInput):
        approach_trajectory(q0, q1, v, a, fraction=0.0)
    with pytest.raises(InvalidInput):
        approach_trajectory(q0, [np.nan, 0.0, 0.0], v, a)


def test_move_to_on_sim_reaches_the_goal_and_refuses_one_outside_the_limits():
    q0 = np.array([0.0, 0.2, -0.3, 0.0, -0.8, 0.0])
    with open_robot("sim", q0=q0) as arm:
        goal = q0 + np.array([0.3, -0.1, 0.2, 0.4, 0.2, -0.5])
        res = arm.move_to(goal)
        assert res.completed
        np.testing.assert_allclose(arm.state().q_cmd, goal, atol=1e-12)
        np.testing.assert_allclose(arm.state().q, goal, atol=5e-3)
        with pytest.raises(UnsafeCommand):
            arm.move_to(goal + np.array([10.0, 0, 0, 0, 0, 0]))
