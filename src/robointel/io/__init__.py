"""Files only: reference data, trajectories, scene YAML, demonstration and grasp-database HDF5.

io imports no phase: each phase turns these plain records into its own types
(:mod:`robointel.planning.scene`, :mod:`robointel.learning.demonstration`,
:mod:`robointel.learning.grasp_database`). The names below are imported from their modules on first
access, so reading a scene or a trajectory does not load h5py.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robointel._lazy import lazy_exports

if TYPE_CHECKING:
    from robointel.io.demonstrations import DemonstrationFile, DemonstrationRecord
    from robointel.io.grasp_db import GraspDatabaseFile, GraspRecord, TemplateRecord
    from robointel.io.reference import data_path
    from robointel.io.scene import read_scene_file, write_scene_file
    from robointel.io.trajectory import load_trajectory, save_trajectory

_EXPORTS = {
    "DemonstrationFile": "robointel.io.demonstrations",
    "DemonstrationRecord": "robointel.io.demonstrations",
    "GraspDatabaseFile": "robointel.io.grasp_db",
    "GraspRecord": "robointel.io.grasp_db",
    "TemplateRecord": "robointel.io.grasp_db",
    "data_path": "robointel.io.reference",
    "read_scene_file": "robointel.io.scene",
    "write_scene_file": "robointel.io.scene",
    "load_trajectory": "robointel.io.trajectory",
    "save_trajectory": "robointel.io.trajectory",
}

__all__ = [
    "DemonstrationFile", "DemonstrationRecord", "GraspDatabaseFile", "GraspRecord", "TemplateRecord", "data_path",
    "load_trajectory", "read_scene_file", "save_trajectory", "write_scene_file",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
