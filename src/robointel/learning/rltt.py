"""The remote lead-through teaching pipeline (Ch. 5): synchronise (DTW, (5.1)-(5.6)), decompose
(Algorithm 1, (5.7)-(5.13)) and learn the skill model ((5.14)-(5.17)) from HDD demonstrations."""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
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
    """

    skill: InsertionSkill
    segmenter: ActionSegmenter
    aligned: list[np.ndarray]
    labels: list[np.ndarray]
    boundary_errors: np.ndarray
    timings: dict = field(default_factory=dict)


def learn_insertion(demos: Sequence[Demonstration], *, n_labelled: int = 20, reference: int = 0,
                    sync_window: int = 150, seg_window: int = 20, seg_band: int = 4, n_components: int = 6,
                    only_successful: bool = True) -> LearnedInsertion:
    """Synchronise, decompose and learn from demonstrations whose first ``n_labelled`` carry
    hand labels (the rest are decomposed by Algorithm 1).

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
                                only_successful)


def _learn_insertion(demos, n_labelled, reference, sync_window, seg_window, seg_band, n_components,
                     only_successful) -> LearnedInsertion:
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
    labels = [d.labels for d in demos[:n_labelled]]
    errs = []
    for d, f in zip(demos[n_labelled:], feats[n_labelled:]):
        r = seg.predict(f)
        labels.append(r.labels)
        if d.labels is not None and len(np.unique(d.labels)) == len(PHASES):
            truth = np.flatnonzero(np.diff(d.labels)) + 1
            errs.append(np.abs(d.t[r.splits] - d.t[truth]))
        else:
            errs.append(np.full(len(PHASES) - 1, np.nan))
    t2 = time.perf_counter()
    keep = [i for i, d in enumerate(demos) if not only_successful or d.meta.get("seated", True)]
    skill = InsertionSkill(n_components).fit([demos[i] for i in keep], [labels[i] for i in keep])
    t3 = time.perf_counter()
    return LearnedInsertion(skill, seg, aligned, labels, np.array(errs),
                            {"sync": t1 - t0, "decompose": t2 - t1, "train": t3 - t2, "total": t3 - t0})


# ------------------------------------------------------------------------------ evaluations
def dtw_speed(*, length: int = 1000, dims: int = 6, window: int = 100, reps: int = 15, pairs: int = 20,
              seed: int = 0) -> dict:
    """Our DTW against ``dtaidistance`` (its C ``distance_fast``) on random walks: median ms of each
    on one (length, dims) pair with the band ``window``, measured in the same run, and the largest
    |distance difference| over ``pairs`` random pairs of mixed lengths."""
    from dtaidistance import dtw_ndim

    from robointel.learning.dtw import dtw_distance

    rng = np.random.default_rng(seed)
    a = np.cumsum(rng.normal(size=(length, dims)), 0)
    b = np.cumsum(rng.normal(size=(length, dims)), 0)

    def med(fn):
        fn()
        ts = []
        for _ in range(reps):
            t = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t)
        return float(np.median(ts) * 1e3)

    ours = med(lambda: dtw_distance(a, b, window=window))
    peer = med(lambda: dtw_ndim.distance_fast(a, b, window=window))
    diff = 0.0
    for _ in range(pairs):
        n, m = rng.integers(length // 4, length + 1, 2)
        x, y = rng.normal(size=(n, dims)), rng.normal(size=(m, dims))
        diff = max(diff, abs(dtw_distance(x, y, window=window) - dtw_ndim.distance_fast(x, y, window=window)))
    return {"dtw_ms": ours, "dtaidistance_ms": peer, "dtw_max_abs_diff": diff}


def gmr_agreement(model, X: np.ndarray) -> float:
    """max |our GMR mean - the ``gmr`` package's| on inputs ``X`` for the same mixture."""
    import gmr as gmr_peer

    g = model.gmr if hasattr(model, "gmr") else model
    peer = gmr_peer.GMM(len(g.priors_), priors=g.priors_, means=g.means_, covariances=g.covariances_)
    ix = list(range(g.n_inputs_))
    return float(np.abs(g.predict(X) - peer.predict(ix, X)).max())


def lasa_rmse(*, n_components: int = 8, samples: int = 100, names: Sequence[str] | None = None) -> dict:
    """GMR reproduction of the LASA shapes: for each shape a GMM over (t, x, y) of its 7
    demonstrations, the GMR mean x(t), y(t) against the demonstrations' mean (mm RMSE)."""
    from robointel.learning.datasets import lasa_names, load_lasa
    from robointel.learning.gmr import GaussianMixtureRegression

    out = {}
    for name in names or lasa_names():
        s = load_lasa(name)
        idx = np.linspace(0, s.pos.shape[1] - 1, samples).astype(int)
        t = np.tile(np.linspace(0, 1, samples), len(s.pos))
        P = s.pos[:, idx].reshape(-1, 2)
        m = GaussianMixtureRegression(n_components, random_state=0).fit(t[:, None], P)
        pred = m.predict(np.linspace(0, 1, samples)[:, None])
        out[name] = float(np.sqrt(np.mean((pred - s.pos[:, idx].mean(0)) ** 2)))
    vals = np.array(list(out.values()))
    return {"mean_mm": float(vals.mean()), "median_mm": float(np.median(vals)), "max_mm": float(vals.max()),
            "shapes": len(vals)}


def ft_episode_features(X: np.ndarray) -> np.ndarray:
    """Features of F/T episodes ``X`` (n, T, 6) -> (n, 8 * 6 + 6 * T): per channel the mean, std,
    min, max, first and last sample, least-squares slope and mean absolute step, plus the raw
    samples, all through a signed log (sign(x) log(1 + |x|): the counts span four decades between
    normal runs and collisions)."""
    X = np.asarray(X, float)
    if X.ndim != 3 or X.shape[2] != 6 or X.shape[1] < 2:
        raise InvalidInput(f"F/T episodes must be (n, T >= 2, 6), got {X.shape}", value=X.shape)
    t = np.arange(X.shape[1]) - 0.5 * (X.shape[1] - 1)
    slope = (X * t[None, :, None]).sum(1) / (t ** 2).sum()
    F = np.concatenate([X.mean(1), X.std(1), X.min(1), X.max(1), X[:, 0], X[:, -1], slope,
                        np.abs(np.diff(X, axis=1)).mean(1), X.reshape(len(X), -1)], 1)
    return np.sign(F) * np.log1p(np.abs(F))


def ft_svm_accuracy(*, folds: int = 5) -> dict:
    """Soft-margin RBF SVM on the UCI robot-failure F/T episodes (lp1-lp5): stratified k-fold
    cross-validated accuracy per problem, features :func:`ft_episode_features` (standardised), C and
    gamma chosen by an inner 3-fold grid search on each training fold only (nested: the held-out
    fold never picks a parameter)."""
    import warnings

    from sklearn.model_selection import GridSearchCV, StratifiedKFold, cross_val_score
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC

    from robointel.learning.datasets import load_ft

    acc = {}
    for p in ("lp1", "lp2", "lp3", "lp4", "lp5"):
        e = load_ft(p)
        X = ft_episode_features(e.X)
        k = min(folds, int(np.bincount(e.y).min()))
        cv = StratifiedKFold(n_splits=max(2, k), shuffle=True, random_state=0)
        inner = StratifiedKFold(n_splits=max(2, min(3, k)), shuffle=True, random_state=1)
        clf = GridSearchCV(make_pipeline(StandardScaler(), SVC()),
                           {"svc__C": [1.0, 10.0, 100.0], "svc__gamma": ["scale", 0.01, 0.001]}, cv=inner)
        with warnings.catch_warnings():  # classes smaller than the inner folds: sklearn warns, still valid
            warnings.simplefilter("ignore", UserWarning)
            acc[p] = float(cross_val_score(clf, X, e.y, cv=cv).mean())
    acc["mean"] = float(np.mean([acc[p] for p in ("lp1", "lp2", "lp3", "lp4", "lp5")]))
    return acc
