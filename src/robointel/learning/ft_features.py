"""Features of force/torque episodes for failure classification (Sec. 5.4, the UCI robot-failure data)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput


def ft_episode_features(X: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Features of F/T episodes for an SVM.

    Per channel the mean, std, min, max, first and last sample, least-squares slope and mean absolute
    step, plus the raw samples, all through a signed log sign(x) log(1 + |x|) (the counts span four
    decades between normal runs and collisions).

    Args:
        X: (n, T, 6) episodes, T >= 2.

    Returns:
        (n, 8 * 6 + 6 * T) features.

    Raises:
        InvalidInput: ``X`` is not (n, T >= 2, 6).
    """
    X = np.asarray(X, float)
    if X.ndim != 3 or X.shape[2] != 6 or X.shape[1] < 2:
        raise InvalidInput(f"F/T episodes must be (n, T >= 2, 6), got {X.shape}", value=X.shape)
    t = np.arange(X.shape[1]) - 0.5 * (X.shape[1] - 1)
    slope = (X * t[None, :, None]).sum(1) / (t ** 2).sum()
    F = np.concatenate([X.mean(1), X.std(1), X.min(1), X.max(1), X[:, 0], X[:, -1], slope,
                        np.abs(np.diff(X, axis=1)).mean(1), X.reshape(len(X), -1)], 1)
    return np.sign(F) * np.log1p(np.abs(F))
