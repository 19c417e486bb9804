"""Corrupt dataset files for the import checks: LeRobot v3 folders and robomimic files broken one way each.

Each case starts from a valid dataset of device demonstrations (:func:`device_episodes`) and breaks
one thing a real file can get wrong: a truncated or foreign file, a missing or ill-typed field,
impossible values (``fps: 0``), duplicated episodes, values that are not finite, times that do not
increase. A reader meets its contract on a case when it raises a
:class:`~robointel.errors.RobointelError` naming the file (and nothing else escapes).
"""
from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from robointel.io.episode import Episode
from robointel.io.lerobot import write_lerobot
from robointel.io.robomimic import write_robomimic
from robointel.learning.demonstration import Demonstration
from robointel.learning.demonstration_episode import demonstration_to_episode

__all__ = ["corrupt_lerobot", "corrupt_robomimic", "device_episodes"]

_DATA = Path("data/chunk-000/file-000.parquet")
_EPISODES = Path("meta/episodes/chunk-000/file-000.parquet")
_INFO = Path("meta/info.json")


def device_episodes(count: int = 3, frames: int = 40, *, seed: int = 0) -> list[Episode]:
    """``count`` device demonstrations (a tool moving along x, a small wrench) as episodes, 100 Hz.

    Args:
        count: number of episodes.
        frames: frames per episode.
        seed: seed of the wrench noise.

    Returns:
        The episodes, named ``demo_0``, ``demo_1``, ...
    """
    rng = np.random.default_rng(seed)
    out = []
    for k in range(count):
        t = np.arange(frames) * 0.01
        pose = np.tile(np.eye(4), (frames, 1, 1))
        pose[:, 0, 3] = 0.4 + 0.001 * np.arange(frames) + 0.01 * k
        wrench = rng.normal(0.0, 0.5, (frames, 6))
        d = Demonstration.create(t, pose, wrench, None, device="hdd", name=f"demo_{k}")
        out.append(demonstration_to_episode(d))
    return out


# ----------------------------------------------------------------------------- LeRobot v3
def _rewrite(path: Path, edit: Callable[[pa.Table], pa.Table]) -> None:
    pq.write_table(edit(pq.read_table(path)), path)


def _info(root: Path, edit: Callable[[dict], object]) -> None:
    info = json.loads((root / _INFO).read_text())
    out = edit(info)
    (root / _INFO).write_text(json.dumps(info if out is None else out))


def _set_column(table: pa.Table, name: str, values: pa.Array) -> pa.Table:
    return table.set_column(table.column_names.index(name), name, values)


def _lerobot_edits() -> dict[str, Callable[[Path], object]]:
    def truncate(rel: Path) -> Callable[[Path], object]:
        def f(root: Path) -> None:
            raw = (root / rel).read_bytes()
            (root / rel).write_bytes(raw[: len(raw) // 2])
        return f

    def drop_col(rel: Path, col: str) -> Callable[[Path], object]:
        return lambda root: _rewrite(root / rel, lambda t: t.drop_columns([col]))

    def info_set(key: str, value: object) -> Callable[[Path], object]:
        return lambda root: _info(root, lambda i: i.__setitem__(key, value))

    def ep_col(col: str, fn: Callable[[list], list]) -> Callable[[Path], object]:
        return lambda root: _rewrite(root / _EPISODES, lambda t: _set_column(
            t, col, pa.array(fn(t.column(col).to_pylist()))))

    def duplicate_rows(root: Path) -> None:
        _rewrite(root / _EPISODES, lambda t: pa.concat_tables([t, t.slice(0, 1)]))

    def nan_state(root: Path) -> None:
        def edit(t: pa.Table) -> pa.Table:
            col = t.column("observation.state").combine_chunks()
            flat = col.flatten().to_numpy(zero_copy_only=False).copy()
            flat[5] = np.nan
            return _set_column(t, "observation.state", pa.FixedSizeListArray.from_arrays(pa.array(flat),
                                                                                        col.type.list_size))
        _rewrite(root / _DATA, edit)

    def time_backwards(root: Path) -> None:
        def edit(t: pa.Table) -> pa.Table:
            v = t.column("time").to_numpy().copy()
            v[3], v[4] = v[4], v[3]
            return _set_column(t, "time", pa.array(v))
        _rewrite(root / _DATA, edit)

    def index_repeated(root: Path) -> None:
        def edit(t: pa.Table) -> pa.Table:
            v = t.column("index").to_numpy().copy()
            v[7] = v[6]
            return _set_column(t, "index", pa.array(v))
        _rewrite(root / _DATA, edit)

    def state_as_text(root: Path) -> None:
        _rewrite(root / _DATA, lambda t: _set_column(t, "observation.state",
                                                     pa.array(["x"] * t.num_rows, pa.string())))

    def action_ragged(root: Path) -> None:
        def edit(t: pa.Table) -> pa.Table:
            rows = t.column("action").to_pylist()
            rows[2] = rows[2][:3]
            return _set_column(t, "action", pa.array(rows, pa.list_(pa.float64())))
        _rewrite(root / _DATA, edit)

    def second_file_other_schema(root: Path) -> None:
        other = root / "data" / "chunk-000" / "file-001.parquet"
        pq.write_table(pa.table({"x": pa.array([1, 2, 3])}), other)

    def empty_data_dir(root: Path) -> None:
        (root / _DATA).unlink()

    def no_episode_files(root: Path) -> None:
        (root / _EPISODES).unlink()

    return {
        "info.json not JSON": lambda root: (root / _INFO).write_text("{codebase_version: v3.0,"),
        "info.json a list": lambda root: _info(root, lambda i: [i]),
        "info.json binary": lambda root: (root / _INFO).write_bytes(bytes(range(256))),
        "codebase_version v2.1": info_set("codebase_version", "v2.1"),
        "fps 0": info_set("fps", 0),
        "fps negative": info_set("fps", -30),
        "fps a string": info_set("fps", "fast"),
        "fps null": info_set("fps", None),
        "features a list": info_set("features", ["observation.state"]),
        "no observation.state feature": lambda root: _info(root, lambda i: i["features"].pop("observation.state")
                                                           and None),
        "data parquet truncated": truncate(_DATA),
        "data parquet is text": lambda root: (root / _DATA).write_text("frame,index\n1,2\n"),
        "no data file": empty_data_dir,
        "episodes parquet truncated": truncate(_EPISODES),
        "no episodes file": no_episode_files,
        "episodes without dataset_from_index": drop_col(_EPISODES, "dataset_from_index"),
        "episode rows duplicated": duplicate_rows,
        "two episodes share frames": ep_col("dataset_from_index", lambda v: [v[0], v[1] - 5, *v[2:]]),
        "episode beyond the data": ep_col("dataset_to_index", lambda v: [*v[:-1], v[-1] + 100]),
        "episode from > to": ep_col("dataset_to_index", lambda v: [0, *v[1:]]),
        "episode_index as text": ep_col("episode_index", lambda v: [str(x) for x in v]),
        "robointel/meta not JSON": ep_col("robointel/meta", lambda v: ["{not json"] * len(v)),
        "robointel/meta a list": ep_col("robointel/meta", lambda v: ["[1, 2]"] * len(v)),
        "data without index": drop_col(_DATA, "index"),
        "data without action": drop_col(_DATA, "action"),
        "data without observation.state": drop_col(_DATA, "observation.state"),
        "data without time and timestamp": lambda root: _rewrite(root / _DATA,
                                                                 lambda t: t.drop_columns(["time", "timestamp"])),
        "NaN in observation.state": nan_state,
        "time not increasing": time_backwards,
        "frame index repeated": index_repeated,
        "observation.state as text": state_as_text,
        "action of mixed widths": action_ragged,
        "second data file of another schema": second_file_other_schema,
    }


def corrupt_lerobot(folder: str | Path, episodes: list[Episode] | None = None) -> list[tuple[str, Path]]:
    """Write one valid LeRobot v3 dataset per corruption and break it; returns ``(case, folder)`` pairs.

    Args:
        folder: where the datasets go (created).
        episodes: what the datasets hold (default: :func:`device_episodes`).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    base = write_lerobot(folder / "valid", episodes or device_episodes(), overwrite=True)
    out = []
    for k, (case, edit) in enumerate(_lerobot_edits().items()):
        root = folder / f"lerobot_{k:02d}"
        if root.exists():
            shutil.rmtree(root)
        shutil.copytree(base, root)
        edit(root)
        out.append((case, root))
    return out


# ----------------------------------------------------------------------------- robomimic
def _robomimic_edits() -> dict[str, Callable[[Path], object]]:
    def h5(edit: Callable[[h5py.File], object]) -> Callable[[Path], object]:
        def f(path: Path) -> None:
            with h5py.File(path, "a") as fh:
                edit(fh)
        return f

    def replace(name: str, data: object) -> Callable[[h5py.File], object]:
        def f(fh: h5py.File) -> None:
            del fh[name]
            fh.create_dataset(name, data=data)
        return f

    def truncate(path: Path) -> None:
        raw = path.read_bytes()
        path.write_bytes(raw[: len(raw) // 2])

    def demo_dataset(fh: h5py.File) -> None:
        fh["data"].create_dataset("demo_9", data=np.zeros(3))

    def obs_group_inside(fh: h5py.File) -> None:
        del fh["data/demo_0/obs/state"]
        fh["data/demo_0/obs"].create_group("state")

    def nan_action(fh: h5py.File) -> None:
        a = fh["data/demo_1/actions"][()]
        a[3, 2] = np.nan
        replace("data/demo_1/actions", a)(fh)

    def set_attr(node: str, key: str, value: object) -> Callable[[h5py.File], object]:
        return lambda fh: fh[node].attrs.__setitem__(key, value)

    n = 40
    return {
        "a text file": lambda p: p.write_text("not an HDF5 file\n"),
        "truncated": truncate,
        "no data group": h5(lambda fh: fh.move("data", "stuff")),
        "env_args not JSON": h5(set_attr("data", "env_args", "{env_name: x")),
        "env_args a list": h5(set_attr("data", "env_args", "[1, 2]")),
        "env_kwargs a list": h5(set_attr("data", "env_args", json.dumps({"env_kwargs": [1]}))),
        "fps 0 and no timestamps": h5(lambda fh: (set_attr("data", "env_args",
                                                           json.dumps({"env_kwargs": {"fps": 0}}))(fh),
                                                  fh.__delitem__("data/demo_0/timestamps"))),
        "demo without actions": h5(lambda fh: fh.__delitem__("data/demo_0/actions")),
        "demo without obs": h5(lambda fh: fh.__delitem__("data/demo_2/obs")),
        "obs group empty": h5(lambda fh: [fh.__delitem__(f"data/demo_0/obs/{k}")
                                          for k in list(fh["data/demo_0/obs"])]),
        "a demo that is a dataset": h5(demo_dataset),
        "an observation that is a group": h5(obs_group_inside),
        "actions shorter than obs": h5(replace("data/demo_0/actions", np.zeros((n - 5, 6)))),
        "timestamps shorter": h5(replace("data/demo_1/timestamps", np.arange(n - 3) * 0.01)),
        "timestamps not increasing": h5(replace("data/demo_1/timestamps", np.zeros(n))),
        "NaN in actions": h5(nan_action),
        "actions as strings": h5(replace("data/demo_0/actions", np.array([b"a"] * n))),
        "robointel_meta not JSON": h5(set_attr("data/demo_0", "robointel_meta", "{oops")),
        "robointel_names not a mapping": h5(set_attr("data/demo_0", "robointel_names", "[1, 2]")),
        "robointel_names with a number": h5(set_attr("data/demo_0", "robointel_names", '{"state": 5}')),
        "a one-frame demo": h5(lambda fh: [replace(f"data/demo_2/{k}", fh[f"data/demo_2/{k}"][:1])(fh)
                                           for k in ("actions", "timestamps", "obs/state", "obs/wrench")]),
        "a 3-d observation": h5(replace("data/demo_0/obs/state", np.zeros((n, 3, 4)))),
    }


def corrupt_robomimic(folder: str | Path, episodes: list[Episode] | None = None) -> list[tuple[str, Path]]:
    """Write one valid robomimic file per corruption and break it; returns ``(case, file)`` pairs.

    Args:
        folder: where the files go (created).
        episodes: what the files hold (default: :func:`device_episodes`, 40 frames each).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    base = write_robomimic(folder / "valid.hdf5", episodes or device_episodes(), overwrite=True)
    out = []
    for k, (case, edit) in enumerate(_robomimic_edits().items()):
        path = folder / f"robomimic_{k:02d}.hdf5"
        shutil.copyfile(base, path)
        edit(path)
        out.append((case, path))
    return out
