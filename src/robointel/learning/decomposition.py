"""Action decomposition by sliding-window SVMs, Algorithm 1 and (5.7)-(5.13).

A demonstration is a sequence of actions in a known order (e.g. approach, rotation, insertion,
completion). From a few labelled demonstrations we learn, per action ``a``:

- the feature vector of each sample ``x_t`` (5.7): vec(T_t) (rotation and position), the wrench and the
  tool velocity, standardised with the training statistics;
- a window ``W_t = [x_{t-w/2}, ..., x_{t+w/2-1}]`` of ``w`` samples around each time t (5.8);
- a reference window ``R_a`` (the mean training window of action ``a``) onto which every window is
  DTW-aligned, so each window is brought to the trained action's time base (5.9)-(5.10);
- a soft-margin SVM (scikit-learn ``SVC``, RBF kernel, penalty C) on the windows aligned to every
  action's reference, one-vs-rest decision value per action (5.11).

For a new demonstration the score map ``S[a, t]`` is the SVM decision value of every window (5.12) and
the split points are the ordered segmentation maximising the summed scores (5.13), found by dynamic
programming over the action order.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray
from sklearn.metrics.pairwise import rbf_kernel
from sklearn.svm import SVC

from robointel._validate import as_array
from robointel.errors import InvalidInput, ShapeError
from robointel.learning.demonstration import Demonstration

#: any numpy array (the compiled kernels take contiguous float64/int64/bool arrays)
Arr = NDArray[Any]


def demo_features(demo: Demonstration, *, smooth: int = 5) -> np.ndarray:
    """Per-sample features (5.7) of a demonstration.

    Vec(T) (12) with the position expressed in the task frame (relative to the demonstration's final tool position,
    where the task completes), wrench (6), tool linear velocity (3) and angular velocity (3) from smoothed finite
    differences. Returns (N, 24).
    """
    f = demo.features(wrench=True)
    f[:, 9:12] -= demo.position[-1]
    p = demo.position
    if smooth > 1:
        k = np.ones(smooth) / smooth
        pad = smooth // 2
        pp = np.pad(p, ((pad, smooth - 1 - pad), (0, 0)), mode="edge")
        p = np.stack([np.convolve(pp[:, i], k, mode="valid") for i in range(3)], 1)
    v = np.gradient(p, demo.t, axis=0)
    R = demo.pose[:, :3, :3]
    dR = np.gradient(R, demo.t, axis=0)
    W = np.einsum("nij,nkj->nik", dR, R)  # dR R^T, skew-symmetric
    w = 0.5 * np.stack([W[:, 2, 1] - W[:, 1, 2], W[:, 0, 2] - W[:, 2, 0], W[:, 1, 0] - W[:, 0, 1]], 1)
    return np.concatenate([f, v, w], axis=1)


@numba.njit(cache=True)
def _windows(X: Arr, centers: Arr, w: int) -> Arr:
    n, f = X.shape
    out = np.empty((centers.shape[0], w, f))
    h = w // 2
    for i in range(centers.shape[0]):
        for k in range(w):
            j = min(max(centers[i] - h + k, 0), n - 1)
            out[i, k] = X[j]
    return out


@numba.njit(cache=True)
def _warp_windows(W: Arr, R: Arr, band: int) -> Arr:
    """DTW-align each window W[i] (w, F) onto the reference R (w, F) with a Sakoe-Chiba band.

    Sample j of the result is the mean of the window samples matched to R[j] (5.9)-(5.10).
    """
    nw, w, f = W.shape
    out = np.zeros((nw, w, f))
    acc = np.empty((w, w))
    cnt = np.zeros(w)
    for q in range(nw):
        for i in range(w):
            for j in range(w):
                acc[i, j] = np.inf
        for i in range(w):
            lo = max(0, i - band + 1)
            hi = min(w, i + band)
            for j in range(lo, hi):
                c = 0.0
                for k in range(f):
                    t = W[q, i, k] - R[j, k]
                    c += t * t
                if i == 0 and j == 0:
                    best = 0.0
                else:
                    best = np.inf
                    if i > 0 and j > 0 and acc[i - 1, j - 1] < best:
                        best = acc[i - 1, j - 1]
                    if i > 0 and acc[i - 1, j] < best:
                        best = acc[i - 1, j]
                    if j > 0 and acc[i, j - 1] < best:
                        best = acc[i, j - 1]
                acc[i, j] = c + best
        for j in range(w):
            cnt[j] = 0.0
        i, j = w - 1, w - 1
        while True:
            for k in range(f):
                out[q, j, k] += W[q, i, k]
            cnt[j] += 1.0
            if i == 0 and j == 0:
                break
            if i == 0:
                j -= 1
            elif j == 0:
                i -= 1
            else:
                d0, d1, d2 = acc[i - 1, j - 1], acc[i - 1, j], acc[i, j - 1]
                if d0 <= d1 and d0 <= d2:
                    i -= 1
                    j -= 1
                elif d1 <= d2:
                    i -= 1
                else:
                    j -= 1
        for j in range(w):
            for k in range(f):
                out[q, j, k] /= cnt[j]
    return out


def ordered_segmentation(scores: np.ndarray) -> np.ndarray:
    """Split points (5.13).

    For scores (A, T) find 0 < b_1 <= ... <= b_{A-1} <= T maximising sum_a sum_{b_a <= t < b_{a+1}} scores[a, t]
    (actions in order, each at least one step). Returns the A-1 split indices (first step of actions 1..A-1).
    """
    a_n, t_n = scores.shape
    if t_n < a_n:
        raise InvalidInput(f"{t_n} windows cannot hold {a_n} ordered actions")
    cum = np.concatenate([np.zeros((a_n, 1)), np.cumsum(scores, axis=1)], axis=1)
    # best[a, t]: best score of actions 0..a covering steps [0, t)
    best = np.full((a_n, t_n + 1), -np.inf)
    arg = np.zeros((a_n, t_n + 1), dtype=np.int64)
    best[0] = cum[0]
    best[0, 0] = -np.inf
    for a in range(1, a_n):
        # best[a, t] = max_{s < t} best[a-1, s] + cum[a, t] - cum[a, s]
        val = best[a - 1] - cum[a]
        run = np.maximum.accumulate(val)
        runarg = np.zeros(t_n + 1, dtype=np.int64)
        cur = 0
        for s in range(t_n + 1):
            if val[s] >= val[cur]:
                cur = s
            runarg[s] = cur
        best[a, 1:] = run[:-1] + cum[a, 1:]
        arg[a, 1:] = runarg[:-1]
    splits = np.zeros(a_n - 1, dtype=np.int64)
    t = t_n
    for a in range(a_n - 1, 0, -1):
        t = int(arg[a, t])
        splits[a - 1] = t
    return splits


@dataclass(frozen=True)
class Decomposition:
    """Result for one demonstration.

    ``labels`` (N,) action per sample, ``splits`` (A-1,) sample index of each action's first sample, ``scores`` (A,
    n_windows) and the window ``centers``.
    """

    labels: np.ndarray
    splits: np.ndarray
    scores: np.ndarray
    centers: np.ndarray


class ActionSegmenter:
    """Algorithm 1: sliding-window, DTW-aligned, soft-margin SVM action decomposition.

    Args:
        window: window length w in samples (5.8).
        band: Sakoe-Chiba band of the window alignment (samples).
        stride: windows are scored every ``stride`` samples.
        resample: points kept per aligned window for the SVM descriptor.
        C: the SVM's soft-margin penalty (scikit-learn ``SVC``).
        gamma: the SVM's RBF width (scikit-learn ``SVC``).
    """

    def __init__(self, *, window: int = 30, band: int = 6, stride: int = 2, resample: int = 10,
                 C: float = 10.0, gamma: str | float = "scale", max_train_windows: int = 3000,
                 random_state: int = 0) -> None:
        if window < 2 or band < 1 or stride < 1 or resample < 1:
            raise InvalidInput("window >= 2, band >= 1, stride >= 1 and resample >= 1 are required")
        self.window, self.band, self.stride, self.resample = int(window), int(band), int(stride), int(resample)
        self.C, self.gamma = C, gamma
        self.max_train_windows = int(max_train_windows)
        self.random_state = random_state

    def _check_series(self, X: ArrayLike, name: str) -> NDArray[np.float64]:
        X = as_array(X, name, (None, None))
        if hasattr(self, "n_features_") and X.shape[1] != self.n_features_:
            raise ShapeError(f"{name} has {X.shape[1]} features, the segmenter was trained on {self.n_features_}")
        if X.shape[0] < self.window:
            raise InvalidInput(f"{name} has {X.shape[0]} samples, fewer than the window of {self.window}; "
                               "use a shorter window", value=X.shape[0])
        return X

    def _descriptors(self, Xs: np.ndarray, centers: np.ndarray, a: int) -> NDArray[np.float64]:
        W = _windows(Xs, centers, self.window)
        A = _warp_windows(W, self.references_[a], self.band)
        idx = np.linspace(0, self.window - 1, self.resample).round().astype(int)
        return A[:, idx].reshape(len(centers), self.resample * self.n_features_)

    def _descriptor_all(self, Xs: np.ndarray, centers: np.ndarray) -> NDArray[np.float64]:
        return np.concatenate([self._descriptors(Xs, centers, a) for a in range(self.n_actions_)], axis=1)

    def fit(self, series: Sequence, labels: Sequence) -> ActionSegmenter:
        """Train on labelled demonstrations.

        ``series`` list of (N_i, F) features, ``labels`` list of (N_i,) action indices 0..A-1 appearing in order.

        Raises:
            ShapeError: different feature dimensions or label lengths. NotFinite: NaN samples.
            InvalidInput: a window longer than a demonstration, an action never labelled.
        """
        if len(series) == 0 or len(series) != len(labels):
            raise InvalidInput("give as many label arrays as demonstrations (at least one)")
        dims = {np.shape(s)[1] if np.ndim(s) == 2 else -1 for s in series}
        if len(dims) != 1:
            raise ShapeError(f"demonstrations have different feature dimensions {sorted(dims)}", value=sorted(dims))
        Xs = [self._check_series(s, f"series[{i}]") for i, s in enumerate(series)]
        Ls = [np.asarray(l, dtype=np.int64) for l in labels]
        for i, (x, l) in enumerate(zip(Xs, Ls)):
            if l.shape != (x.shape[0],):
                raise ShapeError(f"labels[{i}] must have shape ({x.shape[0]},), got {l.shape}")
        self.n_actions_ = int(max(l.max() for l in Ls)) + 1
        if any(not np.any(np.concatenate(Ls) == a) for a in range(self.n_actions_)):
            raise InvalidInput("every action 0..A-1 must appear in the training labels")
        self.n_features_ = Xs[0].shape[1]
        allx = np.concatenate(Xs)
        self.mean_ = allx.mean(0)
        self.scale_ = allx.std(0)
        self.scale_[self.scale_ < 1e-9 * max(1.0, self.scale_.max())] = 1.0
        Zs = [np.ascontiguousarray((x - self.mean_) / self.scale_) for x in Xs]
        self.lengths_ = np.array([np.median([np.sum(l == a) for l in Ls]) for a in range(self.n_actions_)])
        rng = np.random.default_rng(self.random_state)
        wins, labs = [], []
        for z, l in zip(Zs, Ls):
            c = np.arange(0, z.shape[0], self.stride)
            wins.append((z, c))
            labs.append(l[c])
        y = np.concatenate(labs)
        # reference windows R_a: the mean raw training window of each action
        self.references_ = np.empty((self.n_actions_, self.window, self.n_features_))
        raw = np.concatenate([_windows(z, c, self.window) for z, c in wins])
        for a in range(self.n_actions_):
            self.references_[a] = raw[y == a].mean(0)
        keep = np.arange(len(y))
        if len(keep) > self.max_train_windows:
            keep = np.sort(rng.choice(len(y), self.max_train_windows, replace=False))
        # descriptors (windows DTW-aligned to every action's reference) of the kept windows only
        starts = np.cumsum([0] + [len(c) for _, c in wins])
        D = np.concatenate([self._descriptor_all(z, c[keep[(keep >= s0) & (keep < s1)] - s0])
                            for (z, c), s0, s1 in zip(wins, starts[:-1], starts[1:])])
        # one soft-margin SVM over the windows aligned to every action's reference: its one-vs-rest
        # decision values are comparable across actions (separately trained binary SVMs are not).
        # The RBF kernel exp(-gamma |d_i - d_j|^2) is evaluated by scikit-learn's BLAS-backed
        # ``rbf_kernel`` and handed to libsvm precomputed (libsvm's own per-pair loops cost seconds on
        # the ~1000-dimensional descriptors); the SVM is the same as ``SVC(kernel="rbf")``.
        if isinstance(self.gamma, str):
            if self.gamma == "scale":
                var = D.var()
                self.gamma_ = 1.0 / (D.shape[1] * var) if var > 0 else 1.0
            elif self.gamma == "auto":
                self.gamma_ = 1.0 / D.shape[1]
            else:
                raise InvalidInput(f"gamma must be 'scale', 'auto' or a positive float, got {self.gamma!r}",
                                   value=self.gamma)
        else:
            self.gamma_ = float(self.gamma)
        self.svm_ = SVC(C=self.C, kernel="precomputed", class_weight="balanced",
                        decision_function_shape="ovr").fit(rbf_kernel(D, gamma=self.gamma_), y[keep])
        self.support_descriptors_ = D[self.svm_.support_]
        self.n_train_windows_ = len(D)
        return self

    def _decision(self, D: np.ndarray) -> np.ndarray:
        """One-vs-rest SVM decision values (n, A) of descriptors (n, P).

        Only the support vectors enter an SVM's decision function, so only their kernel columns are evaluated (the
        others multiply zero dual coefficients and are left at zero).
        """
        K = np.zeros((len(D), self.n_train_windows_))
        K[:, self.svm_.support_] = rbf_kernel(D, self.support_descriptors_, gamma=self.gamma_)
        return self.svm_.decision_function(K)

    def score_map(self, X: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Score map (5.12): (A, n_windows) SVM decision values and the window centres (n_windows,)."""
        if not hasattr(self, "svm_"):
            raise InvalidInput("the segmenter is not fitted; call fit first")
        X = self._check_series(X, "X")
        z = np.ascontiguousarray((X - self.mean_) / self.scale_)
        c = np.arange(0, z.shape[0], self.stride)
        S = self._decision(self._descriptor_all(z, c)).T
        return S, c

    def predict(self, X: ArrayLike) -> Decomposition:
        """Decompose one demonstration (N, F) into the ordered actions (5.13)."""
        S, c = self.score_map(X)
        split_w = ordered_segmentation(S)
        n = np.shape(X)[0]
        splits = c[split_w] - self.stride // 2 if self.stride > 1 else c[split_w]
        splits = np.clip(splits, 1, n - 1)
        labels = np.zeros(n, dtype=np.int64)
        for a, s in enumerate(splits):
            labels[s:] = a + 1
        return Decomposition(labels, splits, S, c)
