"""Force/torque sensor identification and gravity compensation (Ch. 3.3, eqs. (3.14)-(3.20)).

With no external force, a wrist F/T sensor reads the weight of the payload (tool + handle) and its
own biases. In the sensor frame S, with R the sensor orientation in the world and g the gravity
vector in the world,

    f = m R^T g + f_B                                   (3.14)
    tau = r_P x (m R^T g) + tau_B                         (3.15)

where m is the payload mass (f_P = m g its weight), r_P its centre of mass in S and f_B, tau_B the
biases. Both are linear in the unknowns, so readings in many poses give two stacked least-squares
problems (3.16)-(3.19):

    [R_i^T g, I_3] [m; f_B] = f_i,
    [-[m R_i^T g]_x, I_3] [r_P; tau_B] = tau_i.

The compensated (external) wrench is then (3.20)

    f_E = f - f_B - m R^T g,  tau_E = tau - tau_B - r_P x (m R^T g),

computed by :class:`robointel.control.PayloadCompensation` (written once, used on every backend).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from robointel._validate import as_array
from robointel.control.payload import GRAVITY, PayloadCompensation
from robointel.errors import InvalidInput

if TYPE_CHECKING:  # pragma: no cover
    from robointel.sim import Workcell

__all__ = ["FTCalibration", "GRAVITY", "calibrate_in_workcell", "identify_ft", "skew"]

def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices [v]_x: (3,) -> (3, 3) or (N, 3) -> (N, 3, 3)."""
    v = np.asarray(v, float)
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([np.stack([z, -w, y], -1), np.stack([w, z, -x], -1), np.stack([-y, x, z], -1)], -2)


@dataclass(frozen=True)
class FTCalibration:
    """Identified payload and sensor biases (3.14)-(3.19).

    Attributes:
        mass: payload mass m, kg (the weight f_P = m |g|).
        com: payload centre of mass r_P in the sensor frame, (3,), m.
        force_bias: f_B, (3,), N, sensor frame.
        torque_bias: tau_B, (3,), N m, sensor frame.
        force_rms: RMS force residual of the fit, N.
        torque_rms: RMS torque residual of the fit, N m.
        gravity: world gravity vector used, (3,), m/s^2.
    """

    mass: float
    com: np.ndarray
    force_bias: np.ndarray
    torque_bias: np.ndarray
    force_rms: float
    torque_rms: float
    gravity: np.ndarray = field(default_factory=lambda: GRAVITY.copy())

    @property
    def weight(self) -> float:
        """|f_P| = m |g|, N."""
        return self.mass * float(np.linalg.norm(self.gravity))

    @cached_property
    def payload(self) -> PayloadCompensation:
        """The identified payload and biases as the one F/T compensation of :mod:`robointel.control`.

        Raises:
            InvalidInput: the identified mass is negative (no payload and noise, or poorly exciting poses).
        """
        return PayloadCompensation(self.mass, self.com, self.force_bias, self.torque_bias, self.gravity)

    def payload_wrench(self, R_world_sensor: ArrayLike) -> np.ndarray:
        """Wrench the payload and biases put on the sensor at orientation(s) R (3.14)-(3.15).

        Args:
            R_world_sensor: (3, 3) or (N, 3, 3) sensor orientation(s), world <- sensor.

        Returns:
            (6,) or (N, 6) [f (N); tau (N m)], sensor frame.
        """
        return self.payload.payload_wrench(R_world_sensor)

    def compensate(self, wrench: ArrayLike, R_world_sensor: ArrayLike) -> np.ndarray:
        """External wrench (3.20): reading minus payload weight and biases, in the sensor frame.

        Args:
            wrench: raw reading(s) [f; tau], (6,) or (N, 6).
            R_world_sensor: sensor orientation(s), (3, 3) or (N, 3, 3).

        Returns:
            Same shape as ``wrench``.

        Raises:
            InvalidInput: shapes that do not match or values that are not finite.
        """
        return self.payload.compensate(wrench, R_world_sensor)


def identify_ft(wrenches: ArrayLike, rotations: ArrayLike, *, gravity: ArrayLike = GRAVITY) -> FTCalibration:
    """Identify payload mass, centre of mass and sensor biases by least squares (3.16)-(3.19).

    Args:
        wrenches: (N, 6) readings [f (N); tau (N m)] in the sensor frame, no external force.
        rotations: (N, 3, 3) sensor orientations in the world (world <- sensor).
        gravity: world gravity vector, m/s^2.

    Returns:
        :class:`FTCalibration` with the fit's RMS residuals.

    Raises:
        InvalidInput: fewer than 3 poses, or poses that do not excite the problem (the sensor
            must be seen with gravity along at least two independent directions).
    """
    W = as_array(wrenches, "wrenches", (None, 6))
    R = as_array(rotations, "rotations", (W.shape[0], 3, 3))
    g = as_array(gravity, "gravity", (3,))
    N = W.shape[0]
    if N < 3:
        raise InvalidInput(f"need readings in at least 3 poses to identify the payload, got {N}", value=N)
    g_s = np.einsum("nji,j->ni", R, g)  # gravity in sensor axes, (N, 3)
    if np.linalg.matrix_rank(g_s - g_s.mean(0), tol=1e-3 * np.linalg.norm(g)) < 2:
        raise InvalidInput("poses do not excite the identification: gravity must point in at least two "
                           "independent directions in the sensor frame; tilt the tool in more ways")
    # (3.16)-(3.17): forces, unknowns [m, f_B]
    A = np.zeros((N, 3, 4))
    A[:, :, 0] = g_s
    A[:, :, 1:] = np.eye(3)
    xf, *_ = np.linalg.lstsq(A.reshape(-1, 4), W[:, :3].reshape(-1), rcond=None)
    m, fB = float(xf[0]), xf[1:]
    # (3.18)-(3.19): torques, unknowns [r_P, tau_B]; tau = -[m g_s]_x r + tau_B
    B = np.zeros((N, 3, 6))
    B[:, :, :3] = -skew(m * g_s)
    B[:, :, 3:] = np.eye(3)
    xt, *_ = np.linalg.lstsq(B.reshape(-1, 6), W[:, 3:].reshape(-1), rcond=None)
    r, tB = xt[:3], xt[3:]
    rf = A.reshape(-1, 4) @ xf - W[:, :3].reshape(-1)
    rt = B.reshape(-1, 6) @ xt - W[:, 3:].reshape(-1)
    return FTCalibration(mass=m, com=r, force_bias=fB, torque_bias=tB,
                         force_rms=float(np.sqrt(np.mean(rf ** 2))), torque_rms=float(np.sqrt(np.mean(rt ** 2))),
                         gravity=g.copy())


def calibrate_in_workcell(wc: Workcell, q0: np.ndarray, *, poses: int = 12, settle: float = 0.25, average: int = 50,
                          spread: float = 1.2, seed: int = 0) -> FTCalibration:
    """Identify payload and F/T biases on a (simulated) robot (3.14)-(3.19).

    Holds the robot still in ``poses`` wrist orientations around ``q0`` (J4-J6 offset uniformly
    within +-``spread`` rad), averages ``average`` readings in each after ``settle`` seconds, and fits
    :func:`identify_ft`. Leaves the robot holding the last pose.

    Args:
        wc: a :class:`robointel.sim.Workcell` with an F/T sensor (payload, bias and noise as built).
        q0: (n,) central configuration, rad.
        poses: number of wrist poses around ``q0`` (>= 3).
        settle: time held at each pose before measuring, s.
        average: F/T readings averaged per pose (1 kHz).
        spread: range of the random wrist offsets (J4-J6), +- rad.
        seed: seed of the random poses.

    Returns:
        The identified payload mass, centre of mass and sensor biases.

    Raises:
        InvalidInput: fewer than 3 poses or ``average`` < 1.
    """
    robot = wc.robot
    q0 = robot.check_q(q0, "q0")
    if poses < 3 or average < 1:
        raise InvalidInput("need poses >= 3 and average >= 1", value=(poses, average))
    rng = np.random.default_rng(seed)
    W, R = [], []
    for _ in range(poses):
        q = q0.copy()
        q[3:6] += rng.uniform(-spread, spread, 3)
        q = np.clip(q, robot.lower, robot.upper)
        wc.reset(q)
        wc.hold(settle)
        acc = np.zeros(6)
        for _ in range(average):
            wc.hold(0.001)
            acc += wc.ft_reading()
        W.append(acc / average)
        R.append(wc.sensor_pose()[:3, :3])
    return identify_ft(np.array(W), np.array(R))
