"""Trajectory files: a :class:`robointel.trajectory.Trajectory` as ``.npz`` (arrays + names) or JSON."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from robointel.errors import InvalidInput
from robointel.trajectory import Trajectory

__all__ = ["FORMAT", "load_trajectory", "save_trajectory", "trajectory_to_dict"]

FORMAT = "robointel.trajectory/1"


def trajectory_to_dict(traj: Trajectory) -> dict[str, Any]:
    """The JSON document of a trajectory: ``format``, ``joint_names``, ``t``, ``q``, ``qd``, ``qdd``, ``meta``."""
    return {"format": FORMAT, "joint_names": list(traj.joint_names), "t": traj.t.tolist(),
            "q": traj.q.tolist(), "qd": traj.qd.tolist(), "qdd": traj.qdd.tolist(), "meta": traj.meta}


def save_trajectory(traj: Trajectory, path: str | Path) -> Path:
    """Write ``traj`` as ``.npz`` (arrays + names) or ``.json``; the suffix decides.

    Args:
        traj: The trajectory.
        path: Target file ending in ``.npz`` or ``.json``.

    Returns:
        The path written.

    Raises:
        InvalidInput: any other suffix.
    """
    path = Path(path)
    if path.suffix == ".json":
        path.write_text(json.dumps(trajectory_to_dict(traj), indent=1, default=_json_default))
    elif path.suffix == ".npz":
        np.savez(path, t=traj.t, q=traj.q, qd=traj.qd, qdd=traj.qdd,
                 joint_names=np.array(traj.joint_names), format=np.array(FORMAT),
                 meta=np.array(json.dumps(traj.meta, default=_json_default)))
    else:
        raise InvalidInput(f"trajectory file must end in .npz or .json, got {path.name!r}", value=str(path))
    return path


def load_trajectory(path: str | Path) -> Trajectory:
    """Read a file written by :func:`save_trajectory`.

    Args:
        path: A ``.npz`` or ``.json`` trajectory file.

    Returns:
        The trajectory.

    Raises:
        InvalidInput: the file does not exist or has another suffix; its arrays are inconsistent.
    """
    path = Path(path)
    if not path.exists():
        raise InvalidInput(f"trajectory file {path} does not exist", value=str(path))
    if path.suffix == ".json":
        d = json.loads(path.read_text())
        return Trajectory(d["t"], d["q"], d["qd"], d["qdd"], list(d.get("joint_names", [])), d.get("meta", {}))
    if path.suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"])) if "meta" in z else {}
            return Trajectory(z["t"], z["q"], z["qd"], z["qdd"], [str(s) for s in z["joint_names"]], meta)
    raise InvalidInput(f"trajectory file must end in .npz or .json, got {path.name!r}", value=str(path))


def _json_default(o: object) -> object:
    """JSON encoding of numpy arrays and scalars (anything else as its ``str``)."""
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.floating | np.integer):
        return o.item()
    return str(o)
