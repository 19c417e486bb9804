"""LeRobot dataset v3.0 files (parquet + meta JSON), written and read with ``pyarrow`` only (no torch).

Layout (``codebase_version`` "v3.0")::

    meta/info.json                              fps, totals, features, path templates
    meta/stats.json                             per feature: min, max, mean, std, count, q01..q99
    meta/tasks.parquet                          task (the pandas index), task_index
    meta/episodes/chunk-000/file-000.parquet    one row per episode: episode_index, tasks, length,
                                                data/chunk_index, data/file_index, dataset_from_index,
                                                dataset_to_index, meta/episodes/chunk_index,
                                                meta/episodes/file_index, stats/<feature>/<stat>,
                                                robointel/kind, robointel/name, robointel/meta (JSON)
    data/chunk-000/file-000.parquet             one row per frame, episodes one after another; the next
                                                file (file-001, ...) once one passes 100 MB

Frame columns: ``observation.state`` and ``observation.<name>`` for the other observations,
``action``, ``time`` (the exact sample time, float64 s), and LeRobot's ``timestamp`` (float32 s
from the episode's start), ``frame_index``, ``episode_index``, ``index``, ``task_index``. A
feature of width 1 is a scalar column, wider ones fixed-size lists. No video features.
"""
from __future__ import annotations

import json
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from robointel._extras import optional_module
from robointel.errors import DataMissing, InvalidInput
from robointel.io.episode import STATE, Episode

if TYPE_CHECKING:
    import pyarrow as pa
    import pyarrow.parquet as pq
else:
    pa = optional_module("pyarrow", "datasets", "a LeRobot dataset")
    pq = optional_module("pyarrow.parquet", "datasets", "a LeRobot dataset")

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000  # files per chunk folder
DATA_FILE_MB = 100  # episodes go to the next data file past this size
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
QUANTILES = {"q01": 0.01, "q10": 0.10, "q50": 0.50, "q90": 0.90, "q99": 0.99}
_DEFAULT = ("timestamp", "frame_index", "episode_index", "index", "task_index")
_PREFIX = "observation."


def _key(obs: str) -> str:
    return f"{_PREFIX}{obs}"


def _dtype(a: np.ndarray) -> str:
    return "int64" if a.dtype.kind in "iu" else "float64"


def _schema_of(ep: Episode) -> dict[str, tuple[str, int]]:
    cols = {_key(k): (_dtype(v), v.shape[1]) for k, v in ep.observations.items()}
    cols["action"] = ("float64", ep.action.shape[1])
    return cols


def _fps(ep: Episode) -> int:
    return max(1, int(round(1.0 / float(np.median(np.diff(ep.t))))))


def _column(values: np.ndarray, dtype: str) -> pa.Array:
    pa_type = pa.int64() if dtype == "int64" else pa.float64() if dtype == "float64" else pa.float32()
    if values.ndim == 1 or values.shape[1] == 1:
        return pa.array(values.reshape(-1), type=pa_type)
    flat = pa.array(values.reshape(-1), type=pa_type)
    return pa.FixedSizeListArray.from_arrays(flat, values.shape[1])


def _stats(values: np.ndarray) -> dict[str, list[float] | list[int]]:
    v = values.reshape(len(values), -1).astype(np.float64)
    out: dict[str, Any] = {"min": v.min(0).tolist(), "max": v.max(0).tolist(), "mean": v.mean(0).tolist(),
                           "std": v.std(0).tolist(), "count": [len(v)]}
    for name, q in QUANTILES.items():
        out[name] = np.quantile(v, q, axis=0).tolist()
    return out


def _tasks_table(tasks: list[str]) -> pa.Table:
    """tasks.parquet as pandas writes it: the task string is the DataFrame's index."""
    pandas_meta = {
        "index_columns": ["task"],
        "column_indexes": [{"name": None, "field_name": None, "pandas_type": "unicode", "numpy_type": "object",
                            "metadata": {"encoding": "UTF-8"}}],
        "columns": [{"name": "task_index", "field_name": "task_index", "pandas_type": "int64",
                     "numpy_type": "int64", "metadata": None},
                    {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object",
                     "metadata": None}],
        "creator": {"library": "pyarrow", "version": pa.__version__},
        "pandas_version": "2.2.3",
    }
    table = pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()), "task": pa.array(tasks, pa.string())})
    return table.replace_schema_metadata({b"pandas": json.dumps(pandas_meta).encode()})


def write_lerobot(root: str | Path, episodes: Sequence[Episode], *, robot_type: str = "",
                  fps: int | None = None, overwrite: bool = False, data_file_mb: float = DATA_FILE_MB) -> Path:
    """Write episodes as a LeRobot v3.0 dataset folder.

    Args:
        root: the dataset folder (created; must not exist unless ``overwrite``).
        episodes: one or more episodes with the same observations, widths and dtypes.
        robot_type: info.json's ``robot_type`` (e.g. "lrmate200id7l").
        fps: frames per second (default: from the episodes' median sample period, the same for all).
        overwrite: replace an existing folder.
        data_file_mb: size [MB] past which the next episode starts a new data file.

    Returns:
        The dataset folder.

    Raises:
        InvalidInput: no episodes, episodes of different schemas or rates, an existing folder.
    """
    root = Path(root)
    if not episodes:
        raise InvalidInput("write_lerobot needs at least one episode", value=0)
    schema = _schema_of(episodes[0])
    for i, ep in enumerate(episodes):
        if _schema_of(ep) != schema:
            raise InvalidInput(f"episode {i} ({ep.name!r}) has features {_schema_of(ep)}, episode 0 has {schema}: "
                               "a LeRobot dataset has one schema; export them separately", value=i)
    rates = sorted({_fps(ep) for ep in episodes})
    if fps is None:
        if len(rates) > 1:
            raise InvalidInput(f"the episodes are sampled at different rates {rates} Hz; export them separately "
                               "or resample them", value=rates)
        fps = rates[0]
    if int(fps) < 1:
        raise InvalidInput(f"fps must be a positive integer, got {fps}", value=fps)
    if root.exists():
        if not overwrite:
            raise InvalidInput(f"{root} exists; pass overwrite=True to replace it", value=str(root))
        shutil.rmtree(root)
    tasks = list(dict.fromkeys(ep.task for ep in episodes))
    names = {_key(k): list(v) for k, v in episodes[0].names.items() if k != "action" and v}
    if episodes[0].names.get("action"):
        names["action"] = list(episodes[0].names["action"])

    # frames
    cols: dict[str, list[np.ndarray]] = {c: [] for c in (*schema, "time", *_DEFAULT)}
    files: list[list[int]] = [[]]  # episodes per data file (an episode never spans two files)
    size = 0.0
    ep_rows: dict[str, list[Any]] = {c: [] for c in (
        "episode_index", "tasks", "length", "data/chunk_index", "data/file_index", "dataset_from_index",
        "dataset_to_index", "meta/episodes/chunk_index", "meta/episodes/file_index")}
    ep_stats: list[dict[str, dict[str, Any]]] = []
    start = 0
    for e, ep in enumerate(episodes):
        n = len(ep)
        frame = {**{_key(k): v for k, v in ep.observations.items()}, "action": ep.action, "time": ep.t,
                 "timestamp": (ep.t - ep.t[0]).astype(np.float32), "frame_index": np.arange(n),
                 "episode_index": np.full(n, e), "index": np.arange(start, start + n),
                 "task_index": np.full(n, tasks.index(ep.task))}
        for c, v in frame.items():
            cols[c].append(np.asarray(v))
        mb = sum(np.asarray(v).nbytes for v in frame.values()) / 2 ** 20
        if files[-1] and size + mb > data_file_mb:
            files.append([])
            size = 0.0
        files[-1].append(e)
        size += mb
        chunk, file = divmod(len(files) - 1, CHUNKS_SIZE)
        ep_stats.append({c: _stats(np.asarray(v)) for c, v in frame.items()})
        for c, v in (("episode_index", e), ("tasks", [ep.task]), ("length", n), ("data/chunk_index", chunk),
                     ("data/file_index", file), ("dataset_from_index", start), ("dataset_to_index", start + n),
                     ("meta/episodes/chunk_index", 0), ("meta/episodes/file_index", 0)):
            ep_rows[c].append(v)
        start += n
    dtypes = {**{c: d for c, (d, _) in schema.items()}, "time": "float64", "timestamp": "float32",
              **{c: "int64" for c in _DEFAULT[1:]}}
    for f, members in enumerate(files):
        chunk, file = divmod(f, CHUNKS_SIZE)
        path = root / DATA_PATH.format(chunk_index=chunk, file_index=file)
        path.parent.mkdir(parents=True, exist_ok=True)
        part = {c: np.concatenate([v[e] for e in members]) for c, v in cols.items()}
        pq.write_table(pa.table({c: _column(v, dtypes[c]) for c, v in part.items()}), path)
    data = {c: np.concatenate(v) for c, v in cols.items()}

    # episodes metadata with per-episode stats
    table: dict[str, pa.Array] = {c: pa.array(v) for c, v in ep_rows.items()}
    table["tasks"] = pa.array(ep_rows["tasks"], pa.list_(pa.string()))
    for c in data:
        for s in ep_stats[0][c]:
            typ = pa.list_(pa.int64()) if s == "count" else pa.list_(pa.float64())
            table[f"stats/{c}/{s}"] = pa.array([st[c][s] for st in ep_stats], typ)
    table["robointel/kind"] = pa.array([ep.kind for ep in episodes], pa.string())
    table["robointel/name"] = pa.array([ep.name for ep in episodes], pa.string())
    table["robointel/meta"] = pa.array([json.dumps(ep.meta) for ep in episodes], pa.string())
    path = root / EPISODES_PATH.format(chunk_index=0, file_index=0)
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.table(table), path)
    pq.write_table(_tasks_table(tasks), root / "meta" / "tasks.parquet")

    widths = {**{c: w for c, (_, w) in schema.items()}, "time": 1, **{c: 1 for c in _DEFAULT}}
    features = {c: {"dtype": dtypes[c], "shape": [widths[c]], "names": names.get(c)} for c in data}
    stats = {c: _stats(v) for c, v in data.items()}
    info = {"codebase_version": CODEBASE_VERSION, "robot_type": robot_type or None,
            "total_episodes": len(episodes), "total_frames": int(start), "total_tasks": len(tasks),
            "chunks_size": CHUNKS_SIZE, "data_files_size_in_mb": data_file_mb, "video_files_size_in_mb": 200,
            "fps": int(fps), "splits": {"train": f"0:{len(episodes)}"}, "data_path": DATA_PATH,
            "video_path": None, "features": features}
    (root / "meta" / "info.json").write_text(json.dumps(info, indent=4))
    (root / "meta" / "stats.json").write_text(json.dumps(stats, indent=4))
    return root


def _as_matrix(column: pa.ChunkedArray, rows: slice) -> np.ndarray:
    part = column.slice(rows.start, rows.stop - rows.start).combine_chunks()
    if pa.types.is_fixed_size_list(part.type) or pa.types.is_list(part.type):
        width = part.type.list_size if pa.types.is_fixed_size_list(part.type) else None
        flat = part.flatten().to_numpy(zero_copy_only=False)
        return flat.reshape(len(part), width if width is not None else -1)
    return part.to_numpy(zero_copy_only=False).reshape(-1, 1)


def read_lerobot(root: str | Path) -> list[Episode]:
    """Read the episodes of a LeRobot v3 dataset folder (its parquet data; videos are not read).

    Args:
        root: the dataset folder (with ``meta/info.json``).

    Returns:
        The episodes in episode order. Datasets written by :func:`write_lerobot` come back equal;
        others get ``time`` from ``timestamp`` and empty ``kind``.

    Raises:
        DataMissing: no ``meta/info.json`` or data files.
        InvalidInput: not a v3 dataset, or no ``observation.state``.
    """
    root = Path(root)
    info_path = root / "meta" / "info.json"
    if not info_path.exists():
        raise DataMissing(f"{info_path} not found: not a LeRobot dataset folder", value=str(root))
    info = json.loads(info_path.read_text())
    version = str(info.get("codebase_version", ""))
    if not version.startswith("v3"):
        raise InvalidInput(f"{root} is a LeRobot {version or 'unknown-version'} dataset; only v3 is read",
                           value=version)
    features: dict[str, dict[str, Any]] = info.get("features", {})
    if _key(STATE) not in features:
        raise InvalidInput(f"{root} has no {_key(STATE)!r} feature", value=sorted(features))
    files = sorted((root / "data").glob("chunk-*/file-*.parquet"))
    if not files:
        raise DataMissing(f"no data files under {root / 'data'}", value=str(root))
    data = pa.concat_tables([pq.read_table(f) for f in files])
    meta = pa.concat_tables([pq.read_table(f) for f in sorted((root / "meta" / "episodes").glob("chunk-*/*.parquet"))])
    rows = sorted(meta.to_pylist(), key=lambda r: r["episode_index"])
    index = data.column("index").to_numpy()
    obs_keys = [k for k, f in features.items() if k.startswith(_PREFIX) and f.get("dtype") not in ("video", "image")]
    out = []
    for r in rows:
        lo, hi = (int(np.searchsorted(index, r["dataset_from_index"])),
                  int(np.searchsorted(index, r["dataset_to_index"])))
        sl = slice(lo, hi)
        t = (_as_matrix(data.column("time"), sl) if "time" in data.column_names
             else _as_matrix(data.column("timestamp"), sl).astype(np.float64))[:, 0]
        obs = {k[len(_PREFIX):]: _as_matrix(data.column(k), sl) for k in obs_keys}
        names = {k[len(_PREFIX):]: tuple(features[k]["names"]) for k in obs_keys
                 if isinstance(features[k].get("names"), list)}
        if isinstance(features.get("action", {}).get("names"), list):
            names["action"] = tuple(features["action"]["names"])
        tasks = r.get("tasks") or [""]
        out.append(Episode.create(t, obs, _as_matrix(data.column("action"), sl), names=names, task=tasks[0],
                                  kind=r.get("robointel/kind") or "",
                                  name=r.get("robointel/name") or f"episode_{r['episode_index']:06d}",
                                  meta=json.loads(r.get("robointel/meta") or "{}")))
    return out
