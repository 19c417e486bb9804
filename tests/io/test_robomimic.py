"""robomimic-style HDF5 export/import: layout and lossless round trip."""
from __future__ import annotations

import h5py
import numpy as np
import pytest

from robointel.errors import DataMissing, InvalidInput
from robointel.io.episode import Episode
from robointel.io.robomimic import read_robomimic, write_robomimic


def test_round_trip_is_lossless_and_the_layout_is_robomimic(tmp_path, make_wave):
    other = Episode.create(np.arange(10) / 50.0, {"state": np.arange(30.0).reshape(10, 3)}, np.ones((10, 2)),
                           kind="other", name="three joints")
    eps = [make_wave(40, 0), other]  # different observation sets may share one file
    path = write_robomimic(tmp_path / "demos.hdf5", eps)
    back = read_robomimic(path)
    assert len(back) == 2 and all(a.equals(b) for a, b in zip(eps, back))
    with h5py.File(path) as f:
        assert f["data"].attrs["total"] == 50 and sorted(f["data"]) == ["demo_0", "demo_1"]
        g = f["data/demo_0"]
        assert g.attrs["num_samples"] == 40 and g["actions"].shape == (40, 2)
        assert sorted(g["obs"]) == ["label", "state", "velocity"]
        assert np.array_equal(g["next_obs/state"][:-1], g["obs/state"][1:])
        assert g["dones"][-1] == 1 and g["dones"][:-1].sum() == 0
        assert [d.decode() for d in f["mask/all"][()]] == ["demo_0", "demo_1"]


def test_foreign_file_without_robointel_attributes(tmp_path):
    path = tmp_path / "plain.hdf5"
    with h5py.File(path, "w") as f:
        f.create_dataset("data/demo_0/obs/robot0_eef_pos", data=np.zeros((6, 3)))
        f.create_dataset("data/demo_0/actions", data=np.zeros((6, 7)))
    (ep,) = read_robomimic(path)
    assert ep.observations["state"].shape == (6, 3) and ep.name == "demo_0" and np.allclose(np.diff(ep.t), 1.0)


def test_bad_files(tmp_path):
    with pytest.raises(DataMissing):
        read_robomimic(tmp_path / "missing.hdf5")
    with h5py.File(tmp_path / "empty.hdf5", "w"):
        pass
    with pytest.raises(InvalidInput):
        read_robomimic(tmp_path / "empty.hdf5")
    with pytest.raises(InvalidInput):
        write_robomimic(tmp_path / "x.hdf5", [])
