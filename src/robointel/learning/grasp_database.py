"""Grasp databases of taught templates: :class:`Template`, :class:`Grasp` and the gripper model in and out.

The file format (HDF5, one documented schema) is :mod:`robointel.io.grasp_db`; this module turns
its plain records into the grasp phase's types.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from robointel.io.grasp_db import GraspDatabaseFile, TemplateRecord
from robointel.learning.grasp.classify import Template
from robointel.learning.grasp.quality import ParallelGripper
from robointel.learning.grasp.transfer import Grasp

__all__ = ["GraspDatabase"]


class GraspDatabase:
    """A grasp database file: :meth:`add`, :meth:`names`, :meth:`load`, :meth:`load_all`, :meth:`gripper`.

    Args:
        path: the ``.h5`` file (created on the first :meth:`add`).
        gripper: stored in the root attributes when the file is created (default: the standard
            :class:`ParallelGripper`).
    """

    def __init__(self, path: str | Path, gripper: ParallelGripper | None = None) -> None:
        self.file = GraspDatabaseFile(path, dataclasses.asdict(gripper or ParallelGripper()))

    @property
    def path(self) -> Path:
        """The ``.h5`` file."""
        return self.file.path

    def add(self, template: Template, *, source: str = "") -> None:
        """Write one template and its grasps.

        Args:
            template: The taught template (its grasps in the object frame).
            source: Where it came from ("ycb:065-a_cups", "primitive", ...).

        Raises:
            InvalidInput: no taught grasps, or a template of that name is already stored.
        """
        self.file.add(template, source=source)

    def names(self) -> list[str]:
        """Template names in insertion order.

        Raises:
            DataMissing: the file does not exist.
        """
        return self.file.names()

    def load(self, name: str) -> Template:
        """Read one template with its grasps.

        Args:
            name: The template name.

        Returns:
            The validated template.

        Raises:
            DataMissing: no file or no such template.
        """
        return _template(self.file.load(name))

    def load_all(self) -> list[Template]:
        """All templates in insertion order (see :meth:`load`)."""
        return [_template(r) for r in self.file.load_all()]

    def gripper(self) -> ParallelGripper:
        """The gripper model stored with the database (the default one if none was stored)."""
        return ParallelGripper(**self.file.gripper())


def _template(r: TemplateRecord) -> Template:
    """Validated :class:`Template` of a stored record."""
    return Template(r.name, r.category, r.points, [Grasp(g.centre, g.rotation, g.width, g.name) for g in r.grasps])
