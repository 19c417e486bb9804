"""HDF5 grasp databases: category templates with their taught grasps (one documented schema).

Schema (version 1)::

    /                      attrs: schema = "robointel.grasp_db", version = 1,
                                  gripper = JSON of the ParallelGripper fields (m, kg)
    /templates/<name>      one group per template, attrs:
        category   str     the object category ("cup", "toy_arm", ...)
        source     str     where the template came from ("ycb:065-a_cups", "primitive", ...)
        order      int     insertion order (0, 1, ...)
      points   (M, 3)   float64  template cloud in the object frame (z up, resting on z = 0), m
      grasps/centre    (G, 3)    float64  grasp centres, object frame, m
      grasps/rotation  (G, 3, 3) float64  grasp frames (columns x, y = closing axis, z = approach)
      grasps/width     (G,)      float64  jaw opening at teach time, m
      grasps/names     (G,)      str      grasp labels

Adding a template opens the file in ``"a"`` mode and writes one new group; the others are untouched.
"""
from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import h5py
import numpy as np
from numpy.typing import NDArray

from robointel.errors import DataMissing, InvalidInput

SCHEMA = "robointel.grasp_db"
VERSION = 1

__all__ = ["SCHEMA", "VERSION", "GraspDatabaseFile", "GraspRecord", "TemplateLike", "TemplateRecord"]


class GraspLike(Protocol):
    """What is stored of a grasp (``robointel.learning.grasp.transfer.Grasp``)."""

    @property
    def centre(self) -> NDArray[np.float64]: ...  # noqa: D102
    @property
    def rotation(self) -> NDArray[np.float64]: ...  # noqa: D102
    @property
    def width(self) -> float: ...  # noqa: D102
    @property
    def name(self) -> str: ...  # noqa: D102


class TemplateLike(Protocol):
    """What is stored of a template (``robointel.learning.grasp.classify.Template``)."""

    @property
    def name(self) -> str: ...  # noqa: D102
    @property
    def category(self) -> str: ...  # noqa: D102
    @property
    def points(self) -> NDArray[np.float64]: ...  # noqa: D102
    @property
    def grasps(self) -> Sequence[GraspLike]: ...  # noqa: D102


@dataclass
class GraspRecord:
    """A stored grasp: ``centre`` (3,) m, ``rotation`` (3, 3), ``width`` m, ``name``."""

    centre: NDArray[np.float64]
    rotation: NDArray[np.float64]
    width: float
    name: str


@dataclass
class TemplateRecord:
    """A stored template: ``points`` (M, 3) m in the object frame and its grasps (plain data)."""

    name: str
    category: str
    points: NDArray[np.float64]
    grasps: list[GraspRecord] = field(default_factory=list)


class GraspDatabaseFile:
    """A grasp database file of plain records: :meth:`add`, :meth:`names`, :meth:`load`, :meth:`load_all`.

    The typed API (templates, grasps and the gripper model in and out) is
    :class:`robointel.learning.grasp_database.GraspDatabase`.

    Args:
        path: the ``.h5`` file (created on the first :meth:`add`).
        gripper: the gripper's fields (m, kg), stored in the root attributes when the file is created.
    """

    def __init__(self, path: str | Path, gripper: dict[str, Any] | None = None) -> None:
        self.path = Path(path)
        self._gripper = gripper

    def _open(self, mode: str) -> h5py.File:
        if mode == "r" and not self.path.exists():
            raise DataMissing(f"grasp database {self.path} does not exist; add templates first", value=str(self.path))
        try:
            f = h5py.File(self.path, mode)
        except OSError as exc:
            raise InvalidInput(f"{self.path} is not a readable HDF5 grasp database (corrupt, truncated or another "
                               f"format: {str(exc).splitlines()[0][:120]})", value=str(self.path)) from None
        if mode != "r" and "schema" not in f.attrs:
            f.attrs["schema"] = SCHEMA
            f.attrs["version"] = VERSION
            f.attrs["gripper"] = json.dumps(self._gripper or {})
            f.create_group("templates")
        if f.attrs.get("schema") != SCHEMA:
            f.close()
            raise InvalidInput(f"{self.path} is not a robointel grasp database (schema attribute missing)",
                               value=str(self.path))
        return f

    def add(self, template: TemplateLike, *, source: str = "") -> None:
        """Write one template and its grasps; a template of the same name is an error."""
        if not template.grasps:
            raise InvalidInput(f"template {template.name!r} has no taught grasps", value=template.name)
        with self._open("a") as f:
            tg = f["templates"]
            if template.name in tg:
                raise InvalidInput(f"template {template.name!r} already in {self.path}", value=template.name)
            g = tg.create_group(template.name)
            g.attrs["category"] = template.category
            g.attrs["source"] = source
            g.attrs["order"] = len(tg) - 1
            g.create_dataset("points", data=np.asarray(template.points, float))
            gg = g.create_group("grasps")
            gg.create_dataset("centre", data=np.array([x.centre for x in template.grasps]))
            gg.create_dataset("rotation", data=np.array([x.rotation for x in template.grasps]))
            gg.create_dataset("width", data=np.array([x.width for x in template.grasps], float))
            gg.create_dataset("names", data=np.array([x.name for x in template.grasps], dtype=h5py.string_dtype()))

    def names(self) -> list[str]:
        """Template names in insertion order."""
        with self._open("r") as f:
            tg = f["templates"]
            return sorted(tg.keys(), key=lambda k: int(tg[k].attrs["order"]))

    def load(self, name: str) -> TemplateRecord:
        """Read one template with its grasps."""
        with self._open("r") as f:
            if name not in f["templates"]:
                raise DataMissing(f"no template {name!r} in {self.path}", value=name)
            g = f["templates"][name]
            gg = g["grasps"]
            names = [n.decode() if isinstance(n, bytes) else str(n) for n in gg["names"][()]]
            grasps = [GraspRecord(c, R, float(w), n) for c, R, w, n in
                      zip(gg["centre"][()], gg["rotation"][()], gg["width"][()], names)]
            return TemplateRecord(name, str(g.attrs["category"]), g["points"][()], grasps)

    def load_all(self) -> list[TemplateRecord]:
        """All templates in insertion order."""
        return [self.load(n) for n in self.names()]

    def gripper(self) -> dict[str, Any]:
        """The gripper fields stored with the database ({} if none were given)."""
        with self._open("r") as f:
            return dict(json.loads(f.attrs["gripper"]))
