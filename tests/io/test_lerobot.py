"""LeRobot v3 export/import: layout, metadata, lossless round trip, lerobot-doctor finds no failure."""
from __future__ import annotations

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from robointel.errors import DataMissing, InvalidInput, ShapeError
from robointel.io.episode import Episode
from robointel.io.lerobot import read_lerobot, write_lerobot


def test_round_trip_is_lossless_and_the_layout_is_v3(tmp_path, make_wave):
    eps = [make_wave(120, 0), make_wave(150, 1, task="other"), make_wave(130, 2)]
    root = write_lerobot(tmp_path / "ds", eps, robot_type="scara2")
    back = read_lerobot(root)
    assert len(back) == 3 and all(a.equals(b) for a, b in zip(eps, back))
    assert back[0].observations["label"].dtype == np.int64
    info = json.loads((root / "meta" / "info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["fps"] == 50 and info["total_frames"] == 400
    assert info["total_episodes"] == 3 and info["total_tasks"] == 2 and info["splits"] == {"train": "0:3"}
    assert info["data_path"] == "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
    assert info["features"]["observation.state"] == {"dtype": "float64", "shape": [2], "names": ["j1", "j2"]}
    assert info["features"]["timestamp"]["dtype"] == "float32"
    data = pq.read_table(root / "data" / "chunk-000" / "file-000.parquet")
    assert data.column("index").to_pylist() == list(range(400))
    assert data.column("frame_index").to_pylist()[120:123] == [0, 1, 2]
    assert np.allclose(data.column("timestamp").to_numpy()[:3], [0.0, 0.02, 0.04])
    meta = pq.read_table(root / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pylist()
    assert [m["dataset_from_index"] for m in meta] == [0, 120, 270] and meta[1]["tasks"] == ["other"]
    assert meta[0]["stats/observation.state/count"] == [120]
    tasks = pq.read_table(root / "meta" / "tasks.parquet")
    assert tasks.column("task").to_pylist() == ["wave", "other"]
    assert json.loads(tasks.schema.metadata[b"pandas"])["index_columns"] == ["task"]  # the task is the index
    stats = json.loads((root / "meta" / "stats.json").read_text())
    state = np.concatenate([e.observations["state"] for e in eps])
    assert np.allclose(stats["observation.state"]["mean"], state.mean(0))
    assert np.allclose(stats["action"]["q99"], np.quantile(np.concatenate([e.action for e in eps]), 0.99, axis=0))


def test_lerobot_doctor_finds_no_failure(tmp_path, make_wave, doctor):
    root = write_lerobot(tmp_path / "ds", [make_wave(120, 0), make_wave(150, 1)])
    report, fails = doctor(root)
    assert report["format_version"] == "v3" and report["total_frames"] == 270
    assert fails == []


def test_bad_exports_are_refused(tmp_path, make_wave):
    with pytest.raises(InvalidInput):
        write_lerobot(tmp_path / "a", [])
    other = Episode.create(np.arange(10) / 50.0, {"state": np.zeros((10, 3))}, np.zeros((10, 2)))
    with pytest.raises(InvalidInput, match="one schema"):
        write_lerobot(tmp_path / "b", [make_wave(20, 0), other])
    with pytest.raises(InvalidInput, match="different rates"):
        write_lerobot(tmp_path / "c", [make_wave(20, 0), make_wave(20, 1, hz=30.0)])
    write_lerobot(tmp_path / "d", [make_wave(20, 0)])
    with pytest.raises(InvalidInput, match="exists"):
        write_lerobot(tmp_path / "d", [make_wave(20, 0)])
    with pytest.raises(DataMissing):
        read_lerobot(tmp_path / "nothing")


def test_episode_validation():
    t = np.arange(5) * 0.1
    with pytest.raises(InvalidInput):
        Episode.create(t, {"pose": np.zeros((5, 2))}, np.zeros((5, 1)))            # no state
    with pytest.raises(InvalidInput):
        Episode.create(t[::-1], {"state": np.zeros((5, 2))}, np.zeros((5, 1)))     # time runs backwards
    with pytest.raises(InvalidInput):
        Episode.create(t, {"state": np.full((5, 2), np.nan)}, np.zeros((5, 1)))    # NaN
    with pytest.raises(ShapeError):
        Episode.create(t, {"state": np.zeros((4, 2))}, np.zeros((5, 1)))           # wrong length
    with pytest.raises(InvalidInput):
        Episode.create(t, {"state": np.zeros((5, 2)), "a.b": np.zeros(5)}, np.zeros((5, 1)))
    with pytest.raises(ShapeError):
        Episode.create(t, {"state": np.zeros((5, 2))}, np.zeros((5, 1)), names={"state": ("only one",)})


def test_large_exports_are_split_into_files(tmp_path, make_wave, doctor):
    eps = [make_wave(100, s) for s in range(3)]
    root = write_lerobot(tmp_path / "ds", eps, data_file_mb=0.01)  # ~16 kB per episode: one file each
    files = sorted((root / "data" / "chunk-000").glob("file-*.parquet"))
    assert [f.name for f in files] == ["file-000.parquet", "file-001.parquet", "file-002.parquet"]
    meta = pq.read_table(root / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pylist()
    assert [m["data/file_index"] for m in meta] == [0, 1, 2]
    assert all(a.equals(b) for a, b in zip(eps, read_lerobot(root)))
    assert doctor(root)[1] == []
