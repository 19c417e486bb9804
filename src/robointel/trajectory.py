"""The one time-stamped joint trajectory type: ``{t, q, qd, qdd}`` plus joint names.

It has the shape of a ROS ``JointTrajectory``. Every generator returns it (temporal optimization,
the FRMP, kinematic imitation, key-point reproduction) and the MuJoCo runner consumes it. Between
knots the trajectory is the cubic Hermite interpolant of ``(t, q, qd)``: for the C2 splines the
planner produces inside each segment this reproduces the planned curve exactly, and it keeps zero
velocity at stop-by waypoints. Files: :mod:`robointel.io.trajectory`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicHermiteSpline

from robointel._validate import as_array
from robointel.errors import InvalidInput

__all__ = ["Trajectory"]


@dataclass
class Trajectory:
    """Joint trajectory at knots.

    Attributes:
        t: (K,) strictly increasing times, s (t[0] is usually 0), K >= 2.
        q: (K, n) joint positions, rad.
        qd: (K, n) joint velocities, rad/s.
        qdd: (K, n) joint accelerations, rad/s^2.
        joint_names: n names (default ``joint_1`` ... ``joint_n``).
        meta: free-form metadata (planner figures, scene name).

    Raises:
        ShapeError: arrays of inconsistent shapes.
        NotFinite: NaN or inf in any array.
        InvalidInput: fewer than two or not strictly increasing times; wrong number of names.
    """

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    qd: NDArray[np.float64]
    qdd: NDArray[np.float64]
    joint_names: list[str] = field(default_factory=list)
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.t = as_array(self.t, "t", (None,))
        K = self.t.size
        self.q = as_array(self.q, "q", (K, None))
        n = self.q.shape[1]
        self.qd = as_array(self.qd, "qd", (K, n))
        self.qdd = as_array(self.qdd, "qdd", (K, n))
        if K < 2 or np.any(np.diff(self.t) <= 0):
            raise InvalidInput("t must hold at least two strictly increasing times", value=self.t)
        if not self.joint_names:
            self.joint_names = [f"joint_{i + 1}" for i in range(n)]
        if len(self.joint_names) != n:
            raise InvalidInput(f"{len(self.joint_names)} joint names for {n} joints", value=self.joint_names)
        self._spline: CubicHermiteSpline | None = None

    @property
    def duration(self) -> float:
        """Total time, s."""
        return float(self.t[-1] - self.t[0])

    @property
    def n_joints(self) -> int:
        """Number of joints n."""
        return int(self.q.shape[1])

    @property
    def spline(self) -> CubicHermiteSpline:
        """The cubic Hermite interpolant of ``(t, q, qd)`` (built once)."""
        if self._spline is None:
            self._spline = CubicHermiteSpline(self.t, self.q, self.qd, axis=0)
        return self._spline

    def sample(self, times: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Evaluate the Hermite interpolant.

        Args:
            times: (M,) times, s; clipped to ``[t[0], t[-1]]``.

        Returns:
            Positions (M, n) rad, velocities (M, n) rad/s and accelerations (M, n) rad/s^2.

        Raises:
            ShapeError, NotFinite: ``times`` is not a finite 1-D array.
        """
        ts = np.clip(as_array(times, "times", (None,)), self.t[0], self.t[-1])
        s = self.spline
        return s(ts), s(ts, 1), s(ts, 2)

    def resample(self, dt: float = 0.001) -> Trajectory:
        """A dense copy at a fixed step, ending exactly at the last knot.

        Args:
            dt: Step, s (default 1 ms).

        Returns:
            The resampled trajectory with the same names and a copy of ``meta``.

        Raises:
            InvalidInput: ``dt`` is not positive.
        """
        if not dt > 0:
            raise InvalidInput(f"dt must be positive, got {dt}", value=dt)
        ts = np.arange(self.t[0], self.t[-1], dt)
        ts = np.append(ts, self.t[-1]) if ts[-1] < self.t[-1] - 1e-12 else ts
        q, qd, qdd = self.sample(ts)
        return Trajectory(ts, q, qd, qdd, list(self.joint_names), dict(self.meta))
