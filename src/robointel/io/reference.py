"""The one way to reach the reference data in ``../shared/data`` (never copied into the repo).

The folder is found from ``$ROBOINTEL_DATA``, else ``../shared/data`` beside the project root or
the current directory.
"""
from __future__ import annotations

import os
from pathlib import Path

from robointel.errors import DataMissing

_PROJECT = Path(__file__).resolve().parents[3]


def data_root() -> Path | None:
    """The reference-data folder, or None when it is not there."""
    env = os.environ.get("ROBOINTEL_DATA")
    cands = [Path(env)] if env else []
    cands += [_PROJECT.parent / "shared" / "data", Path.cwd().parent / "shared" / "data",
              Path.cwd() / ".." / ".." / "shared" / "data"]
    for c in cands:
        if c.is_dir():
            return c.resolve()
    return None


def data_path(*parts: str) -> Path:
    """Path of a reference-data file or folder, e.g. ``data_path("kinect", "joints.csv")``.

    Raises:
        DataMissing: the data folder or the file is not there (set ROBOINTEL_DATA).
    """
    root = data_root()
    if root is None:
        raise DataMissing("reference data folder ../shared/data not found; set ROBOINTEL_DATA to its path")
    p = root.joinpath(*parts)
    if not p.exists():
        raise DataMissing(f"reference data file {p} is missing", value=str(p))
    return p
