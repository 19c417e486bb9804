"""robointel.io.mbm: the MotionBenchMaker problem file read into typed problems and geometry shapes."""
from __future__ import annotations

import json

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.geometry import Box, Cylinder, Sphere
from robointel.geometry.rotations import quat_to_matrix
from robointel.io.mbm import MBM_FAMILIES, load_mbm_problems


@pytest.fixture
def problems_path(shared_data):
    return shared_data("mbm", "ur5", "problems.json")


@pytest.fixture
def raw(problems_path):
    return json.loads(problems_path.read_text())


def test_reads_all_families_and_valid_flags(problems_path):
    s = load_mbm_problems(problems_path)
    assert len(s) == 700
    assert set(s.families) == set(MBM_FAMILIES)
    assert s.robot == "ur5" and len(s.joint_names) == 6
    assert len(s.select()) == 689  # the published count of valid problems
    sub = s.select(per_family=3)
    assert len(sub) == 21 and all(sum(p.family == f for p in sub) == 3 for f in MBM_FAMILIES)
    assert all(p.valid for p in sub)
    one = s.select(families=["cage"], index=3)
    assert [p.name for p in one] == ["cage/3"]
    with pytest.raises(InvalidInput, match="unknown family 'kitchen'"):
        s.select(families=["kitchen"])


def test_shapes_follow_the_file_conventions(problems_path, raw):
    s = load_mbm_problems(problems_path)
    p = s.select(families=["bookshelf_small"])[0]
    r = next(q for q in raw["problems"]["bookshelf_small"] if q["index"] == p.index)
    np.testing.assert_allclose(p.start, r["start"])
    np.testing.assert_allclose(p.goals, r["goals"])
    boxes = [o for o in p.obstacles if isinstance(o, Box)]
    cyls = [o for o in p.obstacles if isinstance(o, Cylinder)]
    assert len(boxes) == len(r["box"]) and len(cyls) == len(r["cylinder"])
    assert len([o for o in p.obstacles if isinstance(o, Sphere)]) == len(r["sphere"])
    for b, rb in zip(boxes, r["box"]):
        x, y, z, w = rb["orientation_quat_xyzw"]
        R = quat_to_matrix([w, x, y, z])
        h = np.asarray(rb["half_extents"])
        np.testing.assert_allclose(b.size, 2 * h)  # half extents -> full size
        np.testing.assert_allclose(b.rotation, R, atol=1e-12)
        # a point 1 cm outside the box's local +x face (rotated into the world) is 1 cm away
        pt = np.asarray(rb["position"]) + R @ np.array([h[0] + 0.01, 0.0, 0.0])
        assert b.distance(pt)[0][0] == pytest.approx(0.01, abs=1e-9)
        assert b.name == rb["name"]
    for c, rc in zip(cyls, r["cylinder"]):
        x, y, z, w = rc["orientation_quat_xyzw"]
        axis = quat_to_matrix([w, x, y, z])[:, 2]  # MBM cylinders lie along their local z axis
        assert c.length == pytest.approx(rc["length"]) and c.radius == pytest.approx(rc["radius"])
        np.testing.assert_allclose(c.axis, axis, atol=1e-12)
        np.testing.assert_allclose(c.center, rc["position"], atol=1e-12)


def _write(tmp_path, data) -> str:
    f = tmp_path / "problems.json"
    f.write_text(json.dumps(data))
    return str(f)


def _tiny(raw) -> dict:
    p = json.loads(json.dumps(raw["problems"]["box"][0]))
    return {"robot": raw["robot"], "joints": raw["joints"], "problems": {"box": [p]}}


@pytest.mark.parametrize("edit, key", [
    (lambda d: d["problems"]["box"][0]["box"][0].update(colour="red"), "problems.box[0].box[0].colour"),
    (lambda d: d["problems"]["box"][0].update(extra=1), "problems.box[0].extra"),
    (lambda d: d.update(version=2), "<top>.version"),
    (lambda d: d["problems"]["box"][0]["box"][0].pop("half_extents"), "problems.box[0].box[0].half_extents"),
    (lambda d: d["problems"]["box"][0]["start"].pop(), "problems.box[0].start"),
    (lambda d: d["problems"]["box"][0]["box"][0].update(half_extents=[0.1, -0.1, 0.1]),
     "problems.box[0].box[0].half_extents"),
    (lambda d: d["problems"]["box"][0]["box"][0].update(orientation_euler_xyz=[0.0, 0.0, 0.5]),
     "problems.box[0].box[0].orientation_euler_xyz"),
    (lambda d: d["problems"]["box"][0].update(valid="yes"), "problems.box[0].valid"),
    (lambda d: d["problems"]["box"][0].update(goals=[]), "problems.box[0].goals"),
])
def test_malformed_file_names_file_and_key(tmp_path, raw, edit, key):
    d = _tiny(raw)
    edit(d)
    f = _write(tmp_path, d)
    with pytest.raises(InvalidInput) as e:
        load_mbm_problems(f)
    assert f in str(e.value) and key in str(e.value)


def test_nan_and_non_json_are_refused(tmp_path, raw):
    d = _tiny(raw)
    d["problems"]["box"][0]["goals"][0][2] = float("nan")
    f = _write(tmp_path, d)  # json.dumps writes NaN, which json.loads accepts: the reader must refuse it
    with pytest.raises(InvalidInput, match=r"problems\.box\[0\]\.goals\[0\].*NaN"):
        load_mbm_problems(f)
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(InvalidInput, match="not valid JSON"):
        load_mbm_problems(bad)
    with pytest.raises(InvalidInput, match="cannot read"):
        load_mbm_problems(tmp_path / "missing.json")
