import hashlib

import numpy as np
import pytest

from robointel.batch import TaskSpec, load_sweep, sweep_from_dict
from robointel.errors import InvalidInput, SweepFileError


def test_hash_is_stable_and_ignores_seed_and_key_order():
    a = TaskSpec("insertion", 3, {"controller": "impedance", "gains": {"rot_stiffness": 300, "lat": 1.5}})
    b = TaskSpec("insertion", 7, {"gains": {"lat": 1.5, "rot_stiffness": 300}, "controller": "impedance"})
    assert a.spec_hash == b.spec_hash
    assert len(a.spec_hash) == 16 and int(a.spec_hash, 16) >= 0
    # the hash is SHA-256 of the canonical JSON (sorted keys, no spaces): the same on every machine
    canonical = b'{"kind":"synthetic","params":{"p_success":0.5}}'
    assert TaskSpec("synthetic", 9, {"p_success": 0.5}).spec_hash == hashlib.sha256(canonical).hexdigest()[:16]
    assert TaskSpec("synthetic", 0, {"p_success": 0.5}).spec_hash != TaskSpec("synthetic", 0).spec_hash
    assert a.key == (a.spec_hash, 3)
    assert TaskSpec.from_dict(a.to_dict()) == a


def test_numpy_scalars_are_canonicalised():
    a = TaskSpec("synthetic", 0, {"p_success": np.float64(0.5), "n": np.int64(3)})
    b = TaskSpec("synthetic", 0, {"p_success": 0.5, "n": 3})
    assert a.spec_hash == b.spec_hash


@pytest.mark.parametrize("bad", [
    dict(kind="", seed=0), dict(kind="synthetic", seed=-1), dict(kind="synthetic", seed=1.5),
    dict(kind="synthetic", seed=0, params={"x": float("nan")}), dict(kind="synthetic", seed=0, params={"x": object()}),
    dict(kind="synthetic", seed=0, params={1: 2}),
])
def test_bad_specs_raise(bad):
    with pytest.raises(InvalidInput):
        TaskSpec(**bad)


def test_sweep_expansion(tmp_path):
    f = tmp_path / "s.yaml"
    f.write_text("tasks:\n"
                 "  - kind: synthetic\n    seeds: {start: 5, count: 3}\n    grid: {p_success: [0.1, 0.9]}\n"
                 "    params: {work_s: 0}\n    category: c\n"
                 "  - kind: insertion\n    seeds: [1, 4]\n")
    specs = load_sweep(f)
    assert len(specs) == 8
    assert [s.seed for s in specs[:3]] == [5, 6, 7]
    assert {s.params["p_success"] for s in specs[:6]} == {0.1, 0.9}
    assert specs[0].category == "c" and specs[0].params["work_s"] == 0
    assert [s.seed for s in specs[6:]] == [1, 4]


@pytest.mark.parametrize("d", [
    {}, {"tasks": []}, {"tasks": [{"seeds": 3}]}, {"tasks": [{"kind": "synthetic", "seeds": "x"}]},
    {"tasks": [{"kind": "synthetic", "grid": {"a": []}}]}, {"tasks": [{"kind": "synthetic", "oops": 1}]},
    {"tasks": [{"kind": "synthetic", "seeds": 2}, {"kind": "synthetic", "seeds": [1]}]},  # a repeated key
])
def test_bad_sweeps_raise(d):
    with pytest.raises(SweepFileError):
        sweep_from_dict(d)


def test_missing_or_broken_sweep_file(tmp_path):
    with pytest.raises(SweepFileError, match="does not exist"):
        load_sweep(tmp_path / "nope.yaml")
    (tmp_path / "b.yaml").write_text("tasks: [\n")
    with pytest.raises(SweepFileError, match="not valid YAML"):
        load_sweep(tmp_path / "b.yaml")
