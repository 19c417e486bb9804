"""Skill model (5.14)-(5.17).

A Gaussian mixture over [perception, policy] fitted by EM with k-means initialisation (scikit-learn's
``GaussianMixture``), and our Gaussian mixture regression.

The joint density of perception ``x`` and policy ``y`` is modelled as (5.14)

    p(x, y) = sum_k pi_k N([x; y]; mu_k, Sigma_k),

fitted by EM (5.15). GMR conditions it on ``x`` (5.16)-(5.17):

    h_k(x)     = pi_k N(x; mu_k^x, Sigma_k^xx) / sum_l pi_l N(x; mu_l^x, Sigma_l^xx)
    mu_k(x)    = mu_k^y + Sigma_k^yx (Sigma_k^xx)^-1 (x - mu_k^x)
    Sigma_k^y|x = Sigma_k^yy - Sigma_k^yx (Sigma_k^xx)^-1 Sigma_k^xy
    E[y | x]   = sum_k h_k(x) mu_k(x)
    Cov[y | x] = sum_k h_k(x) (Sigma_k^y|x + mu_k(x) mu_k(x)^T) - E[y|x] E[y|x]^T

Which dimensions are perception and policy is the user's choice (wrench -> corrective velocity for
insertion; pose -> force for grinding).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from scipy.special import logsumexp
from sklearn.mixture import GaussianMixture

from robointel._validate import as_array
from robointel.errors import InvalidInput, ShapeError


def regularize_covariances(covariances: np.ndarray, *, min_eig: float = 1e-9) -> np.ndarray:
    """Make each (d, d) covariance symmetric positive definite.

    Eigenvalues below ``min_eig`` times the largest (and at least ``min_eig``) are raised to it. A singular
    covariance is regularised, not an error. Returns (K, d, d).
    """
    cov = np.array(covariances, dtype=float)
    cov = 0.5 * (cov + np.swapaxes(cov, -1, -2))
    w, v = np.linalg.eigh(cov)
    floor = np.maximum(min_eig * np.maximum(w.max(axis=-1, keepdims=True), 0.0), min_eig)
    if np.all(w >= floor):
        return cov
    w = np.maximum(w, floor)
    return np.einsum("kij,kj,klj->kil", v, w, v)


@dataclass
class _Conditional:
    ix: np.ndarray
    iy: np.ndarray
    chol: list
    log_norm: np.ndarray  # log pi_k - 0.5 log det(2 pi Sigma_xx)
    coef: np.ndarray      # (K, dy, dx) Sigma_yx Sigma_xx^-1
    cond_cov: np.ndarray  # (K, dy, dy)


class GaussianMixtureRegression:
    """GMM + GMR skill model with a scikit-learn-style API.

    Args:
        n_components: number of Gaussians K.
        reg_covar: diagonal added to covariances during EM (scikit-learn's ``reg_covar``).
        max_iter: passed to ``sklearn.mixture.GaussianMixture`` (k-means init).
        n_init: passed to ``sklearn.mixture.GaussianMixture``.
        random_state: passed to ``sklearn.mixture.GaussianMixture``.

    After :meth:`fit`: ``priors_`` (K,), ``means_`` (K, D), ``covariances_`` (K, D, D) with
    D = dx + dy, and ``n_inputs_``.
    """

    def __init__(self, n_components: int = 5, *, reg_covar: float = 1e-6, max_iter: int = 200,
                 n_init: int = 1, random_state: int | None = 0) -> None:
        if int(n_components) < 1:
            raise InvalidInput(f"n_components must be >= 1, got {n_components}", value=n_components)
        self.n_components = int(n_components)
        self.reg_covar = float(reg_covar)
        self.max_iter = int(max_iter)
        self.n_init = int(n_init)
        self.random_state = random_state

    @classmethod
    def from_mixture(cls, priors: ArrayLike, means: ArrayLike, covariances: ArrayLike,
                     n_inputs: int) -> GaussianMixtureRegression:
        """A model from a given mixture; the first ``n_inputs`` dimensions are the perception ``x``."""
        priors = as_array(priors, "priors", (None,))
        k = priors.shape[0]
        means = as_array(means, "means", (k, None))
        covariances = as_array(covariances, "covariances", (k, means.shape[1], means.shape[1]))
        if not 0 < n_inputs < means.shape[1]:
            raise InvalidInput(f"n_inputs must be in 1..{means.shape[1] - 1}, got {n_inputs}", value=n_inputs)
        if np.any(priors < 0) or abs(priors.sum() - 1.0) > 1e-6:
            raise InvalidInput("priors must be non-negative and sum to 1", value=priors)
        self = cls(k)
        self._set(priors, means, covariances, int(n_inputs))
        return self

    def _set(self, priors: np.ndarray, means: np.ndarray, covariances: np.ndarray, n_inputs: int) -> None:
        self.priors_ = np.asarray(priors, float)
        self.means_ = np.asarray(means, float)
        self.covariances_ = regularize_covariances(covariances)
        self.n_inputs_ = n_inputs
        d = means.shape[1]
        ix, iy = np.arange(n_inputs), np.arange(n_inputs, d)
        chol, log_norm, coef, cond = [], [], [], []
        for k in range(len(priors)):
            s = self.covariances_[k]
            sxx, syx, syy = s[np.ix_(ix, ix)], s[np.ix_(iy, ix)], s[np.ix_(iy, iy)]
            c = cho_factor(sxx, lower=True)
            chol.append(c[0])
            log_norm.append(np.log(max(priors[k], 1e-300)) - 0.5 * n_inputs * np.log(2 * np.pi)
                            - np.sum(np.log(np.diag(c[0]))))
            a = cho_solve(c, syx.T).T  # Sigma_yx Sigma_xx^-1
            coef.append(a)
            cond.append(syy - a @ syx.T)
        self._c = _Conditional(ix, iy, chol, np.array(log_norm), np.array(coef),
                               regularize_covariances(np.array(cond)))

    def fit(self, X: ArrayLike, Y: ArrayLike) -> GaussianMixtureRegression:
        """Fit the joint GMM (5.14)-(5.15) by EM with k-means initialisation.

        Fit the joint GMM (5.14)-(5.15) on perception ``X`` (n, dx) and policy ``Y`` (n, dy) by EM with k-means
        initialisation.

        Raises:
            ShapeError: X and Y of different lengths. NotFinite: NaN samples.
            InvalidInput: fewer samples than ``n_components`` (or than the joint dimension + 1 per component).
        """
        X = as_array(X, "X")
        Y = as_array(Y, "Y")
        X = X[:, None] if X.ndim == 1 else X
        Y = Y[:, None] if Y.ndim == 1 else Y
        if X.ndim != 2 or Y.ndim != 2 or X.shape[0] != Y.shape[0]:
            raise ShapeError(f"X (n, dx) and Y (n, dy) must have the same number of rows, got {X.shape}, {Y.shape}")
        n = X.shape[0]
        if n < self.n_components * 2:
            raise InvalidInput(f"{n} samples are too few for {self.n_components} components; give at least "
                               f"{2 * self.n_components} samples or fewer components", value=n)
        Z = np.concatenate([X, Y], axis=1)
        gm = GaussianMixture(self.n_components, covariance_type="full", init_params="kmeans",
                             reg_covar=self.reg_covar, max_iter=self.max_iter, n_init=self.n_init,
                             random_state=self.random_state).fit(Z)
        self.gmm_ = gm
        self._set(gm.weights_, gm.means_, gm.covariances_, X.shape[1])
        return self

    def _check(self, X: ArrayLike) -> NDArray[np.float64]:
        if not hasattr(self, "_c"):
            raise InvalidInput("the model is not fitted; call fit(X, Y) first")
        X = as_array(X, "X")
        X = X[:, None] if X.ndim == 1 and self.n_inputs_ == 1 else np.atleast_2d(X)
        if X.ndim != 2 or X.shape[1] != self.n_inputs_:
            raise ShapeError(f"X must be (n, {self.n_inputs_}), got {X.shape}", value=X.shape)
        return X

    def responsibilities(self, X: ArrayLike) -> np.ndarray:
        """h_k(x) of (5.16): (n, K)."""
        X = self._check(X)
        c = self._c
        logp = np.empty((X.shape[0], len(self.priors_)))
        for k in range(len(self.priors_)):
            z = solve_triangular(c.chol[k], (X - self.means_[k, c.ix]).T, lower=True)
            logp[:, k] = c.log_norm[k] - 0.5 * np.sum(z * z, axis=0)
        return np.exp(logp - logsumexp(logp, axis=1, keepdims=True))

    def predict(self, X: ArrayLike, *, return_cov: bool = False) -> Any:
        """Conditional mean (5.17) E[y|x] (n, dy), and with ``return_cov`` the covariance (n, dy, dy)."""
        X = self._check(X)
        c = self._c
        h = self.responsibilities(X)
        mu = self.means_[:, c.iy][None] + np.einsum("kyx,nkx->nky", c.coef, X[:, None, :] - self.means_[None, :, c.ix])
        mean = np.einsum("nk,nky->ny", h, mu)
        if not return_cov:
            return mean
        cov = np.einsum("nk,kab->nab", h, c.cond_cov) + np.einsum("nk,nka,nkb->nab", h, mu, mu)
        cov -= np.einsum("na,nb->nab", mean, mean)
        return mean, 0.5 * (cov + np.swapaxes(cov, 1, 2))


def held_out_r2(X: ArrayLike, Y: ArrayLike, groups: ArrayLike, *, n_components: int, folds: int = 3,
                random_state: int | None = 0, x_eps: float = 1e-9, sst_about: str = "train",
                single_group: float = np.inf, constant_output: float | None = 0.0) -> NDArray[np.float64]:
    """Per-output coefficient of determination of a GMR on held-out groups (e.g. demonstrations).

    The groups are shuffled (generator seeded 0) and split into ``folds``; each fold is predicted by a
    :class:`GaussianMixtureRegression` fitted on the others (inputs and outputs standardised with the
    training folds' mean and std, held-out inputs clipped to the training range, no extrapolation).
    R^2 = 1 - sum (y - y_hat)^2 / sum (y - y_bar)^2 over all held-out samples, per output.

    Args:
        X: (n, dx) inputs.
        Y: (n, dy) outputs.
        groups: (n,) group id of each sample (all samples of a group are held out together).
        n_components: Components of each fold's mixture.
        folds: Number of folds (at most the number of groups).
        random_state: Seed of each fold's EM initialisation.
        x_eps: Added to the inputs' std when standardising.
        sst_about: ``"train"``: y_bar is the training folds' mean (what a constant predictor from the
            training data would say); ``"test"``: the held-out fold's own mean.
        single_group: Returned for every output when there is only one group (no held-out check).
        constant_output: Returned for an output whose total sum of squares is ~0 (it never varied); None
            keeps the ratio.

    Returns:
        (dy,) held-out R^2.

    Raises:
        InvalidInput: ``sst_about`` not ``"train"`` or ``"test"``, or folds < 2.
    """
    if sst_about not in ("train", "test"):
        raise InvalidInput(f"sst_about must be 'train' or 'test', got {sst_about!r}", value=sst_about)
    if int(folds) < 2:
        raise InvalidInput(f"held_out_r2 needs folds >= 2, got {folds}", value=folds)
    X, Y, G = np.asarray(X, float), np.asarray(Y, float), np.asarray(groups)
    ids = np.unique(G)
    if len(ids) < 2:
        return np.full(Y.shape[1], float(single_group))
    splits = np.array_split(np.random.default_rng(0).permutation(ids), min(int(folds), len(ids)))
    sse, sst = np.zeros(Y.shape[1]), np.zeros(Y.shape[1])
    for held in splits:
        te = np.isin(G, held)
        xm, xs = X[~te].mean(0), X[~te].std(0) + x_eps
        ym, ys = Y[~te].mean(0), Y[~te].std(0) + 1e-12
        gmr = GaussianMixtureRegression(n_components, random_state=random_state)
        gmr.fit((X[~te] - xm) / xs, (Y[~te] - ym) / ys)
        pred = gmr.predict((np.clip(X[te], X[~te].min(0), X[~te].max(0)) - xm) / xs) * ys + ym
        sse += ((Y[te] - pred) ** 2).sum(0)
        sst += ((Y[te] - (ym if sst_about == "train" else Y[te].mean(0))) ** 2).sum(0)
    r2 = 1.0 - sse / np.maximum(sst, 1e-300)
    if constant_output is not None:
        r2 = np.where(sst > 1e-12 * len(Y), r2, constant_output)
    return np.asarray(r2, float)
