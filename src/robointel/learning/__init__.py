"""Part II (Ch. 5-6): demonstrations, DTW, action decomposition, GMM/GMR skills; grasp/ for grasp transfer.

The insertion and grinding tasks (:mod:`.insertion`, :mod:`.grinding`, :mod:`.rltt`, :mod:`.hdd`) and
:mod:`.grasp` are imported from their modules.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the names below are imported on first access (keeps `import` light)
    from robointel.learning.datasets import FTEpisodes, LasaShape, load_ft, load_lasa
    from robointel.learning.decomposition import ActionSegmenter, Decomposition
    from robointel.learning.demonstration import Demonstration, load_demonstrations, save_demonstrations
    from robointel.learning.dtw import DTWResult, align, dtw, dtw_distance, warp_to
    from robointel.learning.gmr import GaussianMixtureRegression
    from robointel.learning.grasp_database import GraspDatabase

_EXPORTS = {
    "FTEpisodes": "robointel.learning.datasets",
    "LasaShape": "robointel.learning.datasets",
    "load_ft": "robointel.learning.datasets",
    "load_lasa": "robointel.learning.datasets",
    "ActionSegmenter": "robointel.learning.decomposition",
    "Decomposition": "robointel.learning.decomposition",
    "Demonstration": "robointel.learning.demonstration",
    "load_demonstrations": "robointel.learning.demonstration",
    "save_demonstrations": "robointel.learning.demonstration",
    "DTWResult": "robointel.learning.dtw",
    "align": "robointel.learning.dtw",
    "dtw": "robointel.learning.dtw",
    "dtw_distance": "robointel.learning.dtw",
    "warp_to": "robointel.learning.dtw",
    "GaussianMixtureRegression": "robointel.learning.gmr",
    "GraspDatabase": "robointel.learning.grasp_database",
}

__all__ = [
    "ActionSegmenter", "DTWResult", "Decomposition", "Demonstration", "FTEpisodes",
    "GaussianMixtureRegression", "GraspDatabase", "LasaShape", "align", "dtw", "dtw_distance",
    "load_demonstrations", "load_ft", "load_lasa", "save_demonstrations", "warp_to",
]


def __getattr__(name: str) -> Any:
    """Import a public name from its module on first access."""
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    """The public names."""
    return list(__all__)
