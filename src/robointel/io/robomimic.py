"""robomimic-style HDF5 dataset files (one file, one group per demonstration), read and written with h5py.

Layout (robomimic's ``data/demo_N`` convention)::

    data                  attrs: total (frames in all demos), env_args (JSON: env_name, type, env_kwargs)
    data/demo_N           attrs: num_samples, robointel_name, robointel_task, robointel_kind,
                                 robointel_meta (JSON), robointel_names (JSON, component names)
      obs/<name>          (N, k) observations (``state`` and the others), float64 or int64
      next_obs/<name>     (N, k) the observation one frame later (the last frame repeats)
      actions             (N, a) float64
      rewards             (N,) float64 zeros (demonstrations carry no reward)
      dones               (N,) int64, 1 at the last frame
      timestamps          (N,) float64 sample times [s]
    mask/<filter>         (M,) names of the demos in a filter key (``all``)
"""
from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from robointel.errors import DataMissing, InvalidInput
from robointel.io.episode import Episode

ENV_TYPE_ROBOINTEL = 0  # robomimic's EnvType has 1-4 for its simulators; 0: none (recorded episodes)


def write_robomimic(path: str | Path, episodes: Sequence[Episode], *, env_name: str = "robointel",
                    overwrite: bool = False) -> Path:
    """Write episodes as a robomimic-style HDF5 file.

    Args:
        path: the ``.hdf5`` file (must not exist unless ``overwrite``).
        episodes: one or more episodes (observation sets may differ between episodes).
        env_name: ``env_args.env_name``.
        overwrite: replace an existing file.

    Returns:
        The file path.

    Raises:
        InvalidInput: no episodes or an existing file.
    """
    path = Path(path)
    if not episodes:
        raise InvalidInput("write_robomimic needs at least one episode", value=0)
    if path.exists() and not overwrite:
        raise InvalidInput(f"{path} exists; pass overwrite=True to replace it", value=str(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    with h5py.File(path, "w") as f:
        data = f.create_group("data")
        data.attrs["total"] = int(sum(len(ep) for ep in episodes))
        data.attrs["env_args"] = json.dumps({"env_name": env_name, "type": ENV_TYPE_ROBOINTEL, "env_kwargs": {}})
        demos = []
        for i, ep in enumerate(episodes):
            g = data.create_group(f"demo_{i}")
            demos.append(f"demo_{i}")
            n = len(ep)
            g.attrs["num_samples"] = n
            g.attrs["robointel_name"] = ep.name
            g.attrs["robointel_task"] = ep.task
            g.attrs["robointel_kind"] = ep.kind
            g.attrs["robointel_meta"] = json.dumps(ep.meta)
            g.attrs["robointel_names"] = json.dumps({k: list(v) for k, v in ep.names.items()})
            for key, value in ep.observations.items():
                g.create_dataset(f"obs/{key}", data=value)
                g.create_dataset(f"next_obs/{key}", data=np.concatenate([value[1:], value[-1:]]))
            g.create_dataset("actions", data=ep.action)
            g.create_dataset("rewards", data=np.zeros(n))
            g.create_dataset("dones", data=(np.arange(n) == n - 1).astype(np.int64))
            g.create_dataset("timestamps", data=ep.t)
        f.create_dataset("mask/all", data=np.array(demos, dtype="S"))
    return path


def _bad(path: Path, field: str, why: str, value: object = None) -> InvalidInput:
    return InvalidInput(f"{path}: {field}: {why}", value=value if value is not None else field)


def _json_attr(node: h5py.HLObject, key: str, path: Path, default: str, kind: type = dict) -> Any:
    """A JSON attribute of ``node`` of type ``kind``."""
    raw = node.attrs.get(key, default)
    if isinstance(raw, bytes):
        raw = raw.decode("utf-8", "replace")
    try:
        out = json.loads(raw)
    except (TypeError, ValueError, RecursionError):
        raise _bad(path, f"{node.name} attribute {key!r}", f"not JSON: {str(raw)[:60]!r}") from None
    if not isinstance(out, kind):
        raise _bad(path, f"{node.name} attribute {key!r}", f"must be a JSON {kind.__name__}")
    return out


def _array(node: h5py.HLObject, key: str, path: Path) -> np.ndarray:
    """A numeric dataset of ``node`` (read whole)."""
    d = node.get(key)
    if not isinstance(d, h5py.Dataset):
        raise _bad(path, f"{node.name}/{key}", "missing or not a dataset", key)
    if d.dtype.kind not in "biuf":
        raise _bad(path, f"{node.name}/{key}", f"must hold numbers, holds {d.dtype}", key)
    try:
        return np.asarray(d[()])
    except (OSError, ValueError, TypeError) as exc:
        raise _bad(path, f"{node.name}/{key}", f"unreadable (corrupt or truncated: {str(exc)[:100]})") from None


def read_robomimic(path: str | Path) -> list[Episode]:
    """Read the demonstrations of a robomimic-style HDF5 file.

    Every part is checked: a malformed file gives one error naming the file and the field, never a
    partial result.

    Args:
        path: the ``.hdf5`` file.

    Returns:
        The episodes in demo order (demo_0, demo_1, ...). Files written by :func:`write_robomimic`
        come back equal; others get times from the ``fps`` env kwarg if there is one (else 1 frame
        per second), the first observation key as ``state`` when there is none, and empty names.

    Raises:
        DataMissing: no such file.
        InvalidInput: not a readable HDF5 file, no ``data`` group, a demo without ``actions``/``obs``
            (or of other lengths), a non-numeric or unreadable dataset, an attribute that is not
            JSON, an ``fps`` that is not positive, values not finite or times not increasing.
    """
    path = Path(path)
    if not path.is_file():
        raise DataMissing(f"robomimic file {path} does not exist", value=str(path))
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise InvalidInput(f"{path} is not a readable HDF5 file (corrupt, truncated or another format: "
                           f"{str(exc).splitlines()[0][:100]})", value=str(path)) from None
    out = []
    with f:
        data = f.get("data")
        if not isinstance(data, h5py.Group):
            raise InvalidInput(f"{path} has no 'data' group: not a robomimic file", value=str(path))
        env_args = _json_attr(data, "env_args", path, "{}")
        env_kwargs = env_args.get("env_kwargs", {})
        if not isinstance(env_kwargs, dict):
            raise _bad(path, "data attribute 'env_args'", "env_kwargs must be a JSON object")
        fps = env_kwargs.get("fps", 1.0)
        if isinstance(fps, bool) or not isinstance(fps, int | float) or not (np.isfinite(fps) and fps > 0):
            raise _bad(path, "data attribute 'env_args'", f"env_kwargs.fps must be a positive number, got {fps!r}",
                       fps)

        def order(s: str) -> tuple[int, str]:
            tail = s.rsplit("_", 1)[-1]
            return (int(tail) if tail.isdigit() else -1, s)

        for demo in sorted(data, key=order):
            g = data[demo]
            if not isinstance(g, h5py.Group):
                raise _bad(path, f"data/{demo}", "must be a group (one per demonstration)", demo)
            if "actions" not in g or not isinstance(g.get("obs"), h5py.Group):
                raise _bad(path, f"data/{demo}", "needs 'actions' and an 'obs' group", demo)
            action = _array(g, "actions", path)
            obs = {str(k): _array(g["obs"], k, path) for k in g["obs"]}
            if not obs:
                raise _bad(path, f"data/{demo}/obs", "holds no observation", demo)
            if "state" not in obs:
                first = sorted(obs)[0]
                obs["state"] = obs.pop(first)
            n = len(action)
            t = _array(g, "timestamps", path) if "timestamps" in g else np.arange(n) / float(fps)
            names_raw = _json_attr(g, "robointel_names", path, "{}")
            try:
                names = {str(k): tuple(str(x) for x in v) for k, v in names_raw.items()}
            except TypeError:
                raise _bad(path, f"data/{demo} attribute 'robointel_names'", "must map names to lists") from None
            meta = _json_attr(g, "robointel_meta", path, "{}")
            try:
                out.append(Episode.create(t, obs, action, names=names, task=str(g.attrs.get("robointel_task", "")),
                                          kind=str(g.attrs.get("robointel_kind", "")),
                                          name=str(g.attrs.get("robointel_name", demo)), meta=meta))
            except InvalidInput as exc:
                raise _bad(path, f"data/{demo}", str(exc), demo) from None
    return out
