"""The readers of files a user brings -- task programs, scenes, batch sweeps, LeRobot and robomimic
datasets -- under mutated and garbled files: a robointel error or a result, never another exception."""
from __future__ import annotations

import json
import shutil

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from robointel.batch.spec import load_sweep
from robointel.errors import RobointelError
from robointel.io.lerobot import read_lerobot, write_lerobot
from robointel.io.robomimic import read_robomimic, write_robomimic
from robointel.planning.scene import SCENES, load_scene
from robointel.program.format import load_program
from robointel.testing.corrupt_data import device_episodes

from .conftest import mutated

PROGRAM = {"format": "robointel.program/1", "name": "p", "scene": "table71",
           "waypoints": {"a": {"q_deg": [0, 10, -20, 0, -60, 0]}, "b": {"pose": {"xyz": [0.45, 0.1, 0.3],
                                                                                 "rpy_deg": [0, 90, 0]}}},
           "steps": [{"move": "a"}, {"wait": 0.1}, {"set_io": {"gripper": 1}}, {"move": "b", "name": "to_b"},
                     {"path": {"points": [[0.45, 0.1, 0.3], [0.45, -0.1, 0.3]], "speed": 0.1}},
                     {"grasp": {"category": "cup"}}, {"place": {"at": [0.45, -0.3]}}],
           "objects": [{"category": "cup", "seed": 3, "at": [0.5, 0.1], "yaw_deg": 30}]}
SCENE = yaml.safe_load((SCENES / "table71.yaml").read_text())
SWEEP = {"name": "s", "tasks": [{"kind": "insertion", "seeds": [0, 1], "params": {"clearance_mm": 0.5}}]}


def _refused_or_read(fn, path):
    try:
        fn(path)
    except RobointelError as exc:
        assert str(exc)


def _dump(doc) -> str:
    try:
        return yaml.safe_dump(doc, allow_unicode=True)
    except yaml.YAMLError:
        return json.dumps(doc, default=str)


@settings(max_examples=25)
@given(doc=mutated(PROGRAM))
def test_programs(tmp_path_factory, doc):
    p = tmp_path_factory.mktemp("prog") / "p.yaml"
    p.write_text(_dump(doc), encoding="utf-8")
    _refused_or_read(load_program, p)


@settings(max_examples=25)
@given(doc=mutated(SCENE))
def test_scenes(tmp_path_factory, doc):
    p = tmp_path_factory.mktemp("scene") / "s.yaml"
    p.write_text(_dump(doc), encoding="utf-8")
    _refused_or_read(load_scene, p)


@given(doc=mutated(SWEEP))
def test_batch_sweeps(tmp_path_factory, doc):
    p = tmp_path_factory.mktemp("sweep") / "s.yaml"
    p.write_text(_dump(doc), encoding="utf-8")
    _refused_or_read(load_sweep, p)


@given(raw=st.binary(max_size=300))
def test_garbage_bytes_as_program_scene_or_sweep(tmp_path_factory, raw):
    p = tmp_path_factory.mktemp("raw") / "x.yaml"
    p.write_bytes(raw)
    for fn in (load_program, load_scene, load_sweep):
        _refused_or_read(fn, p)


@pytest.fixture(scope="module")
def datasets(tmp_path_factory):
    d = tmp_path_factory.mktemp("ds")
    eps = device_episodes(2, 20)
    return write_lerobot(d / "lerobot", eps), write_robomimic(d / "r.hdf5", eps)


@given(info=mutated({"codebase_version": "v3.0", "fps": 100, "robot_type": "", "total_episodes": 2,
                     "features": {"observation.state": {"dtype": "float64", "shape": [12], "names": None},
                                  "action": {"dtype": "float64", "shape": [6], "names": None}}}),
       cut=st.integers(0, 4000), flip=st.integers(0, 4000), byte=st.integers(0, 255),
       which=st.sampled_from(["data/chunk-000/file-000.parquet", "meta/episodes/chunk-000/file-000.parquet"]))
def test_lerobot_datasets(datasets, tmp_path_factory, info, cut, flip, byte, which):
    root = tmp_path_factory.mktemp("lr") / "ds"
    shutil.copytree(datasets[0], root)
    full = json.loads((root / "meta/info.json").read_text())
    (root / "meta/info.json").write_text(json.dumps({**full, **info} if isinstance(info, dict) else info,
                                                    default=str))
    f = root / which
    raw = bytearray(f.read_bytes())
    if flip < len(raw):
        raw[flip] = byte
    f.write_bytes(bytes(raw[: max(cut, 1)] if cut < len(raw) else raw))
    _refused_or_read(read_lerobot, root)


@given(cut=st.integers(0, 40000), flips=st.lists(st.tuples(st.integers(0, 40000), st.integers(0, 255)),
                                                 max_size=4))
def test_robomimic_files(datasets, tmp_path_factory, cut, flips):
    p = tmp_path_factory.mktemp("rm") / "r.hdf5"
    raw = bytearray(datasets[1].read_bytes())
    for at, b in flips:
        if at < len(raw):
            raw[at] = b
    p.write_bytes(bytes(raw[:cut]) if cut < len(raw) else bytes(raw))
    _refused_or_read(read_robomimic, p)
