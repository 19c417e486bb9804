"""Compliance law (3.10)-(3.13) and the damped pseudo-inverse."""
import numpy as np
import pytest

from robointel.errors import InvalidInput, NotFinite, ShapeError
from robointel.teach.compliance import (
    ComplianceGains,
    compliance_twist,
    compliance_velocity,
    damped_pinv,
    shift_wrench,
    wrench_to_world,
)


def test_twist_is_damping_times_wrench():
    g = ComplianceGains(force_deadband=0.0, torque_deadband=0.0)
    w = np.array([10.0, -5.0, 2.0, 0.3, 0.0, -0.1])
    V = compliance_twist(w, g)
    np.testing.assert_allclose(V[:3], 0.07 * w[:3])
    np.testing.assert_allclose(V[3:], g.rotational * w[3:])
    np.testing.assert_allclose(g.matrix @ w, V)


def test_deadband_is_continuous_and_zero_inside():
    g = ComplianceGains(force_deadband=2.0, torque_deadband=0.2)
    assert np.all(compliance_twist([1.5, 0, 0, 0.1, 0, 0], g) == 0)
    V = compliance_twist([2.0 + 1e-9, 0, 0, 0, 0, 0], g)
    assert np.linalg.norm(V) < 1e-9
    np.testing.assert_allclose(compliance_twist([12.0, 0, 0, 0, 0, 0], g)[:3], [0.07 * 10, 0, 0])


def test_bad_input():
    with pytest.raises(NotFinite):
        compliance_twist([np.nan, 0, 0, 0, 0, 0])
    with pytest.raises(ShapeError):
        compliance_twist([1, 2, 3])
    with pytest.raises(InvalidInput):
        ComplianceGains(translational=-1)


def test_pinv_matches_exact_inverse_away_from_singularity(lrmate):
    q = np.array([0.2, 0.3, -0.2, 0.4, -0.8, 0.3])
    J = lrmate.jacobian(q)
    np.testing.assert_allclose(damped_pinv(J), np.linalg.inv(J), atol=1e-9)


def test_pinv_bounded_at_wrist_singularity(lrmate):
    q = np.array([0.2, 0.3, -0.2, 0.4, 0.0, 0.3])  # J5 = 0: wrist singular
    J = lrmate.jacobian(q)
    assert np.linalg.svd(J, compute_uv=False)[-1] < 1e-9
    Jp = damped_pinv(J, epsilon=0.04, max_damping=0.04)
    # ||J# V|| <= ||V|| / (2 lambda)
    assert np.linalg.norm(Jp, 2) <= 1 / (2 * 0.04) + 1e-9
    V = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
    assert np.all(np.isfinite(Jp @ V))
    # continuity: the command hardly changes when q leaves the singular point slightly
    q2 = q.copy(); q2[4] = 1e-4
    Jp2 = damped_pinv(lrmate.jacobian(q2))
    assert np.linalg.norm(Jp2 @ V - Jp @ V) < 0.05 * np.linalg.norm(Jp @ V) + 1e-3


def test_velocity_moves_tcp_along_force(lrmate):
    q = np.array([0.0, 0.2, -0.3, 0.0, -0.9, 0.0])
    w = np.array([20.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    qd = compliance_velocity(lrmate, q, w, ComplianceGains(force_deadband=0.0))
    np.testing.assert_allclose(lrmate.jacobian(q) @ qd, [1.4, 0, 0, 0, 0, 0], atol=1e-9)


def test_wrench_helpers():
    R = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    w = wrench_to_world([1, 0, 0, 0, 0, 1], R)
    np.testing.assert_allclose(w, [0, 1, 0, 0, 0, 1])
    # force along x applied at the origin, about a point 1 m along y: tau' = -r x f = +z
    np.testing.assert_allclose(shift_wrench([1, 0, 0, 0, 0, 0], [0, 1, 0]), [1, 0, 0, 0, 0, 1])
