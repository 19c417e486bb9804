"""Files only: reference data, trajectories, scene YAML, demonstration and grasp-database HDF5.

io imports no phase: each phase turns these plain records into its own types
(:mod:`robointel.planning.scene`, :mod:`robointel.learning.demonstration`,
:mod:`robointel.learning.grasp_database`).
"""

from robointel.io.demonstrations import DemonstrationFile, DemonstrationRecord
from robointel.io.grasp_db import GraspDatabaseFile, GraspRecord, TemplateRecord
from robointel.io.reference import data_path
from robointel.io.scene import read_scene_file, write_scene_file
from robointel.io.trajectory import load_trajectory, save_trajectory

__all__ = [
    "DemonstrationFile", "DemonstrationRecord", "GraspDatabaseFile", "GraspRecord", "TemplateRecord", "data_path",
    "load_trajectory", "read_scene_file", "save_trajectory", "write_scene_file",
]
