"""Task programs: teaching, skills and planning joined into one job (``robointel run PROGRAM.yaml``).

A program (:mod:`robointel.program.format`) is checked as a whole before anything moves
(:func:`check_program`) and then run step by step on a robot cell (:func:`run_program`).
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
from robointel.program.runner import Cell, ProgramRun, SimCell, StepResult, run_program

__all__ = [
    "FORMAT", "STEP_KINDS", "Cell", "GraspCell", "Program", "ProgramCheck", "ProgramRejected", "ProgramRun", "SimCell",
    "Step", "StepPlan", "StepResult", "TableObject", "Target", "check_program", "load_program", "program_from_dict",
    "run_program",
]
