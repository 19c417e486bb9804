"""HDF5 demonstration files (one documented schema).

Schema (version 1)::

    /                       attrs: schema = "robointel.demonstrations", version = 1
    /demonstrations/<name>  one group per demonstration, attrs:
        device        str    the recording device ("hdd", "robot", ...)
        action_names  str    JSON list of action names (labels index into it)
        units         str    JSON {"t": "s", "pose": "m ...", "wrench": "N, N m"}
        meta          str    JSON dict of extra scalars (e.g. ground-truth phase times)
        order         int    insertion order (0, 1, ...)
      t       (N,)      float64  time, s, strictly increasing
      pose    (N, 4, 4) float64  tool pose in the world frame (rotation, translation in m)
      wrench  (N, 6)    float64  [fx, fy, fz, tx, ty, tz] in the sensor frame, N and N m
      labels  (N,)      int64    optional action index per sample (-1 unlabelled)

Appending opens the file in ``"a"`` mode and creates one new group per demonstration: the other
groups are never rewritten (their datasets keep their storage). Several demonstrations are appended
all or none (:meth:`DemonstrationFile.extend`).
"""
from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import h5py
import numpy as np
from numpy.typing import NDArray

from robointel.errors import DataMissing, InvalidInput

__all__ = ["SCHEMA", "UNITS", "VERSION", "DemonstrationFile", "DemonstrationLike", "DemonstrationRecord"]

SCHEMA = "robointel.demonstrations"
VERSION = 1
#: the units attribute written with every demonstration
UNITS = {"t": "s", "pose": "m (translation), rotation matrix (unitless)", "wrench": "N (force), N m (torque)"}


class DemonstrationLike(Protocol):
    """What :meth:`DemonstrationFile.append` reads (``robointel.learning.demonstration.Demonstration``)."""

    @property
    def t(self) -> NDArray[np.float64]: ...  # noqa: D102
    @property
    def pose(self) -> NDArray[np.float64]: ...  # noqa: D102
    @property
    def wrench(self) -> NDArray[np.float64]: ...  # noqa: D102
    @property
    def labels(self) -> NDArray[np.int64] | None: ...  # noqa: D102
    @property
    def action_names(self) -> tuple[str, ...]: ...  # noqa: D102
    @property
    def device(self) -> str: ...  # noqa: D102
    @property
    def name(self) -> str: ...  # noqa: D102
    @property
    def meta(self) -> dict[str, Any]: ...  # noqa: D102


@dataclass
class DemonstrationRecord:
    """One stored demonstration as plain data (the schema above; not validated here).

    Attributes:
        t: (N,) time, s.
        pose: (N, 4, 4) tool poses in the world frame, m.
        wrench: (N, 6) wrench in the sensor frame, N and N m.
        labels: (N,) action indices or None.
        action_names: names the labels index into.
        device: the recording device.
        name: the group name.
        meta: extra scalars.
    """

    t: NDArray[np.float64]
    pose: NDArray[np.float64]
    wrench: NDArray[np.float64]
    labels: NDArray[np.int64] | None
    action_names: tuple[str, ...] = ()
    device: str = "hdd"
    name: str = ""
    meta: dict[str, Any] = field(default_factory=dict)


def _check_name(name: str) -> str:
    """A demonstration name: one HDF5 group name (no '/', not '.', not empty, printable)."""
    if not isinstance(name, str) or not name or name in (".", "..") or "/" in name \
            or not name.isprintable() or len(name) > 200:
        raise InvalidInput(f"demonstration name {name!r} is not allowed: use 1-200 printable characters without "
                           "'/' (a '/' would store it outside the file's index)", value=name)
    return name


class DemonstrationFile:
    """An HDF5 file of demonstrations: ``append``, ``names``, ``load``, ``load_all`` (plain records).

    The typed API (:class:`robointel.learning.demonstration.Demonstration` in and out) is
    :func:`robointel.learning.demonstration.save_demonstrations` / ``load_demonstrations``.

    Args:
        path: the ``.h5`` file; created on first append.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def _open(self, mode: str) -> h5py.File:
        """Open the file; a truncated or non-HDF5 file is an :class:`InvalidInput` saying so."""
        try:
            return h5py.File(self.path, mode)
        except OSError as exc:
            raise InvalidInput(f"{self.path} is not a readable HDF5 demonstration file (corrupt, truncated or "
                               f"another format: {str(exc).splitlines()[0][:120]})", value=str(self.path)) from None

    def _check(self, f: h5py.File) -> None:
        if f.attrs.get("schema") != SCHEMA:
            raise InvalidInput(f"{self.path} is not a robointel demonstration file (schema attr "
                               f"{f.attrs.get('schema')!r}, want {SCHEMA!r})", value=str(self.path))

    def append(self, demo: DemonstrationLike, *, name: str | None = None) -> str:
        """Add one demonstration as a new group; returns its name.

        Raises:
            InvalidInput: a demonstration with that name is already stored, the name contains '/'
                (or is empty, '.', '..', unprintable), or the file is not a readable HDF5 file.
        """
        return self.extend([demo], names=[name])[0]

    def extend(self, demos: Iterable[DemonstrationLike], *, names: Iterable[str | None] | None = None) -> list[str]:
        """Append several demonstrations, all or none; returns their names.

        Every name is checked (allowed, not stored yet, not repeated) before anything is written; a
        write that fails part way removes the groups it made.

        Args:
            demos: the demonstrations.
            names: their names (None entries, or no list: each demonstration's own name, else
                ``demo_NNNN``).

        Returns:
            The stored names, in order.

        Raises:
            InvalidInput: a name is taken, repeated or not allowed, or the file is not a readable
                HDF5 demonstration file (nothing is written then).
        """
        demos = list(demos)
        given = list(names) if names is not None else [None] * len(demos)
        if len(given) != len(demos):
            raise InvalidInput(f"{len(given)} names for {len(demos)} demonstrations", value=len(given))
        with self._open("a") as f:
            if "schema" not in f.attrs:
                f.attrs["schema"] = SCHEMA
                f.attrs["version"] = VERSION
            self._check(f)
            root = f.require_group("demonstrations")
            out: list[str] = []
            for k, (d, nm) in enumerate(zip(demos, given)):
                name = _check_name(nm or d.name or f"demo_{len(root) + k:04d}")
                if name in root or name in out:
                    raise InvalidInput(f"demonstration {name!r} already in {self.path}"
                                       + (" (twice in this import)" if name in out else "")
                                       + "; choose another name; nothing was appended", value=name)
                out.append(name)
            made: list[str] = []
            try:
                for d, name in zip(demos, out):
                    g = root.create_group(name)
                    made.append(name)
                    g.create_dataset("t", data=d.t)
                    g.create_dataset("pose", data=d.pose)
                    g.create_dataset("wrench", data=d.wrench)
                    if d.labels is not None:
                        g.create_dataset("labels", data=d.labels.astype(np.int64))
                    g.attrs["device"] = d.device
                    g.attrs["action_names"] = json.dumps(list(d.action_names))
                    g.attrs["units"] = json.dumps(UNITS)
                    g.attrs["meta"] = json.dumps(d.meta, default=float)
                    g.attrs["order"] = len(root) - 1
            except BaseException:
                for name in made:
                    del root[name]
                raise
        return out

    def names(self) -> list[str]:
        """Stored demonstration names in insertion order."""
        if not self.path.exists():
            return []
        with self._open("r") as f:
            self._check(f)
            root = f.get("demonstrations", {})
            return sorted(root, key=lambda n: int(root[n].attrs.get("order", 0)))

    def __len__(self) -> int:
        return len(self.names())

    def load(self, name: str) -> DemonstrationRecord:
        """Read one demonstration.

        Raises:
            DataMissing: no file or no such demonstration.
        """
        if not self.path.exists():
            raise DataMissing(f"demonstration file {self.path} does not exist", value=str(self.path))
        with self._open("r") as f:
            self._check(f)
            root = f.get("demonstrations")
            if root is None or name not in root:
                raise DataMissing(f"no demonstration {name!r} in {self.path}", value=name)
            g = root[name]
            try:
                labels = g["labels"][()] if "labels" in g else None
                t, pose, wrench = g["t"][()], g["pose"][()], g["wrench"][()]
                attrs = (tuple(json.loads(g.attrs["action_names"])), str(g.attrs["device"]),
                         json.loads(g.attrs.get("meta", "{}")))
            except (OSError, KeyError, ValueError, TypeError) as exc:
                raise InvalidInput(f"demonstration {name!r} in {self.path} is corrupt or truncated "
                                   f"({type(exc).__name__}: {str(exc)[:120]})", value=name) from None
            return DemonstrationRecord(t, pose, wrench, labels, action_names=attrs[0], device=attrs[1], name=name,
                                       meta=attrs[2])

    def load_all(self) -> list[DemonstrationRecord]:
        """All demonstrations in insertion order."""
        return [self.load(n) for n in self.names()]

