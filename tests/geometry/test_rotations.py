"""Rotation helpers against SciPy's Rotation (an independent implementation)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robointel.errors import InvalidInput, NotFinite, ShapeError
from robointel.geometry import rotations as rot

RS = Rotation.random(50, random_state=1)


def test_rotation_about_matches_scipy():
    rng = np.random.default_rng(0)
    for _ in range(20):
        axis, angle = rng.normal(size=3), rng.uniform(-np.pi, np.pi)
        want = Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()
        np.testing.assert_allclose(rot.rotation_about(axis * 3.0, angle), want, atol=1e-12)


def test_rpy_round_trip_and_convention():
    for R in RS.as_matrix():
        rpy = rot.matrix_to_rpy(R)
        np.testing.assert_allclose(rot.rpy_to_matrix(rpy), R, atol=1e-12)
        # URDF convention: R = Rz(yaw) Ry(pitch) Rx(roll) = extrinsic x-y-z
        np.testing.assert_allclose(Rotation.from_euler("xyz", rpy).as_matrix(), R, atol=1e-12)


def test_quaternion_round_trip():
    for R in RS.as_matrix():
        q = rot.matrix_to_quat(R)
        assert q[0] >= 0 and np.linalg.norm(q) == pytest.approx(1.0)
        np.testing.assert_allclose(rot.quat_to_matrix(q), R, atol=1e-12)
        np.testing.assert_allclose(rot.quat_to_matrix(-2.0 * q), R, atol=1e-12)  # sign and scale free
    np.testing.assert_allclose(rot.matrix_to_quat(np.eye(3)), [1, 0, 0, 0])


def test_so3_exp_log():
    for v in RS.as_rotvec():
        R = rot.so3_exp(v)
        np.testing.assert_allclose(R, Rotation.from_rotvec(v).as_matrix(), atol=1e-12)
        np.testing.assert_allclose(rot.so3_log(R), v, atol=1e-9)
    np.testing.assert_allclose(rot.so3_log(np.eye(3)), 0.0, atol=1e-15)


def test_skew():
    a, b = np.array([1.0, -2.0, 0.5]), np.array([0.3, 0.1, -4.0])
    np.testing.assert_allclose(rot.skew(a) @ b, np.cross(a, b))


def test_project_to_rotation():
    rng = np.random.default_rng(2)
    for R in RS.as_matrix()[:10]:
        noisy = R + 1e-3 * rng.normal(size=(3, 3))
        P = rot.project_to_rotation(noisy)
        assert rot.is_rotation(P, 1e-12)
        np.testing.assert_allclose(P, R, atol=5e-3)
        # the nearest rotation is no farther from the noisy matrix than the original one
        assert np.linalg.norm(P - noisy) <= np.linalg.norm(R - noisy) + 1e-12
    # a reflection projects to a proper rotation (det +1)
    P = rot.project_to_rotation(np.diag([1.0, 1.0, -1.0]))
    assert np.linalg.det(P) == pytest.approx(1.0)


def test_check_rotation_errors():
    with pytest.raises(InvalidInput):
        rot.check_rotation(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(InvalidInput):
        rot.check_rotation(2 * np.eye(3))
    with pytest.raises(ShapeError):
        rot.check_rotation(np.eye(4))
    with pytest.raises(NotFinite):
        rot.check_rotation(np.full((3, 3), np.nan))
    with pytest.raises(InvalidInput):
        rot.rotation_about([0, 0, 0], 1.0)
    with pytest.raises(InvalidInput):
        rot.quat_to_matrix([0, 0, 0, 0])
    with pytest.raises(ShapeError):
        rot.rpy_to_matrix([0.1, 0.2])
