"""The remote lead-through teaching (RLTT) pipeline of Ch. 5 for the insertion.

Synchronise (DTW, (5.1)-(5.6)), decompose (Algorithm 1, (5.7)-(5.13)) and learn the skill model
((5.14)-(5.17)) from demonstrations with the hand-held device.
"""
from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from threadpoolctl import threadpool_limits

from robointel.errors import InvalidInput
from robointel.learning.decomposition import ActionSegmenter, demo_features
from robointel.learning.demonstration import Demonstration
from robointel.learning.dtw import align
from robointel.learning.insertion import PHASES, InsertionSkill


@dataclass
class LearnedInsertion:
    """What :func:`learn_insertion` returns.

    Attributes:
        skill: the fitted :class:`InsertionSkill`.
        segmenter: the fitted :class:`ActionSegmenter`.
        aligned: synchronised demonstrations: (m, F) feature arrays on the reference's time axis.
        labels: per demonstration (N_i,) action labels: ground truth for the labelled ones, the
            decomposition for the rest.
        boundary_errors: (n_unlabelled, A-1) |predicted - true| split times (s) where ground truth
            exists (NaN otherwise).
        timings: seconds for ``sync``, ``decompose``, ``train`` and ``total``.
        skill_demos: indices of the demonstrations the skill was fitted on (seated, and hand-labelled or
            decomposed into phases no shorter than half the shortest hand-labelled one).
    """

    skill: InsertionSkill
    segmenter: ActionSegmenter
    aligned: list[npt.NDArray[np.float64]]
    labels: list[npt.NDArray[np.int_]]
    boundary_errors: npt.NDArray[np.float64]
    timings: dict[str, float] = field(default_factory=dict)
    skill_demos: list[int] = field(default_factory=list)


def plausible_decompositions(labels: Sequence[npt.NDArray[np.int_]], n_labelled: int,
                             *, min_fraction: float = 0.5) -> list[bool]:
    """Whether each decomposition has every phase at least ``min_fraction`` of its shortest hand-labelled length.

    With few hand-labelled demonstrations Algorithm 1 can collapse a phase to a window or two and hand the
    whole approach and rotation (free-air motion at up to 7 cm/s and 0.3 rad/s, zero wrench) to the
    insertion; a skill fitted on those samples drifts sideways and turns with nothing felt.

    Args:
        labels: Per demonstration (N_i,) phase labels; the first ``n_labelled`` are the hand labels.
        n_labelled: How many leading entries are hand labels (always plausible).
        min_fraction: Shortest accepted phase, as a fraction of its shortest hand-labelled length.

    Returns:
        One flag per demonstration.
    """
    n_phases = len(PHASES)
    counts = [np.bincount(np.asarray(lab), minlength=n_phases)[:n_phases] for lab in labels]
    shortest = np.min(counts[:n_labelled], axis=0)
    return [i < n_labelled or bool(np.all(c >= min_fraction * shortest)) for i, c in enumerate(counts)]


def learn_insertion(demos: Sequence[Demonstration], *, n_labelled: int = 20, reference: int = 0,
                    sync_window: int = 150, seg_window: int = 20, seg_band: int = 4, n_components: int = 6,
                    only_successful: bool = True, centre: float = 0.0) -> LearnedInsertion:
    """Synchronise, decompose and learn from demonstrations whose first ``n_labelled`` carry hand labels.

    The rest are decomposed by Algorithm 1.

    Args:
        demos: The demonstrations.
        n_labelled: How many of the first demonstrations carry hand labels.
        reference: Index of the synchronisation reference.
        sync_window: DTW band of the synchronisation (samples).
        seg_window: Window of the action segmenter (samples).
        seg_band: Band of the segmenter's boundary search (samples).
        n_components: Gaussian components of the skill model.
        only_successful: Learn the skill only from demonstrations that seated the peg.
        centre: Distance (m) along the tool axis from the F/T sensor to the point whose velocity the skill
            outputs (the robot's compliance centre).

    Returns:
        The skill, the segmenter, the aligned features, labels, boundary errors and timings.

    Raises:
        InvalidInput: fewer demonstrations than labelled ones, a labelled demonstration without labels.
    """
    if len(demos) < 2 or not 0 < n_labelled < len(demos):
        raise InvalidInput(f"need more demonstrations ({len(demos)}) than labelled ones ({n_labelled}), "
                           "and at least one labelled", value=n_labelled)
    if any(d.labels is None for d in demos[:n_labelled]):
        raise InvalidInput("the first n_labelled demonstrations must carry labels")
    # every linear-algebra call below is small (10-D EM steps, ~1000 x 1000 kernels): OpenBLAS's
    # thread start-up and spin-waiting cost 10-100x the arithmetic there, on a shared machine most
    with threadpool_limits(limits=1, user_api="blas"):
        return _learn_insertion(demos, n_labelled, reference, sync_window, seg_window, seg_band, n_components,
                                only_successful, centre)


def _learn_insertion(demos: Sequence[Demonstration], n_labelled: int, reference: int, sync_window: int,
                     seg_window: int, seg_band: int, n_components: int, only_successful: bool,
                     centre: float) -> LearnedInsertion:
    t0 = time.perf_counter()
    feats = [demo_features(d) for d in demos]
    allf = np.concatenate(feats)
    mu, sd = allf.mean(0), allf.std(0) + 1e-9
    z = [(f - mu) / sd for f in feats]
    aligned = align(z, reference=reference, window=sync_window)
    aligned = [a * sd + mu for a in aligned]
    t1 = time.perf_counter()
    seg = ActionSegmenter(window=seg_window, band=seg_band, stride=2, max_train_windows=1500)
    seg.fit(feats[:n_labelled], [d.labels for d in demos[:n_labelled]])
    labels: list[npt.NDArray[np.int_]] = [d.labels for d in demos[:n_labelled] if d.labels is not None]
    errs: list[npt.NDArray[np.float64]] = []
    for d, f in zip(demos[n_labelled:], feats[n_labelled:]):
        r = seg.predict(f)
        labels.append(r.labels)
        if d.labels is not None and len(np.unique(d.labels)) == len(PHASES):
            truth = np.flatnonzero(np.diff(d.labels)) + 1
            errs.append(np.abs(d.t[r.splits] - d.t[truth]))
        else:
            errs.append(np.full(len(PHASES) - 1, np.nan))
    t2 = time.perf_counter()
    plausible = plausible_decompositions(labels, n_labelled)
    keep = [i for i, d in enumerate(demos) if plausible[i] and (not only_successful or d.meta.get("seated", True))]
    if not keep:
        raise InvalidInput("no seated demonstration with a plausible decomposition to learn the skill from",
                           value=len(demos))
    skill = InsertionSkill(n_components, centre=centre).fit([demos[i] for i in keep], [labels[i] for i in keep])
    t3 = time.perf_counter()
    return LearnedInsertion(skill, seg, aligned, labels, np.array(errs),
                            {"sync": t1 - t0, "decompose": t2 - t1, "train": t3 - t2, "total": t3 - t0}, keep)
