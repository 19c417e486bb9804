"""The log of a trajectory tracked in the workcell at the control rate."""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from robointel.robot import Robot


@dataclass
class TrackingLog:
    """What :meth:`Workcell.run_trajectory` recorded at each 1 kHz control step.

    Arrays: ``t`` (N,) s; ``q``, ``qd``, ``q_ref``, ``qd_ref``, ``tau`` (N, n) rad, rad/s, N m;
    ``ft`` (N, 6) sensor wrench or None; ``contacts`` (N,) number of robot contacts with the
    environment (obstacles, table, floor, self); ``distance`` (N,) minimum robot-obstacle signed
    distance (m; NaN where not evaluated, ``inf`` without obstacles).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    q_ref: np.ndarray
    qd_ref: np.ndarray
    tau: np.ndarray
    ft: np.ndarray | None
    contacts: np.ndarray
    distance: np.ndarray
    joint_names: list[str] = field(default_factory=list)
    saturated: np.ndarray | None = None

    @property
    def error(self) -> np.ndarray:
        """Tracking error q_ref - q, (N, n) rad."""
        return self.q_ref - self.q

    @property
    def rms_error(self) -> np.ndarray:
        """RMS tracking error per joint, (n,) rad."""
        return np.sqrt(np.mean(self.error**2, axis=0))

    @property
    def max_error(self) -> np.ndarray:
        """Maximum absolute tracking error per joint, (n,) rad."""
        return np.max(np.abs(self.error), axis=0)

    @property
    def min_distance(self) -> float:
        """Smallest robot-obstacle distance over the run (m; ``inf`` without obstacles)."""
        d = self.distance[np.isfinite(self.distance) | np.isinf(self.distance)]
        return float(np.min(d)) if d.size else float("inf")

    @property
    def collided(self) -> bool:
        """True if the robot touched an obstacle, the table, the floor or itself."""
        return bool(np.any(self.contacts > 0)) or self.min_distance < 0

    @property
    def saturation_fraction(self) -> np.ndarray:
        """Fraction of control periods each joint's torque was at its effort limit, (n,)."""
        if self.saturated is None or len(self.saturated) == 0:
            return np.zeros(self.q.shape[1])
        return self.saturated.mean(axis=0)

    def velocity_ratio(self, robot: Robot) -> np.ndarray:
        """max_t |qd_ref| / velocity limit per joint, (n,): > 1 means the reference was too fast."""
        return np.max(np.abs(self.qd_ref), axis=0) / robot.velocity_limit

    @property
    def duration(self) -> float:
        """Time span of the log, s."""
        return float(self.t[-1] - self.t[0]) if len(self.t) else 0.0

    def tcp_error(self, robot: Robot) -> np.ndarray:
        """TCP position error |p(q_ref) - p(q)| per sample, (N,) m."""
        return np.array([np.linalg.norm(robot.fk(a)[:3, 3] - robot.fk(b)[:3, 3]) for a, b in zip(self.q_ref, self.q)])

    def to_dict(self) -> dict:
        """All arrays and the joint names (for ``np.savez`` / JSON)."""
        out = {k: getattr(self, k) for k in ("t", "q", "qd", "q_ref", "qd_ref", "tau", "contacts", "distance")}
        if self.ft is not None:
            out["ft"] = self.ft
        if self.saturated is not None:
            out["saturated"] = self.saturated
        out["joint_names"] = np.array(self.joint_names)
        return out

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the log as a compressed ``.npz``."""
        np.savez_compressed(path, **self.to_dict())

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> TrackingLog:
        """Read a log written by :meth:`save`."""
        with np.load(path) as z:
            d = {k: z[k] for k in z.files}
        return cls(t=d["t"], q=d["q"], qd=d["qd"], q_ref=d["q_ref"], qd_ref=d["qd_ref"], tau=d["tau"],
                   ft=d.get("ft"), contacts=d["contacts"], distance=d["distance"],
                   joint_names=[str(x) for x in d["joint_names"]], saturated=d.get("saturated"))

    def summary(self) -> dict:
        """Scalars for reports: RMS/max error per joint (rad), min distance, collided, duration."""
        return {"rms_error_rad": self.rms_error.tolist(), "max_error_rad": self.max_error.tolist(),
                "rms_error_all_rad": float(np.sqrt(np.mean(self.error**2))),
                "min_distance_m": self.min_distance, "collided": self.collided, "duration_s": self.duration}
