"""Learned delay compensation (Ch. 3.2): a linear autoregressive predictor of the human angles.

It is fitted by ridge regression on recordings other than the one it runs on.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline
from sklearn.linear_model import Ridge
from sklearn.model_selection import GridSearchCV, LeaveOneGroupOut

from robointel.errors import DataMissing, InvalidInput
from robointel.io.reference import data_path
from robointel.robot import Robot
from robointel.teach.scara.angles import human_reference
from robointel.teach.scara.settings import LIVE_CUTOFF_HZ
from robointel.teach.skeleton import Skeleton, read_kinect_csv, synthetic_wave

Run = tuple[npt.ArrayLike, npt.ArrayLike, npt.ArrayLike]


class ARPredictor:
    """Linear autoregressive predictor of the human joint angles across the latency.

    Fitted by ridge regression (``sklearn.linear_model.Ridge``) on recordings other than the one
    it runs on.

    From the newest received frame q_k (captured at t_k) and the P frames before it, the angle of
    joint c at t_k + h is

        q_c(t_k + h) = q_c,k + w' (phi_c,k kron [1, h, ..., h^poly]),
        phi_c,k = [q_c,k-1 - q_c,k, ..., q_c,k-P - q_c,k,  (the same for the other joints c+1, c+2, ...)],

    one weight vector shared by the joints (each joint sees its own past first, then the others').
    The features are differences to the newest frame, so the prediction does not depend on where
    the arm is, only on how it has been moving; no intercept. The horizon h (latency plus the age
    of the frame) enters polynomially. The ridge strength is chosen by leave-one-recording-out
    cross-validation *within* the training recordings (``GridSearchCV`` + ``LeaveOneGroupOut``).

    Args:
        weights: (n * P * (poly + 1),) regression weights (``n`` = number of joints).
        order: P, number of past frames.
        poly: degree of the horizon polynomial.
        alpha: the ridge strength it was fitted with (for the record).
    """

    def __init__(self, weights: npt.ArrayLike, order: int = 10, poly: int = 1, alpha: float = float("nan")) -> None:
        self.order, self.poly, self.alpha = int(order), int(poly), float(alpha)
        w = np.asarray(weights, float).ravel()
        per = self.order * (self.poly + 1)
        if self.order < 1 or self.poly < 0 or w.size == 0 or w.size % per:
            raise InvalidInput(f"ARPredictor: {w.size} weights do not fit order {order}, poly {poly}")
        if not np.all(np.isfinite(w)):
            raise InvalidInput("ARPredictor weights must be finite")
        self.w, self.n = w, w.size // per
        self.hist: list[np.ndarray] = []
        self.t: float | None = None
        self._f = np.zeros((self.n, self.n * self.order))

    @staticmethod
    def _features(hist: np.ndarray, order: int) -> np.ndarray:
        """(n, n * P) features per joint from the last frames ``hist`` (m, n), oldest first.

        Missing early frames repeat the first one (zero differences).
        """
        hist = np.asarray(hist, float)
        h = hist[-(order + 1):]
        if len(h) < order + 1:
            h = np.vstack([np.repeat(h[:1], order + 1 - len(h), 0), h])
        d = (h[:-1] - h[-1])[::-1]  # (P, n): q_{k-1} - q_k first
        n = h.shape[1]
        return np.stack([np.concatenate([d[:, (c + r) % n] for r in range(n)]) for c in range(n)])

    @staticmethod
    def _design(f: np.ndarray, h: np.ndarray, poly: int) -> np.ndarray:
        """Rows f kron [1, h, ..h^poly]: f (m, K), h (m,) -> (m, K * (poly + 1))."""
        return np.einsum("mk,md->mkd", f, np.asarray(h, float)[:, None] ** np.arange(poly + 1)).reshape(len(f), -1)

    def reset(self) -> None:
        """Forget all frames."""
        self.hist, self.t = [], None

    def update(self, t: float, z: npt.ArrayLike) -> None:
        """Add the frame (n,) [rad] captured at time ``t`` [s].

        Raises:
            InvalidInput: the frame does not have the fitted number of joints.
        """
        z = np.asarray(z, float)
        if z.shape != (self.n,):
            raise InvalidInput(f"ARPredictor was fitted for {self.n} joints, got a frame of shape {z.shape}")
        self.hist.append(z.copy())
        if len(self.hist) > self.order + 1:
            self.hist.pop(0)
        self.t = t
        self._f = self._features(np.asarray(self.hist), self.order)  # (n, n P)

    def predict(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(angle (n,) [rad], rate (n,) [rad/s]) predicted at time ``t`` from the frames received so far."""
        if self.t is None:
            raise InvalidInput("ARPredictor.predict before the first update: give it a frame first")
        h = t - self.t
        f = self._f
        W = self.w.reshape(-1, self.poly + 1)  # (n P, poly + 1)
        hv = h ** np.arange(self.poly + 1)
        dv = np.concatenate([[0.0], np.arange(1, self.poly + 1) * h ** np.arange(self.poly)])
        return self.hist[-1] + f @ W @ hv, f @ W @ dv

    @classmethod
    def fit(cls, runs: Iterable[Run], *, latency: float = 0.1, order: int = 10, poly: int = 1,
            alphas: Sequence[float] = (1e-3, 1e-1, 1e1, 1e3), dt: float = 0.004, span: float | None = None,
            rate_weight: float = 0.03) -> ARPredictor:
        """Fit on recordings by ridge regression, the ridge strength chosen leave-one-recording-out.

        Args:
            runs: iterable of (t (N,), q_true (N, n), q_meas (N, n)) as returned by
                :func:`human_reference` (uniform frame times [s], true angles, angles as received live).
            latency: sensor latency [s]; trained on horizons from ``latency`` to ``latency`` + ``span``.
            order: P, the number of past frames.
            poly: the horizon polynomial's degree.
            alphas: ridge strengths to choose from by leave-one-recording-out cross-validation over
                ``runs`` (with fewer than 3 recordings the middle one is used).
            dt: spacing of the training horizons [s].
            span: range of horizons beyond the latency [s] (default one frame period: the age of
                the newest frame runs from 0 to one period).
            rate_weight: [s] weight of extra rows fitting the prediction's slope in h to the true
                angle rate (in rad/s, times ``rate_weight``); over a horizon range of one frame
                period the slope is otherwise barely determined and comes out arbitrary (on a ramp
                it is off by a third).

        Returns:
            The fitted predictor.

        Raises:
            InvalidInput: a run is malformed, or no run is longer than the latency.
        """
        X: list[np.ndarray] = []
        Y: list[np.ndarray] = []
        G: list[np.ndarray] = []
        for g, run in enumerate(runs):
            t_h, q_true, q_meas = (np.asarray(x, float) for x in run)
            if q_true.ndim != 2 or q_true.shape != q_meas.shape or len(t_h) != len(q_true) or len(t_h) < 4:
                raise InvalidInput("ARPredictor.fit: each run is (t (N,), q_true (N, n), q_meas (N, n)), N >= 4")
            spline = CubicSpline(t_h, q_true, axis=0)
            T = float(np.median(np.diff(t_h)))
            hs = np.arange(latency, latency + (T if span is None else float(span)), dt)
            jj, hh = (a.ravel() for a in np.meshgrid(np.arange(len(t_h)), hs, indexing="ij"))
            ok = t_h[jj] + hh <= t_h[-1]
            jj, hh = jj[ok], hh[ok]
            if len(jj) == 0:
                continue
            F = np.stack([cls._features(q_meas[max(0, j - order):j + 1], order) for j in range(len(t_h))])
            target = spline(t_h[jj] + hh) - q_meas[jj]  # (m, n)
            rate = spline(t_h[jj] + hh, 1)
            dpow = np.concatenate([np.zeros((len(hh), 1)), np.arange(1, poly + 1) * hh[:, None] ** np.arange(poly)], 1)
            for c in range(q_meas.shape[1]):
                X.append(cls._design(F[jj, c], hh, poly))
                Y.append(target[:, c])
                if rate_weight > 0:  # the prediction's slope in h is the rate: fit it to the true rate too
                    X.append(rate_weight * np.einsum("mk,md->mkd", F[jj, c], dpow).reshape(len(jj), -1))
                    Y.append(rate_weight * rate[:, c])
                G.append(np.full(len(jj) * (2 if rate_weight > 0 else 1), g))
        if not X:
            raise InvalidInput("ARPredictor.fit needs at least one recording longer than the latency")
        Xa, Ya, Ga = np.vstack(X), np.concatenate(Y), np.concatenate(G)
        grid = [float(a) for a in alphas]
        if len(np.unique(Ga)) >= 3 and len(grid) > 1:
            search = GridSearchCV(Ridge(fit_intercept=False), {"alpha": grid}, cv=LeaveOneGroupOut(),
                                  scoring="neg_mean_squared_error").fit(Xa, Ya, groups=Ga)
            alpha = float(search.best_params_["alpha"])
        else:
            alpha = grid[len(grid) // 2]
        model = Ridge(alpha=alpha, fit_intercept=False).fit(Xa, Ya)
        return cls(model.coef_, order, poly, alpha)


def fit_predictor(skeletons: Iterable[Skeleton], *, latency: float = 0.1, robot: Robot | None = None,
                  elbow: str = "flexion", live_cutoff_hz: float = LIVE_CUTOFF_HZ, **kw: object) -> ARPredictor:
    """An :class:`ARPredictor` fitted on recordings as the SCARA simulation sees them.

    The angles come from :func:`human_reference`, clipped to the SCARA's joint range. Pass
    recordings other than the one you evaluate on.

    Args:
        skeletons: raw recordings.
        latency: sensor latency [s].
        robot: default ``Robot.load("scara2")``.
        elbow: "flexion" or "planar".
        live_cutoff_hz: causal low-pass of the live signal [Hz].
        **kw: passed to :meth:`ARPredictor.fit`.

    Returns:
        The fitted predictor.

    Raises:
        InvalidInput: no recording given.
    """
    robot = robot or Robot.load("scara2")
    runs = []
    for sk in skeletons:
        t_h, q_true, q_meas = human_reference(sk, elbow=elbow, live_cutoff_hz=live_cutoff_hz)
        runs.append((t_h, np.clip(q_true, robot.lower, robot.upper), np.clip(q_meas, robot.lower, robot.upper)))
    if not runs:
        raise InvalidInput("fit_predictor needs at least one recording")
    return ARPredictor.fit(runs, latency=latency, **kw)  # type: ignore[arg-type]


def training_predictor(exclude: str = "", *, latency: float = 0.1, robot: Robot | None = None,
                       elbow: str = "flexion") -> tuple[ARPredictor, str]:
    """An :class:`ARPredictor` for a live run, fitted on recordings other than the one it runs on.

    Args:
        exclude: file name of the recording to leave out (such as ``Ges01_wavehand.csv``).
        latency: sensor latency [s].
        robot: default ``Robot.load("scara2")``.
        elbow: "flexion" or "planar".

    Returns:
        (predictor, what it was fitted on): the reference Kinect recordings except ``exclude``,
        or, without the reference data, three synthetic arm waves (seeds 1-3).
    """
    try:
        files = sorted(p for p in data_path("kinect").glob("*.csv") if p.name != Path(exclude).name)
    except DataMissing:
        files = []
    if files:
        skels, what = [read_kinect_csv(f) for f in files], f"{len(files)} other Kinect recordings"
    else:
        skels, what = [synthetic_wave(6.0, seed=s, dropout_at=None) for s in (1, 2, 3)], "3 synthetic arm waves"
    return fit_predictor(skels, latency=latency, robot=robot, elbow=elbow), what

