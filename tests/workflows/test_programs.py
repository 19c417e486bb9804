"""Programs checked before they move (docs/guides/programs.md): refusals name the step and the key."""
import copy

import pytest
import yaml

from robointel.program.format import EXAMPLES

BASE = yaml.safe_load((EXAMPLES / "pick_place.yaml").read_text())
BASE["objects"] = [{"category": "cup", "seed": 1, "at": [0.5, 0.1]}]
BASE["steps"] = [{"move": "home", "name": "start"}, {"grasp": {"category": "cup"}, "name": "pick_part"},
                 {"place": {"at": [0.46, -0.36]}, "name": "place_part"}]
FAR = {"move": {"pose": {"xyz": [1.6, 0.0, 0.4], "rpy_deg": [0, 90, 0]}}, "name": "reach_far"}


def _edit(path, value):
    d = copy.deepcopy(BASE)
    *keys, last = path
    node = d
    for k in keys:
        node = node[k]
    if last == "insert":
        node.insert(1, value)
    else:
        node[last] = value
    return d


@pytest.mark.parametrize("edit, words", [
    ((("objects", 0, "at"), [0.26, -0.24]), ["step 1 ('pick_part', grasp)", "key 'at'", "inside fixture 'fixture_A'"]),
    ((("steps", "insert"), FAR), ["step 1 ('reach_far', move)", "key 'pose'", "outside the workspace"]),
    ((("steps", 2, "place"), {"at": [0.5, 0.9], "speed": 1}), ["step 2 ('place_part')", "place needs {at: [x, y]}"]),
], ids=["part_in_fixture", "pose_outside_workspace", "malformed_place"])
def test_a_bad_program_is_refused_before_anything_moves(robointel, tmp_path, edit, words):
    path = tmp_path / "job.yaml"
    path.write_text(yaml.safe_dump(_edit(*edit), sort_keys=False))
    r = robointel("run", str(path), "--report", str(tmp_path / "report"))
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1, r.stdout + r.stderr
    assert all(w in lines[0] for w in words), lines[0]
    assert not (tmp_path / "report").exists()  # nothing ran


def test_run_help_lists_the_built_in_programs(robointel):
    r = robointel("run", "--help")
    assert r.returncode == 0
    for name in ("example", "example_ycb", "moves", "moves_fanuc", "pick_place"):
        assert name in r.stdout
