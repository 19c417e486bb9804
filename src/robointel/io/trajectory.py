"""Time-stamped joint trajectories ``{t, q, qd, qdd}`` plus joint names (the shape of a ROS
``JointTrajectory``), saved as ``.npz`` or JSON.

Between knots the trajectory is the cubic Hermite interpolant of ``(t, q, qd)``: for the C2 splines
the planner produces inside each segment this reproduces the planned curve exactly, and it keeps
zero velocity at stop-by waypoints. :meth:`Trajectory.sample` evaluates it at any times.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicHermiteSpline

from robointel._validate import as_array
from robointel.errors import InvalidInput

FORMAT = "robointel.trajectory/1"


@dataclass
class Trajectory:
    """Joint trajectory at knots.

    Attributes:
        t: (K,) strictly increasing times, s (t[0] is usually 0).
        q: (K, n) joint positions, rad.
        qd: (K, n) joint velocities, rad/s.
        qdd: (K, n) joint accelerations, rad/s^2.
        joint_names: n names.
        meta: free-form metadata (planner figures, scene name).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    joint_names: list[str] = field(default_factory=list)
    meta: dict = field(default_factory=dict)

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
        self._spline = None

    @property
    def duration(self) -> float:
        """Total time, s."""
        return float(self.t[-1] - self.t[0])

    @property
    def spline(self) -> CubicHermiteSpline:
        if self._spline is None:
            self._spline = CubicHermiteSpline(self.t, self.q, self.qd, axis=0)
        return self._spline

    def sample(self, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions, velocities, accelerations (len(times), n) of the Hermite interpolant."""
        ts = np.clip(as_array(times, "times", (None,)), self.t[0], self.t[-1])
        s = self.spline
        return s(ts), s(ts, 1), s(ts, 2)

    def resample(self, dt: float = 0.001) -> "Trajectory":
        """A dense copy at a fixed step ``dt`` (default 1 ms), ending exactly at the last knot."""
        if not dt > 0:
            raise InvalidInput(f"dt must be positive, got {dt}", value=dt)
        ts = np.arange(self.t[0], self.t[-1], dt)
        ts = np.append(ts, self.t[-1]) if ts[-1] < self.t[-1] - 1e-12 else ts
        q, qd, qdd = self.sample(ts)
        return Trajectory(ts, q, qd, qdd, list(self.joint_names), dict(self.meta))

    # files ------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {"format": FORMAT, "joint_names": list(self.joint_names), "t": self.t.tolist(),
                "q": self.q.tolist(), "qd": self.qd.tolist(), "qdd": self.qdd.tolist(), "meta": self.meta}

    def save(self, path) -> Path:
        """Write ``.npz`` (arrays + names) or ``.json``; the suffix decides."""
        path = Path(path)
        if path.suffix == ".json":
            path.write_text(json.dumps(self.to_dict(), indent=1, default=_json_default))
        elif path.suffix == ".npz":
            np.savez(path, t=self.t, q=self.q, qd=self.qd, qdd=self.qdd,
                     joint_names=np.array(self.joint_names), format=np.array(FORMAT),
                     meta=np.array(json.dumps(self.meta, default=_json_default)))
        else:
            raise InvalidInput(f"trajectory file must end in .npz or .json, got {path.name!r}", value=str(path))
        return path

    @classmethod
    def load(cls, path) -> "Trajectory":
        """Read a file written by :meth:`save`."""
        path = Path(path)
        if not path.exists():
            raise InvalidInput(f"trajectory file {path} does not exist", value=str(path))
        if path.suffix == ".json":
            d = json.loads(path.read_text())
            return cls(d["t"], d["q"], d["qd"], d["qdd"], list(d.get("joint_names", [])), d.get("meta", {}))
        if path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"])) if "meta" in z else {}
                return cls(z["t"], z["q"], z["qd"], z["qdd"], [str(s) for s in z["joint_names"]], meta)
        raise InvalidInput(f"trajectory file must end in .npz or .json, got {path.name!r}", value=str(path))


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    return str(o)
