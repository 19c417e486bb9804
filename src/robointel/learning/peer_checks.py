"""Side-by-side checks of the learning pipeline's parts against their peer libraries (dtaidistance, gmr)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel._extras import needs_extra
from robointel.learning.dtw import dtw_distance


def dtw_speed(*, length: int = 1000, dims: int = 6, window: int = 100, reps: int = 15, pairs: int = 20,
              seed: int = 0) -> dict[str, float]:
    """Our DTW against ``dtaidistance`` (its C ``distance_fast``) on random walks, measured in the same run.

    Args:
        length: Length of the timed pair.
        dims: Dimensions of the series.
        window: Sakoe-Chiba band (samples).
        reps: Timed repetitions.
        pairs: Random pairs of mixed lengths compared for agreement.
        seed: Random seed.

    Returns:
        ``dtw_ms`` and ``dtaidistance_ms`` (medians) and ``dtw_max_abs_diff`` (largest |distance difference|).
    """
    with needs_extra("peers", "the dtaidistance comparison"):
        from dtaidistance import dtw_ndim  # a peer, imported only when compared

    rng = np.random.default_rng(seed)
    a = np.cumsum(rng.normal(size=(length, dims)), 0)
    b = np.cumsum(rng.normal(size=(length, dims)), 0)

    def med(fn: Callable[[], object]) -> float:
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


def gmr_agreement(model: Any, X: npt.NDArray[np.float64]) -> float:
    """Largest |our GMR mean - the ``gmr`` package's| on inputs ``X`` for the same mixture.

    Args:
        model: A fitted :class:`~robointel.learning.gmr.GaussianMixtureRegression` (or an object with ``.gmr``).
        X: (n, d_in) inputs.

    Returns:
        The largest absolute difference.
    """
    with needs_extra("peers", "the gmr comparison"):
        import gmr as gmr_peer  # a peer, imported only when compared

    g = model.gmr if hasattr(model, "gmr") else model
    peer = gmr_peer.GMM(len(g.priors_), priors=g.priors_, means=g.means_, covariances=g.covariances_)
    ix = list(range(g.n_inputs_))
    return float(np.abs(g.predict(X) - peer.predict(ix, X)).max())
