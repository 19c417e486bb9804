import numpy as np
import pytest

from robointel.errors import InvalidInput, ShapeError
from robointel.learning.decomposition import ActionSegmenter, ordered_segmentation


def _series(rng, dt=0.01):
    """Four ordered phases with random durations, distinct dynamics and noise: returns X, labels."""
    durs = rng.uniform([1.0, 0.6, 1.2, 0.5], [1.6, 1.0, 2.0, 0.8])
    xs, ls = [], []
    pos = np.zeros(3)
    for a, d in enumerate(durs):
        n = int(d / dt)
        s = np.linspace(0, 1, n)
        f = np.zeros((n, 6))
        if a == 0:
            v = np.tile([0.05, 0.02, 0.0], (n, 1)) * np.sin(np.pi * s)[:, None]
        elif a == 1:
            v = np.zeros((n, 3))
            f[:, 3] = 0.3 * np.sin(np.pi * s)
        elif a == 2:
            v = np.tile([0, 0, -0.01], (n, 1))
            f[:, 2] = -10 + rng.normal(0, 1, n)
        else:
            v = np.zeros((n, 3))
            f[:, 2] = -25 * (1 - s)
        p = pos + np.cumsum(v, 0) * dt
        pos = p[-1]
        xs.append(np.concatenate([p, v, f], 1) + rng.normal(0, 0.002, (n, 12)))
        ls.append(np.full(n, a))
    return np.concatenate(xs), np.concatenate(ls)


def test_ordered_segmentation_exact():
    S = -np.ones((3, 10))
    S[0, :3] = 1
    S[1, 3:7] = 1
    S[2, 7:] = 1
    np.testing.assert_array_equal(ordered_segmentation(S), [3, 7])


def test_segmenter_finds_boundaries_within_50ms():
    rng = np.random.default_rng(3)
    train = [_series(rng) for _ in range(6)]
    seg = ActionSegmenter(window=30, band=6, stride=2).fit([x for x, _ in train], [l for _, l in train])
    errs = []
    for _ in range(6):
        x, l = _series(rng)
        d = seg.predict(x)
        truth = np.flatnonzero(np.diff(l)) + 1
        errs.extend(np.abs(d.splits - truth) * 0.01)
        assert d.labels.shape == l.shape and np.all(np.diff(d.labels) >= 0)
    assert np.median(errs) <= 0.05


def test_bad_input():
    rng = np.random.default_rng(0)
    x, l = _series(rng)
    with pytest.raises(InvalidInput):
        ActionSegmenter(window=10_000).fit([x], [l])  # window longer than the demonstration
    with pytest.raises(ShapeError):
        ActionSegmenter().fit([x, x[:, :5]], [l, l])
    seg = ActionSegmenter(window=20).fit([x], [l])
    with pytest.raises(ShapeError):
        seg.predict(x[:, :5])


def test_precomputed_kernel_svm_equals_rbf_svc():
    """The segmenter evaluates the RBF kernel with BLAS and hands it to libsvm precomputed; its score
    map equals scikit-learn's ``SVC(kernel="rbf")`` trained on the same aligned-window descriptors."""
    from sklearn.svm import SVC

    rng = np.random.default_rng(5)
    train = [_series(rng) for _ in range(3)]
    seg = ActionSegmenter(window=20, band=4, stride=3, max_train_windows=10**6)
    seg.fit([x for x, _ in train], [l for _, l in train])
    D, y = [], []
    for x, l in train:
        z = np.ascontiguousarray((x - seg.mean_) / seg.scale_)
        c = np.arange(0, len(x), seg.stride)
        D.append(seg._descriptor_all(z, c))
        y.append(l[c])
    ref = SVC(C=seg.C, gamma="scale", kernel="rbf", class_weight="balanced",
              decision_function_shape="ovr").fit(np.concatenate(D), np.concatenate(y))
    x, _ = _series(rng)
    S, c = seg.score_map(x)
    z = np.ascontiguousarray((x - seg.mean_) / seg.scale_)
    np.testing.assert_allclose(S, ref.decision_function(seg._descriptor_all(z, c)).T, atol=1e-6)
    np.testing.assert_array_equal(np.sort(seg.svm_.support_), np.sort(ref.support_))


def test_subsampled_training_windows():
    """With ``max_train_windows`` far below the window count (some demonstrations keep no window),
    the SVM is trained on that many windows and still decomposes."""
    rng = np.random.default_rng(7)
    train = [_series(rng) for _ in range(8)]
    seg = ActionSegmenter(window=20, band=4, stride=2, max_train_windows=12, random_state=1)
    seg.fit([x for x, _ in train], [l for _, l in train])
    assert seg.n_train_windows_ == 12
    x, l = _series(rng)
    d = seg.predict(x)
    assert d.labels.shape == l.shape and np.all(np.diff(d.labels) >= 0)
