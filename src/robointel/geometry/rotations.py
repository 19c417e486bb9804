"""Rotation helpers: thin, validated wrappers around Pinocchio and SciPy.

Conventions: rotation matrices act on column vectors (``R @ v``) and map frame coordinates to the
parent frame; roll-pitch-yaw is ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (the URDF convention, Pinocchio's
``rpyToMatrix``); quaternions are ``(w, x, y, z)`` with ``w >= 0`` on output.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from robointel._validate import as_array
from robointel.errors import InvalidInput

__all__ = [
    "rotation_about", "rpy_to_matrix", "matrix_to_rpy", "quat_to_matrix", "matrix_to_quat",
    "so3_exp", "so3_log", "skew", "project_to_rotation", "is_rotation", "check_rotation",
]


def skew(v: ArrayLike) -> np.ndarray:
    """3x3 cross-product matrix [v]x with ``skew(v) @ w == cross(v, w)``."""
    return pin.skew(as_array(v, "v", (3,)))


def rotation_about(axis: ArrayLike, angle: float) -> np.ndarray:
    """3x3 rotation by ``angle`` (rad) about ``axis`` (any non-zero length; normalised here)."""
    axis = as_array(axis, "axis", (3,))
    nrm = float(np.linalg.norm(axis))
    if nrm < 1e-12:
        raise InvalidInput("rotation axis must be non-zero", value=axis)
    angle = float(as_array(angle, "angle", ()))
    return pin.AngleAxis(angle, axis / nrm).matrix()


def rpy_to_matrix(rpy: ArrayLike) -> np.ndarray:
    """3x3 rotation from roll, pitch, yaw (rad): ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    r, p, y = as_array(rpy, "rpy", (3,))
    return pin.rpy.rpyToMatrix(float(r), float(p), float(y))


def matrix_to_rpy(R: ArrayLike) -> np.ndarray:
    """Roll, pitch, yaw (rad), pitch in [-pi/2, pi/2], of a proper rotation matrix."""
    return np.asarray(pin.rpy.matrixToRpy(check_rotation(R)), float)


def quat_to_matrix(q: ArrayLike) -> np.ndarray:
    """3x3 rotation from a quaternion ``(w, x, y, z)`` (normalised here; must be non-zero)."""
    q = as_array(q, "quaternion", (4,))
    if np.linalg.norm(q) < 1e-12:
        raise InvalidInput("quaternion must be non-zero", value=q)
    return Rotation.from_quat(q, scalar_first=True).as_matrix()


def matrix_to_quat(R: ArrayLike) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` with ``w >= 0`` of a proper rotation matrix."""
    q = Rotation.from_matrix(check_rotation(R)).as_quat(canonical=True, scalar_first=True)
    return np.asarray(q, float)


def so3_exp(omega: ArrayLike) -> np.ndarray:
    """Exponential map: rotation vector ``omega`` (axis * angle, rad) -> 3x3 rotation."""
    return pin.exp3(as_array(omega, "omega", (3,)))


def so3_log(R: ArrayLike) -> np.ndarray:
    """Logarithm map: proper rotation -> rotation vector (axis * angle), angle in [0, pi]."""
    return np.asarray(pin.log3(check_rotation(R)), float)


def project_to_rotation(M: ArrayLike) -> np.ndarray:
    """Nearest proper rotation (Frobenius norm) to a 3x3 matrix, via SVD with det = +1."""
    M = as_array(M, "matrix", (3, 3))
    U, _, Vt = np.linalg.svd(M)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    return U @ D @ Vt


def is_rotation(R: ArrayLike, tol: float = 1e-6) -> bool:
    """True when ``R`` is a 3x3 orthonormal matrix with determinant +1 (to ``tol``)."""
    R = np.asarray(R, float)
    return (R.shape == (3, 3) and bool(np.all(np.isfinite(R)))
            and np.allclose(R.T @ R, np.eye(3), atol=tol) and abs(np.linalg.det(R) - 1.0) < tol * 10)


def check_rotation(R: ArrayLike, name: str = "rotation", tol: float = 1e-6) -> np.ndarray:
    """Validate a proper rotation and return it re-orthonormalised (exactly orthonormal).

    Raises:
        ShapeError / NotFinite: not a finite 3x3 array.
        InvalidInput: not orthonormal or a reflection (det = -1).
    """
    R = as_array(R, name, (3, 3))
    if not is_rotation(R, tol):
        raise InvalidInput(
            f"{name} must be a proper rotation matrix (R^T R = I, det R = +1 to {tol:g}); got det "
            f"{np.linalg.det(R):.6g}. Use project_to_rotation() to repair a nearly orthonormal matrix.",
            value=R)
    return project_to_rotation(R)
