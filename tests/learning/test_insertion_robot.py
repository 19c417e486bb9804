"""The LR Mate insertion cell: the torque-level impedance, the policies, the position-only baseline."""
import numpy as np
import pytest

from robointel.learning import insertion as I
from robointel.outcome import Failure


@pytest.fixture(scope="module")
def cell():
    return I.RobotCell(I.PegHole())


def test_policies_are_the_documented_maps():
    w = np.array([1.0, -2.0, -5.0, 0.1, -0.2, 0.0])
    np.testing.assert_allclose(I.ConstantPush(0.005)(w), [0, 0, 0.005, 0, 0])
    a = I.HandTunedAdmittance(k_force=1e-3, k_torque=0.5, speed=0.01, f_slow=10.0)
    np.testing.assert_allclose(a(w), [1e-3, -2e-3, 0.005, 0.05, -0.1])
    c = I.HandTunedAdmittance(k_force=0.0, k_torque=1.0, centre=0.1)
    np.testing.assert_allclose(c(w)[3:], [0.1 + 0.1 * -2.0, -0.2 - 0.1 * 1.0])  # torque about the centre


def test_impedance_holds_the_start_pose_under_gravity(cell):
    T0 = cell.start_pose(np.zeros(2), (0.0, 0.0))
    r = cell.insert(I.ConstantPush(0.0), T0, time_limit=0.3)
    assert r.outcome.reason is Failure.TIMEOUT
    assert np.linalg.norm(r.tip[-1] - r.tip[0]) < 1e-3 and r.max_force < 1.0


def test_start_pose_errors(cell):
    T = cell.start_pose(np.array([2e-3, -1e-3]), (0.3, np.radians(5.0)))
    assert np.isclose(np.degrees(np.arccos(-T[2, 2])), 5.0)
    tip = I.tip_point(T, cell.tool)
    np.testing.assert_allclose(tip[:2] - np.array(cell.task.top[:2]), [2e-3, -1e-3], atol=1e-12)


def test_position_only_baseline_jams_a_tilted_peg(cell):
    T0 = cell.start_pose(np.array([5e-4, -6e-4]), (1.0, np.radians(2.5)))
    r = cell.insert_position_only(T0, seed=3, time_limit=4.0)
    assert not r.success and r.outcome.reason in (Failure.FORCE_LIMIT, Failure.TIMEOUT, Failure.WEDGED)


def test_an_aligned_peg_seats_from_a_2mm_lateral_error(cell):
    # the contact model does not jam what a real 20 um fit takes: no tilt, 2 mm off, constant push
    r = cell.insert(I.ConstantPush(), cell.start_pose([2e-3, 0.0], (0.0, 0.0)), seed=0, time_limit=8.0)
    assert r.success, r.reason
    assert r.max_penetration < 0.5 * cell.task.clearance
