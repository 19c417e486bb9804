"""Task programs: teaching, skills and planning joined into one job (``robointel run PROGRAM.yaml``).

A program (:mod:`robointel.program.format`) is checked as a whole before anything moves
(:func:`check_program`) and then run step by step on a robot cell (:func:`run_program`): the simulated
cell (:class:`SimCell`, :class:`GraspCell`) or a robot interface (:class:`InterfaceCell`).
"""

from robointel.program.check import ProgramCheck, ProgramRejected, StepPlan, check_program
from robointel.program.format import (
    FORMAT,
    STEP_KINDS,
    Program,
    Step,
    TableObject,
    Target,
    load_program,
    program_from_dict,
)
from robointel.program.grasp_cell import GraspCell
from robointel.program.guide_step import PushOperator, run_guide
from robointel.program.interface_cell import InterfaceCell
from robointel.program.motion import CellPlanner
from robointel.program.runner import Cell, ProgramRun, SimCell, StepResult, run_program
from robointel.program.skill_file import load_skill, save_skill
from robointel.program.teaching import path_step_from_guided, program_from_teleop

__all__ = [
    "FORMAT", "STEP_KINDS", "Cell", "CellPlanner", "GraspCell", "InterfaceCell", "Program", "ProgramCheck",
    "ProgramRejected", "ProgramRun", "PushOperator", "SimCell", "Step", "StepPlan", "StepResult", "TableObject",
    "Target", "check_program", "load_program", "load_skill", "path_step_from_guided", "program_from_dict",
    "program_from_teleop", "run_guide", "run_program", "save_skill",
]
