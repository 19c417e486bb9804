"""A demonstration recorded with the hand-held demonstration device (HDD, Sec. 5.2).

A demonstration is the time series the HDD's tracker and 6-axis F/T sensor record while a person
performs a task: tool poses ``T_k`` in the world frame and the wrench ``w_k = [f, tau]`` in the sensor
frame, optionally with one action label per sample (approach, rotation, insertion, completion, ...).
The same device is later mounted on the robot, so demonstration and reproduction share one tool frame.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robointel._validate import as_array
from robointel.errors import InvalidInput, ShapeError

UNITS = {"t": "s", "pose": "m (translation), rotation matrix (unitless)", "wrench": "N (force), N m (torque)"}


@dataclass(frozen=True)
class Demonstration:
    """One demonstration: ``t`` (N,) s, ``pose`` (N, 4, 4) tool poses in the world frame (m),
    ``wrench`` (N, 6) [fx, fy, fz, tx, ty, tz] in the sensor frame (N, N m), optional ``labels`` (N,)
    integer action indices into ``action_names`` (-1 = unlabelled).

    Construct with :meth:`create` to validate shapes, monotonic time and finiteness.
    """

    t: np.ndarray
    pose: np.ndarray
    wrench: np.ndarray
    labels: np.ndarray | None = None
    action_names: tuple[str, ...] = ()
    device: str = "hdd"
    name: str = ""
    meta: dict = field(default_factory=dict)

    @classmethod
    def create(cls, t, pose, wrench, labels=None, *, action_names=(), device: str = "hdd", name: str = "",
               meta: dict | None = None) -> "Demonstration":
        """Validated constructor.

        Raises:
            ShapeError: inconsistent lengths or wrong shapes.
            NotFinite: NaN or inf samples.
            InvalidInput: time not strictly increasing, labels outside ``action_names``.
        """
        t = as_array(t, "t", (None,))
        n = t.shape[0]
        if n < 2:
            raise ShapeError(f"a demonstration needs at least 2 samples, got {n}", value=n)
        pose = as_array(pose, "pose", (n, 4, 4))
        wrench = as_array(wrench, "wrench", (n, 6))
        if np.any(np.diff(t) <= 0):
            raise InvalidInput("t must be strictly increasing (seconds)", value=t)
        if labels is not None:
            labels = np.asarray(labels)
            if labels.shape != (n,) or labels.dtype.kind not in "iu":
                raise ShapeError(f"labels must be ({n},) integers, got {labels.shape} {labels.dtype}", value=labels)
            labels = labels.astype(np.int64)
            if action_names and labels.max() >= len(action_names):
                raise InvalidInput(f"label {labels.max()} has no name in action_names {tuple(action_names)}")
        return cls(t, pose, wrench, labels, tuple(action_names), str(device), str(name), dict(meta or {}))

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def position(self) -> np.ndarray:
        """(N, 3) tool positions in metres."""
        return self.pose[:, :3, 3]

    def features(self, *, wrench: bool = True) -> np.ndarray:
        """Per-sample feature vectors (Sec. 5.3.2): vec(T) = [r11..r33, p] (12) and the wrench (6).

        Returns:
            (N, 12) or (N, 18) array.
        """
        f = np.concatenate([self.pose[:, :3, :3].reshape(len(self), 9), self.pose[:, :3, 3]], axis=1)
        return np.concatenate([f, self.wrench], axis=1) if wrench else f

    def phase_times(self) -> np.ndarray:
        """Times (s) of the first sample of each new action (the split points), (n_changes,)."""
        if self.labels is None:
            raise InvalidInput(f"demonstration {self.name!r} has no labels")
        k = np.flatnonzero(np.diff(self.labels) != 0) + 1
        return self.t[k]
