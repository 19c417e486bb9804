"""The insertion skill model: GMR from the felt wrench to the corrective tool twist, (5.14)-(5.17)."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput
from robointel.geometry.rotations import so3_log
from robointel.learning.demonstration import Demonstration
from robointel.learning.gmr import GaussianMixtureRegression, held_out_r2
from robointel.learning.insertion.demonstrator import PHASES

PERCEPTION = (0, 1, 2, 3, 4)  # fx fy fz tx ty (tool frame)
POLICY = ("vx", "vy", "vz", "wx", "wy")  # tool-frame linear (m/s) and angular (rad/s) velocity


def tool_velocities(demo: Demonstration, *, smooth: int = 5, centre: float = 0.0) -> npt.NDArray[np.float64]:
    """Tool-frame twist of a demonstration by central differences of its recorded poses.

    Args:
        demo: The demonstration (N samples).
        smooth: Length of the moving average applied to the twist (samples).
        centre: Distance (m) along the tool z axis of the point whose velocity is v (0: the tool origin).

    Returns:
        (N, 6) twist [v (m/s); w (rad/s)] in the tool frame.
    """
    t, T = demo.t, demo.pose
    n = len(t)
    p = T[:, :3, 3]
    v = np.gradient(p, t, axis=0)
    w = np.zeros((n, 3))
    for k in range(n):
        a, b = max(k - 1, 0), min(k + 1, n - 1)
        w[k] = so3_log(T[b, :3, :3] @ T[a, :3, :3].T) / (t[b] - t[a])
    tw = np.concatenate([np.einsum("nji,nj->ni", T[:, :3, :3], v), np.einsum("nji,nj->ni", T[:, :3, :3], w)], 1)
    tw[:, :3] += np.cross(tw[:, 3:], np.array([0.0, 0.0, centre]))
    if smooth > 1:
        box = np.ones(smooth) / smooth
        pad = smooth // 2
        tp = np.pad(tw, ((pad, smooth - 1 - pad), (0, 0)), mode="edge")
        tw = np.stack([np.convolve(tp[:, i], box, mode="valid") for i in range(6)], 1)
    return tw


class InsertionSkill:
    """The insertion skill model (5.14)-(5.17): GMR from the felt wrench to the corrective tool twist.

    Inputs [fx, fy, fz, tx, ty] and outputs [vx, vy, vz, wx, wy] are in the tool frame; both are
    standardised before the mixture is fitted (k-means needs comparable scales). The output rotation
    [wx, wy] is about the compliance centre.

    An output is used only where the demonstrations show that it depends on the wrench: its GMR
    prediction on held-out demonstrations explains at least ``min_r2`` of its variance (leave-demonstrations-
    out cross-validation, ``r2_``). Otherwise the wrench does not tell the demonstrated value: the axial
    speed is the demonstrated mean push and a lateral or rotational correction is zero (a correction the
    wrench does not determine is none). A reproducing robot integrates the twist into its impedance
    equilibrium: the mixture's incidental structure, or a few demonstrations' mean turn, would wind the
    stiff rotational spring against the wall at a rate no demonstration links to the felt wrench.
    """

    def __init__(self, n_components: int = 6, *, random_state: int = 0, max_samples: int = 12000,
                 centre: float = 0.0, min_r2: float = 0.1, cv_folds: int = 3) -> None:
        """Set up an unfitted skill.

        Args:
            n_components: Gaussian components of the mixture.
            random_state: Seed of the EM initialisation.
            max_samples: Samples kept for EM (a seeded subsample above that).
            centre: Distance (m) along the tool axis from the F/T sensor to the compliance centre the
                twist's velocity refers to (the robot's impedance centre).
            min_r2: Held-out coefficient of determination an output needs to follow the wrench.
            cv_folds: Folds (over demonstrations) of the support check; fewer demonstrations: one fold each.
        """
        self.centre = float(centre)
        self.min_r2 = float(min_r2)
        self.cv_folds = int(cv_folds)
        self.gmr = GaussianMixtureRegression(n_components, random_state=random_state)
        self.max_samples = int(max_samples)

    def fit(self, demos: Sequence[Demonstration], labels: Sequence[np.ndarray] | None = None,
            *, phase: int = PHASES.index("insertion")) -> InsertionSkill:
        """Fit on the samples of ``phase`` (labels from the decomposition, or each demo's own labels).

        Args:
            demos: The demonstrations.
            labels: Per demonstration (N_i,) action labels; None: each demonstration's own.
            phase: The action whose samples are learned.

        Returns:
            This skill, fitted.

        Raises:
            InvalidInput: no demonstrations or no samples of the phase.
        """
        if len(demos) == 0:
            raise InvalidInput("InsertionSkill.fit needs at least one demonstration")
        xs, ys, gs = [], [], []
        for i, d in enumerate(demos):
            lab = d.labels if labels is None else np.asarray(labels[i])
            if lab is None:
                raise InvalidInput(f"demonstration {i} has no labels; decompose it first")
            m = lab == phase
            tw = tool_velocities(d, centre=self.centre)
            xs.append(d.wrench[m][:, list(PERCEPTION)])
            ys.append(tw[m][:, [0, 1, 2, 3, 4]])
            gs.append(np.full(int(m.sum()), i))
        X, Y, G = np.concatenate(xs), np.concatenate(ys), np.concatenate(gs)
        if len(X) == 0:
            raise InvalidInput(f"no samples labelled {PHASES[phase]!r} in the demonstrations")
        if len(X) > self.max_samples:  # EM cost grows with the samples; a seeded subsample suffices
            keep = np.sort(np.random.default_rng(0).choice(len(X), self.max_samples, replace=False))
            X, Y, G = X[keep], Y[keep], G[keep]
        self.x_lo_, self.x_hi_ = np.percentile(X, 0.5, axis=0), np.percentile(X, 99.5, axis=0)
        self.y_lo_, self.y_hi_ = np.percentile(Y, 0.5, axis=0), np.percentile(Y, 99.5, axis=0)
        self.x_mean_, self.x_scale_ = X.mean(0), X.std(0) + 1e-9
        self.y_mean_, self.y_scale_ = Y.mean(0), Y.std(0) + 1e-12
        self.gmr.fit((X - self.x_mean_) / self.x_scale_, (Y - self.y_mean_) / self.y_scale_)
        self.X_, self.Y_ = X, Y
        # an output that never varied gets 0 (nothing to follow); one demonstration: inf (no check)
        self.r2_ = held_out_r2(X, Y, G, n_components=self.gmr.n_components, folds=self.cv_folds)
        self.y_supported_ = self.r2_ >= self.min_r2
        return self

    def predict(self, wrench: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Corrective tool twist for felt wrenches, saturated to the demonstrated ranges (no extrapolation).

        Outputs the wrench does not predict (``y_supported_`` False): the mean axial speed, no correction.

        Args:
            wrench: (n, 6) or (6,) wrenches [N; N m] in the tool frame.

        Returns:
            (n, 5) or (5,) twists [vx, vy, vz (m/s), wx, wy (rad/s)].
        """
        w = np.asarray(wrench, float)
        one = w.ndim == 1
        w = np.clip(np.atleast_2d(w)[:, list(PERCEPTION)], self.x_lo_, self.x_hi_)
        y = self.gmr.predict((w - self.x_mean_) / self.x_scale_) * self.y_scale_ + self.y_mean_
        y = np.clip(y, self.y_lo_, self.y_hi_)
        supported = getattr(self, "y_supported_", None)
        if supported is not None:
            fallback = np.where(np.arange(len(POLICY)) == POLICY.index("vz"), self.y_mean_, 0.0)
            y = np.where(np.asarray(supported, bool), y, fallback)
        return y[0] if one else y


    def policy(self) -> Callable[[npt.NDArray[np.float64]], npt.NDArray[np.float64]]:
        """A policy for one trial (wrench (6,) -> twist (5,)): :meth:`predict` on one wrench."""
        return self.predict  # type: ignore[return-value]
