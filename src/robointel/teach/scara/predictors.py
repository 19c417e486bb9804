"""Predictors of the human angles across the sensor latency (Ch. 3.2, delay compensation).

The interface, a constant-rate Kalman filter and the no-prediction hold.
"""
from __future__ import annotations

from typing import Protocol

import numpy as np
import numpy.typing as npt


class Predictor(Protocol):
    """What the SCARA simulation needs of a predictor: frames in, angle estimates at any time out."""

    t: float | None  # capture time [s] of the last frame taken

    def reset(self) -> None:
        """Forget all frames."""

    def update(self, t: float, z: npt.ArrayLike) -> None:
        """Take the frame (n,) [rad] captured at time ``t`` [s]."""

    def predict(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(angle (n,) [rad], rate (n,) [rad/s]) estimated at time ``t`` [s]."""
        ...


class KalmanPredictor:
    """Per-joint Kalman filter with a white-noise-acceleration model on frames that arrive late.

    State per joint x = [angle, rate]; between frames h apart F = [[1, h], [0, 1]] and process
    noise Q = q [[h^3/3, h^2/2], [h^2/2, h]]. It predicts the angles at any later time by
    constant-rate extrapolation (the delay compensation).

    Args:
        n: number of joints.
        accel_psd: process noise (acceleration) spectral density q [rad^2/s^3].
        meas_std: measurement noise [rad].
    """

    def __init__(self, n: int, *, accel_psd: float = 1e3, meas_std: float = 0.02) -> None:
        self.n, self.q, self.r = n, float(accel_psd), float(meas_std) ** 2
        self.x: np.ndarray | None = None  # (n, 2): angle, rate at time self.t
        self.P: np.ndarray | None = None
        self.t: float | None = None

    def reset(self) -> None:
        """Forget all frames."""
        self.x = self.P = self.t = None

    def update(self, t: float, z: npt.ArrayLike) -> None:
        """Fuse the frame (n,) [rad] taken at time ``t`` [s] (its capture time, not its arrival)."""
        z = np.asarray(z, float)
        if self.x is None or self.P is None or self.t is None:
            self.x = np.stack([z, np.zeros(self.n)], 1)
            self.P = np.tile(np.diag([self.r, 10.0]), (self.n, 1, 1))
            self.t = t
            return
        h = t - self.t
        F = np.array([[1.0, h], [0.0, 1.0]])
        Qn = self.q * np.array([[h ** 3 / 3, h ** 2 / 2], [h ** 2 / 2, h]])
        self.x = self.x @ F.T
        self.P = F @ self.P @ F.T + Qn
        S = self.P[:, 0, 0] + self.r
        K = self.P[:, :, 0] / S[:, None]
        self.x = self.x + K * (z - self.x[:, 0])[:, None]
        self.P = self.P - K[:, :, None] * self.P[:, 0, None, :]
        self.t = t

    def predict(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(angle (n,) [rad], rate (n,) [rad/s]) at time ``t`` [s], extrapolated from the last frame."""
        assert self.x is not None and self.t is not None, "predict() before the first update()"
        h = t - self.t
        return self.x[:, 0] + h * self.x[:, 1], self.x[:, 1].copy()


class HoldPredictor:
    """No prediction: the newest received frame as it is, rate 0.

    The human motion delayed by the latency and the frame's age (the uncompensated reference).
    """

    def __init__(self) -> None:
        self.z: np.ndarray | None = None
        self.t: float | None = None

    def reset(self) -> None:
        """Forget all frames."""
        self.z = self.t = None

    def update(self, t: float, z: npt.ArrayLike) -> None:
        """Take the frame (n,) [rad] captured at time ``t`` [s]."""
        self.z, self.t = np.asarray(z, float).copy(), t

    def predict(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(the newest frame (n,) [rad], zeros (n,))."""
        assert self.z is not None, "predict() before the first update()"
        return self.z.copy(), np.zeros_like(self.z)


class LinePredictor:
    """The line through the two newest frames: q(t) = q_k + (t - t_k) (q_k - q_{k-1}) / (t_k - t_{k-1}).

    Between the two frames it interpolates; past the newest it extrapolates at their rate (the first
    frame alone: held). No smoothing: a frame's noise passes through as it is.
    """

    def __init__(self) -> None:
        self.z: np.ndarray | None = None
        self.v: np.ndarray | None = None
        self.t: float | None = None

    def reset(self) -> None:
        """Forget all frames."""
        self.z = self.v = self.t = None

    def update(self, t: float, z: npt.ArrayLike) -> None:
        """Take the frame (n,) [rad] captured at time ``t`` [s] (after the previous one)."""
        z = np.asarray(z, float).copy()
        if self.z is None or self.t is None or t <= self.t:
            self.v = np.zeros_like(z)
        else:
            self.v = (z - self.z) / (t - self.t)
        self.z, self.t = z, t

    def predict(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(angle (n,) [rad], rate (n,) [rad/s]) on the line at time ``t`` [s]."""
        assert self.z is not None and self.v is not None and self.t is not None, "predict() before update()"
        return self.z + (t - self.t) * self.v, self.v.copy()
