"""set_io on a FANUC controller: numeric registers over RMI, other outputs refused before anything moves."""
import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from robointel.cli import app
from robointel.interface import open_robot
from robointel.outcome import Failure
from robointel.program import InterfaceCell, ProgramRejected, program_from_dict, run_program
from robointel.testing.emulator import EmulatorProcess, protocol_violations

HOME = [0.0, 0.3, -23.8, 0.0, -65.8, 0.0]
LEFT = [35.0, 56.3, -11.0, 0.0, -22.7, -0.6]
SCENE = {"robot": "lrmate200id7l", "d_min": 0.03, "limits": {"velocity_scale": 0.5, "acceleration_scale": 0.5}}
RMI_ERROR = 2556966  # "Invalid Port Number." in the RMI client's error table


def io_program(*steps):
    return {"name": "io", "scene": SCENE, "waypoints": {"home": {"q_deg": HOME}, "left": {"q_deg": LEFT}},
            "steps": [{"move": "home", "name": "start"}, *steps]}


def test_set_io_writes_numeric_registers_on_the_fanuc_emulator():
    prog = program_from_dict(io_program({"set_io": {"R[11]": 1, "R[12]": 2.5}, "name": "signal"},
                                        {"move": "left", "name": "reach"}, {"set_io": {"R[11]": 0}, "name": "done"}))
    with EmulatorProcess(np.radians(HOME)) as emu:
        with open_robot(emu.url) as arm:
            cell = InterfaceCell(arm)
            run = run_program(prog, cell)
            assert run.success, run.outcome
            # read back from the controller over RMI, not from the cell's own record
            assert arm.read_register(11) == 0.0 and arm.read_register(12) == 2.5
            assert cell.io == {"R[11]": 0.0, "R[12]": 2.5}
        violations = protocol_violations(emu.close())
    assert violations == []


def test_outputs_a_fanuc_controller_cannot_write_are_refused_before_moving(tmp_path):
    bad = program_from_dict(io_program({"move": "left", "name": "reach"},
                                       {"set_io": {"R[11]": 1, "DO[1]": 1}, "name": "lamp"}))
    grip = program_from_dict(io_program({"set_io": {"R[2]": 1}, "name": "poke_gripper"}))
    with EmulatorProcess(np.radians(HOME)) as emu:
        with open_robot(emu.url) as arm:
            refused = r"step 2 \('lamp', set_io\): output 'DO\[1\]'.*registers R\[n\]"
            with pytest.raises(ProgramRejected, match=refused) as err:
                run_program(bad, InterfaceCell(arm))
            assert err.value.value == {"step": 2, "name": "lamp", "output": "DO[1]"}
            assert arm.read_register(11) == 0.0  # nothing was written ...
        np.testing.assert_allclose(np.radians(emu.call("q_meas_deg"))[:6], np.radians(HOME), atol=1e-3)  # ... or moved
        with open_robot(emu.url, gripper=True) as arm:
            with pytest.raises(ProgramRejected, match=r"poke_gripper.*R\[1\]-R\[3\] belong to the gripper"):
                run_program(grip, InterfaceCell(arm))
        # the command line refuses the same program before moving
        path = tmp_path / "bad.yaml"
        path.write_text(yaml.safe_dump(io_program({"set_io": {"gripper": 1}, "name": "close"})))
        res = CliRunner().invoke(app, ["run", str(path), "--robot", emu.url, "--report", str(tmp_path / "rep")])
        out = " ".join(res.output.split())
        assert res.exit_code == 2 and "refused before moving" in out and "'gripper'" in out
        violations = protocol_violations(emu.close())
    assert violations == []


def test_a_register_write_the_controller_refuses_fails_the_step_and_stops():
    prog = program_from_dict(io_program({"set_io": {"R[20]": 1}, "name": "signal"}, {"move": "left", "name": "reach"}))
    with EmulatorProcess(np.radians(HOME)) as emu:
        with open_robot(emu.url) as arm:
            emu.call("arm_rmi_error", "FRC_WriteRegister", RMI_ERROR)  # injected: the controller refuses the write
            run = run_program(prog, InterfaceCell(arm))
            assert not run.success and run.steps[-1].name == "signal" and len(run.steps) == 2
            assert run.outcome.reason is Failure.FAULT and "R[20]" in run.outcome.detail
        np.testing.assert_allclose(np.radians(emu.call("q_meas_deg"))[:6], np.radians(HOME), atol=1e-3)
        violations = protocol_violations(emu.close())
    assert violations == []
