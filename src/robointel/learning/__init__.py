"""Part II (Ch. 5-6): demonstrations, DTW, action decomposition, GMM/GMR skills; grasp/ for grasp transfer.

Chapter 5 modules (import them directly; nothing heavy is imported here):

* :mod:`~robointel.learning.demonstration` - :class:`Demonstration` (t, tool pose, wrench, labels).
* :mod:`~robointel.learning.datasets` - LASA handwriting and UCI robot-failure F/T loaders.
* :mod:`~robointel.learning.dtw` - numba DTW (5.1)-(5.6): ``dtw_distance``, ``dtw``, ``align``, ``warp_to``.
* :mod:`~robointel.learning.decomposition` - Algorithm 1 (5.7)-(5.13): ``ActionSegmenter``.
* :mod:`~robointel.learning.gmr` - GMM (scikit-learn) + GMR (5.14)-(5.17): ``GaussianMixtureRegression``.
* :mod:`~robointel.learning.hdd` - the hand-held demonstration device and its tool in MuJoCo.
* :mod:`~robointel.learning.insertion` - tight peg-in-hole (a package: task, device scene, scripted
  demonstrator, skill, baseline policies, impedance, robot cell, press test).
* :mod:`~robointel.learning.grinding` - plate grinding: position -> force skill, force-controlled reproduction.
* :mod:`~robointel.learning.rltt` - the pipeline (synchronise, decompose, learn).
* :mod:`~robointel.learning.ft_features` - F/T episode features for failure classification.
* :mod:`~robointel.learning.peer_checks` - DTW and GMR side by side with dtaidistance and gmr.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robointel._lazy import lazy_exports

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

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
