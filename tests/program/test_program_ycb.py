"""A YCB scan as a program's part: the example cell picks and places the scanned screwdriver."""
import numpy as np
import pytest
import yaml

from robointel.errors import InvalidInput
from robointel.io.reference import data_root
from robointel.program import GraspCell, ProgramRejected, check_program, load_program, program_from_dict, run_program

needs_data = pytest.mark.skipif(data_root() is None or not (data_root() / "objects" / "ycb").is_dir(),
                                reason="the YCB scans (../shared/data/objects/ycb) are not here")


def ycb_program(name):
    d = yaml.safe_load(open(load_program("example_ycb").source))
    d["objects"][0]["ycb"] = name
    d["steps"] = d["steps"][:-1]  # pick, carry, place, home (the insertion is tested with the example)
    return program_from_dict(d)


def test_a_ycb_object_is_named_by_its_scan_and_refused_before_moving_when_missing():
    prog = load_program("example_ycb")
    assert prog.objects[0].ycb == "044_flat_screwdriver" and prog.to_dict()["objects"][0]["ycb"] == prog.objects[0].ycb
    with pytest.raises(InvalidInput, match="ycb must be the name"):
        program_from_dict({**ycb_program("x").to_dict(), "objects": [{"category": "long_tool", "ycb": "../etc"}]})
    missing = ycb_program("999_no_such_scan")
    with pytest.raises(ProgramRejected, match=r"object 0 \(long_tool\).*'999_no_such_scan' is not available") as err:
        check_program(missing, missing.initial_configuration())
    assert err.value.value == {"object": 0, "ycb": "999_no_such_scan"}


@needs_data
def test_the_example_cell_picks_and_places_the_scanned_screwdriver():
    prog = ycb_program("044_flat_screwdriver")
    cell = GraspCell(prog, prog.initial_configuration(), seed=2000)
    run = run_program(prog, cell)
    assert run.success, run.outcome
    at = prog.steps[prog.index("place_part")].args["at"]
    p = cell.object_position(0)
    assert np.hypot(p[0] - at[0], p[1] - at[1]) < 0.03 and p[2] < 0.03  # resting on the table at the target
    assert cell.held is None and np.max(np.abs(cell.q - prog.waypoints["home"])) < 0.02
