import numpy as np
import pytest
from dtaidistance import dtw_ndim

from robointel.errors import NotFinite, ShapeError
from robointel.learning.dtw import align, dtw, dtw_distance, warp_to


@pytest.mark.parametrize("window", [None, 1, 3, 10])
def test_matches_dtaidistance_distance_and_path(window):
    rng = np.random.default_rng(7)
    for _ in range(30):
        n, m, d = rng.integers(2, 40), rng.integers(2, 40), rng.integers(1, 5)
        a, b = rng.normal(size=(n, d)), rng.normal(size=(m, d))
        ref = dtw_ndim.distance_fast(a, b, window=window)
        assert abs(dtw_distance(a, b, window=window) - ref) < 1e-9
        res = dtw(a, b, window=window)
        assert abs(res.distance - ref) < 1e-9
        assert [tuple(p) for p in res.path.tolist()] == [tuple(p) for p in dtw_ndim.warping_path(a, b, window=window)]


def test_long_6d_window_100():
    rng = np.random.default_rng(1)
    a, b = np.cumsum(rng.normal(size=(1000, 6)), 0), np.cumsum(rng.normal(size=(900, 6)), 0)
    assert abs(dtw_distance(a, b, window=100) - dtw_ndim.distance_fast(a, b, window=100)) < 1e-9


def test_path_properties_and_alignment_recovers_time_warp():
    t = np.linspace(0, 1, 200)
    ref = np.stack([np.sin(2 * np.pi * t), np.cos(3 * t)], 1)
    warped_t = t ** 1.3  # a slower start, a faster end
    s = np.stack([np.sin(2 * np.pi * warped_t), np.cos(3 * warped_t)], 1)
    res = dtw(s, ref)
    steps = np.diff(res.path, axis=0)
    assert tuple(res.path[0]) == (0, 0) and tuple(res.path[-1]) == (199, 199)
    assert np.all((steps >= 0) & (steps <= 1)) and np.all(steps.sum(1) >= 1)
    out = align([s, ref], reference=1)
    assert out[0].shape == ref.shape
    assert np.abs(out[0] - ref).max() < 0.05
    np.testing.assert_allclose(out[1], ref)
    assert warp_to(s[:, 0], ref[:, 0]).shape == (200,)
    assert dtw_distance(s, s) == 0.0


def test_bad_input():
    with pytest.raises(ShapeError):
        dtw_distance(np.zeros((5, 2)), np.zeros((5, 3)))
    with pytest.raises(ShapeError):
        align([np.zeros((5, 2)), np.zeros((6, 3))])
    x = np.zeros((5, 2))
    x[2, 1] = np.nan
    with pytest.raises(NotFinite):
        dtw(x, np.zeros((5, 2)))
