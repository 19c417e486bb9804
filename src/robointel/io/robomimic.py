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


def read_robomimic(path: str | Path) -> list[Episode]:
    """Read the demonstrations of a robomimic-style HDF5 file.

    Args:
        path: the ``.hdf5`` file.

    Returns:
        The episodes in demo order (demo_0, demo_1, ...). Files written by :func:`write_robomimic`
        come back equal; others get times from the ``fps`` env kwarg if there is one (else 1 frame
        per second), the first observation key as ``state`` when there is none, and empty names.

    Raises:
        DataMissing: no such file.
        InvalidInput: no ``data`` group or a demo without ``actions``/``obs``.
    """
    path = Path(path)
    if not path.exists():
        raise DataMissing(f"robomimic file {path} does not exist", value=str(path))
    out = []
    with h5py.File(path, "r") as f:
        if "data" not in f:
            raise InvalidInput(f"{path} has no 'data' group: not a robomimic file", value=str(path))
        data = f["data"]
        env_kwargs = json.loads(data.attrs.get("env_args", "{}")).get("env_kwargs", {})
        order = sorted(data, key=lambda s: int(s.split("_")[-1]) if s.split("_")[-1].isdigit() else 0)
        for demo in order:
            g = data[demo]
            if "actions" not in g or "obs" not in g:
                raise InvalidInput(f"{path}: {demo} needs 'actions' and 'obs'", value=demo)
            action = g["actions"][()]
            obs = {k: g["obs"][k][()] for k in g["obs"]}
            if "state" not in obs:
                first = sorted(obs)[0]
                obs["state"] = obs.pop(first)
            n = len(action)
            t = g["timestamps"][()] if "timestamps" in g else np.arange(n) / float(env_kwargs.get("fps", 1.0))
            names = {k: tuple(v) for k, v in json.loads(g.attrs.get("robointel_names", "{}")).items()}
            out.append(Episode.create(t, obs, action, names=names, task=str(g.attrs.get("robointel_task", "")),
                                      kind=str(g.attrs.get("robointel_kind", "")),
                                      name=str(g.attrs.get("robointel_name", demo)),
                                      meta=json.loads(g.attrs.get("robointel_meta", "{}"))))
    return out
