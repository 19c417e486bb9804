"""A demonstration recorded with the hand-held demonstration device (HDD, Sec. 5.2).

A demonstration is the time series the HDD's tracker and 6-axis F/T sensor record while a person
performs a task: tool poses ``T_k`` in the world frame and the wrench ``w_k = [f, tau]`` in the sensor
frame, optionally with one action label per sample (approach, rotation, insertion, completion, ...).
The same device is later mounted on the robot, so demonstration and reproduction share one tool frame.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robointel._validate import as_array
from robointel.errors import InvalidInput, ShapeError
from robointel.io.demonstrations import UNITS, DemonstrationFile, DemonstrationRecord

__all__ = ["UNITS", "Demonstration", "load_demonstrations", "save_demonstrations"]


@dataclass(frozen=True)
class Demonstration:
    """One demonstration.

    ``t`` (N,) s, ``pose`` (N, 4, 4) tool poses in the world frame (m), ``wrench`` (N, 6) [fx, fy, fz, tx, ty, tz]
    in the sensor frame (N, N m), optional ``labels`` (N,) integer action indices into ``action_names`` (-1 =
    unlabelled).

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
    def create(cls, t: np.ndarray, pose: np.ndarray, wrench: np.ndarray, labels: np.ndarray | None = None, *,
               action_names: Sequence[str] = (), device: str = "hdd", name: str = "",
               meta: dict | None = None) -> Demonstration:
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


def save_demonstrations(path: str | Path, demos: Iterable[Demonstration]) -> DemonstrationFile:
    """Append demonstrations to an HDF5 file (created if missing; the others are not rewritten).

    Args:
        path: The ``.h5`` file (schema in :mod:`robointel.io.demonstrations`).
        demos: The demonstrations, stored under their names (or ``demo_NNNN``).

    Returns:
        The file.

    Raises:
        InvalidInput: a name is already stored or the file has another schema.
    """
    f = DemonstrationFile(path)
    f.extend(demos)
    return f


def load_demonstrations(path: str | Path) -> list[Demonstration]:
    """Read and validate every demonstration of an HDF5 file, in insertion order.

    Args:
        path: The ``.h5`` file.

    Returns:
        The demonstrations.

    Raises:
        DataMissing: the file does not exist.
        InvalidInput, ShapeError, NotFinite: a stored demonstration is invalid.
    """
    return [_from_record(r) for r in DemonstrationFile(path).load_all()]


def _from_record(r: DemonstrationRecord) -> Demonstration:
    """Validated :class:`Demonstration` of a stored record."""
    return Demonstration.create(r.t, r.pose, r.wrench, r.labels, action_names=r.action_names, device=r.device,
                                name=r.name, meta=r.meta)
