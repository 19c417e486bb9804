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
    if isinstance(fps, bool) or not isinstance(fps, int | np.integer) or int(fps) < 1:
        raise InvalidInput(f"fps must be a positive integer, got {fps!r}", value=fps)
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


def _bad(where: Path | str, field: str, why: str, value: Any = None) -> InvalidInput:
    return InvalidInput(f"{where}: {field}: {why}", value=value if value is not None else field)


def _read_info(root: Path) -> dict[str, Any]:
    """``meta/info.json``, checked: a v3 dataset with a positive fps and an ``observation.state`` feature."""
    info_path = root / "meta" / "info.json"
    if not info_path.is_file():
        raise DataMissing(f"{info_path} not found: not a LeRobot dataset folder", value=str(root))
    try:
        info = json.loads(info_path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise _bad(info_path, "the file", f"not valid JSON ({str(exc)[:120]})") from None
    if not isinstance(info, dict):
        raise _bad(info_path, "the file", f"must hold a JSON object, got {type(info).__name__}")
    version = str(info.get("codebase_version", ""))
    if not version.startswith("v3"):
        raise InvalidInput(f"{root} is a LeRobot {version or 'unknown-version'} dataset; only v3 is read "
                           f"({info_path}: codebase_version)", value=version)
    fps = info.get("fps")
    if isinstance(fps, bool) or not isinstance(fps, int | float) or not (np.isfinite(fps) and fps > 0):
        raise _bad(info_path, "fps", f"must be a positive number of frames per second, got {fps!r}", fps)
    features = info.get("features")
    if not isinstance(features, dict) or not all(isinstance(f, dict) for f in features.values()):
        raise _bad(info_path, "features", "must be an object of feature name -> {dtype, shape, names}")
    if _key(STATE) not in features:
        raise _bad(info_path, "features", f"no {_key(STATE)!r} feature", sorted(features))
    return info


def _read_parquet(files: list[Path], what: str) -> pa.Table:
    """The tables of ``files`` one after the other (one schema)."""
    tables = []
    for f in files:
        try:
            tables.append(pq.read_table(f))
        except (OSError, pa.ArrowException, ValueError) as exc:
            raise _bad(f, "the file", f"not a readable {what} parquet file ({str(exc).splitlines()[0][:120]})",
                       str(f)) from None
    try:
        return pa.concat_tables(tables)
    except (pa.ArrowException, ValueError) as exc:
        raise _bad(files[0].parent, f"{what} files", f"differ in their columns ({str(exc)[:120]})") from None


def _episode_rows(meta: pa.Table, where: Path, index: np.ndarray) -> list[dict[str, Any]]:
    """The episode rows, checked: integer indices, one row per episode, disjoint frame ranges in the data."""
    need = ("episode_index", "dataset_from_index", "dataset_to_index")
    missing = [c for c in need if c not in meta.column_names]
    if missing:
        raise _bad(where, "columns", f"missing {missing}", missing)
    rows = meta.to_pylist()
    for r in rows:
        for c in need:
            if isinstance(r[c], bool) or not isinstance(r[c], int):
                raise _bad(where, c, f"must be an integer, got {r[c]!r} (episode row {r.get('episode_index')!r})",
                           r[c])
        a, b = r["dataset_from_index"], r["dataset_to_index"]
        lo, hi = int(np.searchsorted(index, a)), int(np.searchsorted(index, b))
        if not (a < b and lo < len(index) and index[lo] == a and hi - lo == b - a):
            raise _bad(where, "dataset_from_index/dataset_to_index",
                       f"episode {r['episode_index']} spans frames [{a}, {b}), which are not all in the data",
                       r["episode_index"])
    rows.sort(key=lambda r: r["episode_index"])
    seen = [r["episode_index"] for r in rows]
    dup = sorted({i for i in seen if seen.count(i) > 1})
    if dup:
        raise _bad(where, "episode_index", f"episodes {dup} appear more than once (duplicated episode rows)", dup)
    spans = sorted((r["dataset_from_index"], r["dataset_to_index"], r["episode_index"]) for r in rows)
    for (_, a1, ea), (b0, _, eb) in zip(spans, spans[1:]):
        if b0 < a1:
            raise _bad(where, "dataset_from_index/dataset_to_index",
                       f"episodes {ea} and {eb} share frames (a duplicated episode)", (ea, eb))
    return rows


def _json_field(r: dict[str, Any], key: str, where: Path) -> Any:
    raw = r.get(key)
    if raw is None:
        return {}
    try:
        out = json.loads(raw)
    except (TypeError, ValueError, RecursionError):
        raise _bad(where, key, f"not JSON in episode {r['episode_index']}: {str(raw)[:60]!r}") from None
    if not isinstance(out, dict):
        raise _bad(where, key, f"must be a JSON object in episode {r['episode_index']}")
    return out


def read_lerobot(root: str | Path) -> list[Episode]:
    """Read the episodes of a LeRobot v3 dataset folder (its parquet data; videos are not read).

    Every part is checked before an episode is returned: a malformed dataset gives one error
    naming the file and the field, never a partial result.

    Args:
        root: the dataset folder (with ``meta/info.json``).

    Returns:
        The episodes in episode order. Datasets written by :func:`write_lerobot` come back equal;
        others get ``time`` from ``timestamp`` and empty ``kind``.

    Raises:
        DataMissing: no ``meta/info.json``, data files or episode files.
        InvalidInput: not a v3 dataset, ``fps`` not positive, no ``observation.state``, an unreadable
            or malformed file, a missing or ill-typed column, duplicated episodes (rows repeated or
            sharing frames), an episode whose values are not finite or whose times do not increase.
    """
    root = Path(root)
    info = _read_info(root)
    features: dict[str, dict[str, Any]] = info["features"]
    files = sorted((root / "data").glob("chunk-*/file-*.parquet"))
    if not files:
        raise DataMissing(f"no data files under {root / 'data'}", value=str(root))
    ep_files = sorted((root / "meta" / "episodes").glob("chunk-*/*.parquet"))
    if not ep_files:
        raise DataMissing(f"no episode files under {root / 'meta' / 'episodes'}", value=str(root))
    data = _read_parquet(files, "data")
    meta = _read_parquet(ep_files, "episodes")
    obs_keys = [k for k, f in features.items() if k.startswith(_PREFIX) and f.get("dtype") not in ("video", "image")]
    for c in ("index", "action", *obs_keys):
        if c not in data.column_names:
            raise _bad(files[0], "columns", f"no {c!r} column", c)
    if "time" not in data.column_names and "timestamp" not in data.column_names:
        raise _bad(files[0], "columns", "neither 'time' nor 'timestamp'", "time")
    try:
        index = np.asarray(data.column("index").to_numpy(zero_copy_only=False), dtype=np.int64)
    except (pa.ArrowException, TypeError, ValueError):
        raise _bad(files[0], "index", "must be integers") from None
    if np.any(np.diff(index) <= 0):
        raise _bad(files[0], "index", "must increase strictly from frame to frame (a frame repeated or out of order)")
    rows = _episode_rows(meta, ep_files[0], index)
    out = []
    for r in rows:
        e = r["episode_index"]
        lo, hi = (int(np.searchsorted(index, r["dataset_from_index"])),
                  int(np.searchsorted(index, r["dataset_to_index"])))
        sl = slice(lo, hi)
        try:
            t = (_as_matrix(data.column("time"), sl) if "time" in data.column_names
                 else _as_matrix(data.column("timestamp"), sl).astype(np.float64))[:, 0]
            obs = {k[len(_PREFIX):]: _as_matrix(data.column(k), sl) for k in obs_keys}
            action = _as_matrix(data.column("action"), sl)
        except (pa.ArrowException, TypeError, ValueError) as exc:
            raise _bad(files[0], "columns", f"episode {e}: a column is not numbers of one width "
                                            f"({str(exc)[:120]})", e) from None
        names = {k[len(_PREFIX):]: tuple(map(str, features[k]["names"])) for k in obs_keys
                 if isinstance(features[k].get("names"), list)}
        if isinstance(features.get("action", {}).get("names"), list):
            names["action"] = tuple(map(str, features["action"]["names"]))
        tasks = r.get("tasks") or [""]
        if not isinstance(tasks, list):
            raise _bad(ep_files[0], "tasks", f"must be a list of strings in episode {e}", e)
        meta_e = _json_field(r, "robointel/meta", ep_files[0])
        try:
            out.append(Episode.create(t, obs, action, names=names, task=str(tasks[0]),
                                      kind=str(r.get("robointel/kind") or ""),
                                      name=str(r.get("robointel/name") or f"episode_{e:06d}"), meta=meta_e))
        except InvalidInput as exc:
            raise _bad(root, f"episode {e}", str(exc), e) from None
    return out
