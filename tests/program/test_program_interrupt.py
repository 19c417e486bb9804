"""Ctrl-C during a program run, wherever it lands (in a step's motion, or in a callback between two
steps): the run ends as interrupted, the robot stopped, and the result names the interrupted step."""
from __future__ import annotations

import pytest

from robointel.program import SimCell, load_program, run_program


@pytest.fixture(scope="module")
def moves():
    prog = load_program("moves")
    return prog, prog.initial_configuration(0)


def test_ctrl_c_in_the_callback_after_a_step_interrupts_the_next(moves):
    prog, q0 = moves
    calls = []

    def on_step(result):
        calls.append(result.index)
        if len(calls) == 1:
            raise KeyboardInterrupt

    run = run_program(prog, SimCell(prog, q0), on_step=on_step)
    assert run.interrupted and run.failed_step == 1
    assert [r.index for r in run.steps] == [0, 1]
    assert run.steps[0].outcome.success and not run.steps[1].outcome.success
    assert "interrupted" in run.steps[1].outcome.detail


def test_ctrl_c_before_the_first_step_ends_the_run_at_it(moves):
    prog, q0 = moves

    def progress(i, name):
        raise KeyboardInterrupt

    run = run_program(prog, SimCell(prog, q0), progress=progress)
    assert run.interrupted and run.failed_step == 0 and len(run.steps) == 1
    assert not run.steps[0].outcome.success
