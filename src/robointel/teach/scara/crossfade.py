"""The crossfaded reference: lag-free shaping of a predicted signal (Ch. 3.2).

At each frame arrival, a quintic smoothstep from the reference as it was to the new frame's prediction.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from robointel.teach.scara.predictors import Predictor


def smoothstep(x: float) -> tuple[float, float, float]:
    """Quintic smoothstep s(x) = 10 x^3 - 15 x^4 + 6 x^5 on [0, 1] and its first two derivatives.

    Args:
        x: the phase (clipped to [0, 1]).

    Returns:
        (s, ds/dx, d2s/dx2).
    """
    x = min(max(x, 0.0), 1.0)
    return (x ** 3 * (10 - 15 * x + 6 * x * x), 30 * x * x * (1 - x) ** 2, 60 * x * (1 - x) * (1 - 2 * x))


class Transition:
    """One piece of the blended reference.

    From the reference as it was before a frame arrived (``prev``) to the prediction made with that
    frame, over a smoothstep of ``tb`` seconds per joint starting at the arrival ``a``; predictions
    are taken as linear in time (p'' = 0). Both ends estimate the same instant, so the crossfade
    adds no lag.

    Args:
        pred: the predictor as it was right after the frame (a copy; it is not updated again).
        a: arrival time of the frame [s].
        tb: (n,) crossfade length per joint [s].
        prev: the piece before (None: none, the prediction alone).
        horizon: the time [s] to predict for, given the predictor.
    """

    def __init__(self, pred: Predictor, a: float, tb: npt.ArrayLike, prev: Transition | None,
                 horizon: Callable[[Predictor], float]) -> None:
        self.pred, self.a, self.tb, self.prev, self.horizon = pred, a, np.asarray(tb, float), prev, horizon

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(r, r', r'') (n,) each [rad, rad/s, rad/s^2] at time ``t`` [s] (non-decreasing over calls)."""
        p, v = self.pred.predict(self.horizon(self.pred))
        x = (t - self.a) / self.tb
        if self.prev is not None and np.all(x >= 1.0):
            self.prev = None  # the transition is over: the older pieces are never needed again
        if self.prev is None:
            return p, v, np.zeros_like(p)
        q0, v0, a0 = self.prev(t)
        s, s1, s2 = (np.array(z) for z in zip(*(smoothstep(xi) for xi in x)))
        s1, s2, d = s1 / self.tb, s2 / self.tb ** 2, p - q0
        return q0 + s * d, v0 + s * (v - v0) + s1 * d, (1 - s) * a0 + 2 * s1 * (v - v0) + s2 * d
