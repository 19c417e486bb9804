"""Coherent Point Drift (6.3)-(6.13): rigid, affine and non-rigid point-set registration.

Conventions follow ``pycpd``: ``X`` is the target (N, D), ``Y`` the template (M, D) that moves onto
``X``. The Gaussian-mixture E-step (6.5)-(6.7) is shared; the M-step differs per warp:

* rigid (6.8)-(6.10): ``T(y) = s R y + t`` (scale optional),
* affine: ``T(y) = B y + t``,
* non-rigid (6.11)-(6.13): ``T(y) = y + sum_m G(y, y_m) w_m`` with the Gaussian kernel
  ``G(a, b) = exp(-|a - b|^2 / (2 beta^2))`` and the motion-coherence weight ``lambda``.

Variants of the non-rigid solver (``method``):

* ``"exact"``: dense kernel G, dense E-step in float64, ``np.linalg.solve`` for W; with
  ``normalize=False`` this is the same computation as ``pycpd.DeformableRegistration`` (the results
  agree to ~1e-12 on the fish and bunny pairs). O(M N) memory, O(M^3) per iteration.
* ``"lowrank"``: G replaced by a Nystrom eigen-decomposition ``U diag(lam) U^T`` (landmarks chosen by
  farthest-point sampling; the number of landmarks grows until the kernel spectrum has decayed below
  ``rank_tol`` of its largest eigenvalue), W from the Woodbury identity in O(M K^2); the E-step is a
  fused float32 numba kernel (vectorised polynomial exp, relative error < 2e-7; float32 sums give
  ~1e-5 relative error in P1 and PX); the warp is stored on the landmarks, so applying it to any
  point costs O(K). The registered template differs from the exact one by ~1e-5 of the cloud size
  (5e-6 on the 1k bunny pair).
* ``"fast"`` (default): ``"lowrank"``, and for clouds larger than ``max_points`` the registration runs on
  farthest-point subsamples of both clouds (at most ``max_points`` each) and the fitted warp, a smooth
  function of space, is then applied to every template point (the down-sample-and-interpolate idea of
  BCPD++). Accuracy trade-off: detail finer than the subsample spacing is not registered; the
  residual on the full clouds is reported by :func:`mean_nn_residual`.

Inputs are normalised (zero mean, unit RMS radius; Myronenko's ``cpd_normalize``) unless
``normalize=False``; the returned warp always acts in the caller's units.
"""
from __future__ import annotations

from contextlib import AbstractContextManager
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from robointel._validate import as_array
from robointel.errors import InvalidInput, ShapeError, SolverFailure
from robointel.learning.grasp.cpd_estep import (
    _estep_exact,
    _FastEstep,
    _sqdist,
    farthest_point_sample,
)
from robointel.learning.grasp.cpd_warps import (
    AffineWarp,
    CPDResult,
    NonrigidWarp,
    RigidWarp,
)

__all__ = [
    "RigidWarp", "AffineWarp", "NonrigidWarp", "CPDResult", "cpd_rigid", "cpd_affine", "cpd_nonrigid",
    "register", "mean_nn_residual", "farthest_point_sample", "single_thread_blas",
]


# ----------------------------------------------------------------------------------------------
# helpers


_BLAS_CONTROLLER = None


def single_thread_blas() -> AbstractContextManager[Any]:
    """Context manager limiting BLAS to one thread.

    Context manager limiting BLAS to one thread. The fast variants issue many small, thin GEMMs
    for which OpenBLAS' thread start-up and spinning cost 10-100x the arithmetic on a shared machine.

    The ``threadpoolctl`` controller is built once (the first call) and reused: building it scans
    the process's loaded libraries, ~3-7 ms a call, a third of a whole 1k-point registration.
    BLAS libraries loaded after the first call are not limited (numpy's and scipy's are loaded by then).
    """
    global _BLAS_CONTROLLER
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - threadpoolctl ships with scikit-learn
        import contextlib

        return contextlib.nullcontext()
    if _BLAS_CONTROLLER is None:
        import scipy.linalg  # noqa: F401  - load scipy's BLAS before the scan

        _BLAS_CONTROLLER = ThreadpoolController()
    return _BLAS_CONTROLLER.limit(limits=1, user_api="blas")


def _check_clouds(X: npt.ArrayLike, Y: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    X = as_array(X, "X (target)", (None, None))
    Y = as_array(Y, "Y (template)", (None, None))
    if X.shape[0] == 0 or Y.shape[0] == 0:
        raise InvalidInput(f"empty point cloud: target has {X.shape[0]} points, template {Y.shape[0]}; "
                           "register non-empty clouds", value=(X.shape, Y.shape))
    if X.shape[1] != Y.shape[1] or X.shape[1] < 1:
        raise ShapeError(f"target and template must have the same dimension D >= 1, got {X.shape[1]} "
                         f"and {Y.shape[1]}", value=(X.shape, Y.shape))
    return X, Y


def _check_params(w: float, tolerance: float, max_iterations: int, sigma2: float | None) -> None:
    if not (0.0 <= w < 1.0):
        raise InvalidInput(f"outlier weight w must be in [0, 1), got {w}", value=w)
    if not (tolerance >= 0.0):
        raise InvalidInput(f"tolerance must be >= 0, got {tolerance}", value=tolerance)
    if int(max_iterations) != max_iterations or max_iterations < 0:
        raise InvalidInput(f"max_iterations must be a non-negative integer, got {max_iterations}",
                           value=max_iterations)
    if sigma2 is not None and not (np.isfinite(sigma2) and sigma2 > 0):
        raise InvalidInput(f"initial sigma2 must be positive and finite, got {sigma2}", value=sigma2)


def _normalise(P: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray, float]:
    mu = P.mean(axis=0)
    scale = float(np.sqrt(np.sum((P - mu) ** 2) / P.shape[0]))
    if not scale > 1e-12 * max(1.0, float(np.abs(P).max())):
        raise InvalidInput(f"degenerate {name}: all {P.shape[0]} points coincide (zero spread); "
                           "registration needs a cloud with extent", value=P)
    return (P - mu) / scale, mu, scale


def _init_sigma2(X: np.ndarray, Y: np.ndarray) -> float:
    """Pycpd's sigma2 = sum |x_n - y_m|^2 / (D M N), in closed form."""
    N, D = X.shape
    M = Y.shape[0]
    sx, sy = X.sum(0), Y.sum(0)
    tot = M * np.sum(X * X) + N * np.sum(Y * Y) - 2.0 * sx @ sy
    return float(tot / (D * M * N))


def _nystrom(Y: np.ndarray, beta: float, rank_tol: float, max_rank: int | None,
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Low-rank G ~ U diag(lam) U^T from Nystrom landmarks (grown until the spectrum decays).

    Returns U (M, K), lam (K,), landmarks Z (L, D), and the map ``Lmap`` (L, M) with
    ``G(x, Y) ~ G(x, Z) Lmap`` (so that the warp can live on the landmarks).
    """
    M = Y.shape[0]
    cap = M if max_rank is None else min(M, int(max_rank))
    L = min(cap, 64)
    while True:
        Z = Y[farthest_point_sample(Y, L)]
        Gzz = np.exp(-_sqdist(Z, Z) / (2 * beta ** 2))
        ev, V = np.linalg.eigh(Gzz)
        keep = ev > rank_tol * ev[-1]
        if ev[0] <= rank_tol * ev[-1] or L >= cap:
            break
        L = min(2 * L, cap)
    ev, V = ev[keep], V[:, keep]
    Cyz = np.exp(-_sqdist(Y, Z) / (2 * beta ** 2))  # (M, L)
    F = Cyz @ (V / np.sqrt(ev))  # G ~ F F^T
    lam, Vs = np.linalg.eigh(F.T @ F)
    good = lam > rank_tol * lam[-1]
    lam, Vs = lam[good], Vs[:, good]
    U = F @ (Vs / np.sqrt(lam))
    # G(x, Y) ~ G(x, Z) Gzz^+ G(Z, Y)
    Lmap = (V / ev) @ (V.T @ Cyz.T)  # (L, M)
    return U, lam, Z, Lmap


# ----------------------------------------------------------------------------------------------
# rigid and affine (pycpd's update rules, column-vector warps on output)


def _cpd_rigid(X: npt.ArrayLike, Y: npt.ArrayLike, *, w: float = 0.0, tolerance: float = 1e-3,
               max_iterations: int = 100,
              sigma2: float | None = None, scale: bool = True, normalize: bool = True,
              method: str = "exact") -> CPDResult:
    """Rigid CPD (6.8)-(6.10) in the calling thread (see :func:`cpd_rigid`)."""
    X, Y = _check_clouds(X, Y)
    _check_params(w, tolerance, max_iterations, sigma2)
    D = X.shape[1]
    if D not in (2, 3):
        raise ShapeError(f"rigid CPD needs 2-D or 3-D points, got D = {D}", value=D)
    if method not in ("exact", "fast"):
        raise InvalidInput(f"method must be 'exact' or 'fast', got {method!r}", value=method)
    if normalize:
        Xn, mx, sx = _normalise(X, "target")
        Yn, my, sy = _normalise(Y, "template")
        if not scale:
            sy = sx
            Yn = (Y - my) / sx
    else:
        Xn, Yn, mx, my, sx, sy = X, Y, np.zeros(D), np.zeros(D), 1.0, 1.0
    M = Yn.shape[0]
    s2 = _init_sigma2(Xn, Yn) if sigma2 is None else float(sigma2)
    R = np.eye(D)  # pycpd row convention: TY = s Y R + t
    t = np.zeros(D)
    s = 1.0
    TY = Yn.copy()
    q, diff, it, converged = np.inf, np.inf, 0, False
    P1 = np.zeros(M)
    if method == "fast":
        estep = _FastEstep(Xn, Yn.shape[0])
    while it < max_iterations and diff > tolerance:
        if method == "exact":
            P, Pt1, P1, Np = _estep_exact(Xn, TY, s2, w)
            PX = P @ Xn
        else:
            Pt1, P1, PX, Np = estep(TY, s2, w)
        if Np <= 1e-300:
            raise SolverFailure(f"CPD lost all correspondences at iteration {it} (sigma2 = {s2:.3g}); "
                                "start from a larger sigma2 or pre-align the clouds", value=s2)
        muX = PX.sum(0) / Np
        muY = P1 @ Yn / Np
        Xh = Xn - muX
        Yh = Yn - muY
        YPY = float(P1 @ np.sum(Yh * Yh, axis=1))
        A = (PX - P1[:, None] * muX).T @ Yh
        U, _, Vt = np.linalg.svd(A, full_matrices=True)
        C = np.ones(D)
        C[-1] = np.linalg.det(U @ Vt)
        R = (U @ np.diag(C) @ Vt).T
        s = float(np.trace(A.T @ R.T) / YPY) if scale else 1.0
        t = muX - s * R.T @ muY
        TY = s * Yn @ R + t
        trAR = float(np.trace(A @ R))
        xPx = float(Pt1 @ np.sum(Xh * Xh, axis=1))
        qprev = q
        q = (xPx - 2 * s * trAR + s * s * YPY) / (2 * s2) + D * Np / 2 * np.log(s2)
        diff = abs(q - qprev)
        s2 = (xPx - s * trAR) / (Np * D) if scale else (xPx - 2 * trAR + YPY) / (Np * D)
        it += 1
        if not s2 > 0:
            s2 = max(tolerance / 10, 1e-16)
            converged = True
            break
    converged = converged or diff <= tolerance
    Rc = R.T  # column convention
    s_out = s * sx / sy
    t_out = sx * t + mx - s_out * Rc @ my
    warp = RigidWarp(s_out, Rc, t_out)
    return CPDResult("rigid", warp, warp(Y), float(s2), it, bool(converged), P1, method)


def cpd_affine(X: npt.ArrayLike, Y: npt.ArrayLike, *, w: float = 0.0, tolerance: float = 1e-3,
               max_iterations: int = 100,
               sigma2: float | None = None, normalize: bool = True) -> CPDResult:
    """Affine CPD: find ``B, t`` so that ``B y + t`` matches the target (Myronenko Fig. 3).

    Arguments as :func:`cpd_rigid`. Returns a CPDResult with an :class:`AffineWarp`.
    """
    X, Y = _check_clouds(X, Y)
    _check_params(w, tolerance, max_iterations, sigma2)
    D = X.shape[1]
    if normalize:
        Xn, mx, sx = _normalise(X, "target")
        Yn, my, sy = _normalise(Y, "template")
    else:
        Xn, Yn, mx, my, sx, sy = X, Y, np.zeros(D), np.zeros(D), 1.0, 1.0
    M = Yn.shape[0]
    s2 = _init_sigma2(Xn, Yn) if sigma2 is None else float(sigma2)
    B = np.eye(D)
    t = np.zeros(D)
    TY = Yn.copy()
    q, diff, it, converged = np.inf, np.inf, 0, False
    P1 = np.zeros(M)
    while it < max_iterations and diff > tolerance:
        P, Pt1, P1, Np = _estep_exact(Xn, TY, s2, w)
        if Np <= 1e-300:
            raise SolverFailure(f"CPD lost all correspondences at iteration {it} (sigma2 = {s2:.3g}); "
                                "start from a larger sigma2 or pre-align the clouds", value=s2)
        muX = (P @ Xn).sum(0) / Np
        muY = P1 @ Yn / Np
        Xh = Xn - muX
        Yh = Yn - muY
        A = Xh.T @ P.T @ Yh
        YPY = (Yh.T * P1) @ Yh
        try:
            B = np.linalg.solve(YPY.T, A.T)
        except np.linalg.LinAlgError:
            raise InvalidInput("degenerate template for affine CPD: its points do not span "
                               f"{D} dimensions (singular moment matrix)", value=YPY) from None
        t = muX - B.T @ muY
        TY = Yn @ B + t
        trAB = float(np.trace(A @ B))
        xPx = float(Pt1 @ np.sum(Xh * Xh, axis=1))
        trBYPYB = float(np.trace(B @ YPY @ B))
        qprev = q
        q = (xPx - 2 * trAB + trBYPYB) / (2 * s2) + D * Np / 2 * np.log(s2)
        diff = abs(q - qprev)
        s2 = (xPx - trAB) / (Np * D)
        it += 1
        if not s2 > 0:
            s2 = max(tolerance / 10, 1e-16)
            converged = True
            break
    converged = converged or diff <= tolerance
    Bc = B.T * (sx / sy)
    t_out = sx * t + mx - Bc @ my
    warp = AffineWarp(Bc, t_out)
    return CPDResult("affine", warp, warp(Y), float(s2), it, bool(converged), P1, "exact")


# ----------------------------------------------------------------------------------------------
# non-rigid


def _cpd_nonrigid(X: npt.ArrayLike, Y: npt.ArrayLike, *, beta: float = 2.0, lmbda: float = 2.0, w: float = 0.0,
                  tolerance: float = 1e-3,
                 max_iterations: int = 100, sigma2: float | None = None, normalize: bool = True,
                 method: str = "fast", rank_tol: float = 1e-8, max_rank: int | None = None,
                 max_points: int = 2500) -> CPDResult:
    """Non-rigid CPD (6.11)-(6.13) in the calling thread (see :func:`cpd_nonrigid`)."""
    X, Y = _check_clouds(X, Y)
    _check_params(w, tolerance, max_iterations, sigma2)
    if not (beta > 0 and np.isfinite(beta)):
        raise InvalidInput(f"beta must be positive, got {beta}", value=beta)
    if not (lmbda > 0 and np.isfinite(lmbda)):
        raise InvalidInput(f"lambda must be positive, got {lmbda}", value=lmbda)
    if method not in ("exact", "lowrank", "fast"):
        raise InvalidInput(f"method must be 'exact', 'lowrank' or 'fast', got {method!r}", value=method)
    D = X.shape[1]
    if normalize:
        Xn, mx, sx = _normalise(X, "target")
        Yn, my, sy = _normalise(Y, "template")
    else:
        Xn, Yn, mx, my, sx, sy = X, Y, np.zeros(D), np.zeros(D), 1.0, 1.0
    Yfull = None
    if method == "fast":
        if Xn.shape[0] > max_points:
            Xn = Xn[farthest_point_sample(Xn, max_points)]
        if Yn.shape[0] > max_points:
            Yfull = Y
            Yn = Yn[farthest_point_sample(Yn, max_points)]
    M = Yn.shape[0]
    s2 = _init_sigma2(Xn, Yn) if sigma2 is None else float(sigma2)
    W = np.zeros((M, D))
    TY = Yn.copy()
    diff, it, converged = np.inf, 0, False
    P1 = np.zeros(M)
    exact = method == "exact"
    if exact:
        G = np.exp(-_sqdist(Yn, Yn) / (2 * beta ** 2))
    else:
        U, lam, Z, Lmap = _nystrom(Yn, beta, rank_tol, max_rank)
        estep = _FastEstep(Xn, M)
    xx = np.sum(Xn * Xn, axis=1)
    while it < max_iterations and diff > tolerance:
        if exact:
            P, Pt1, P1, Np = _estep_exact(Xn, TY, s2, w)
            PX = P @ Xn
        else:
            Pt1, P1, PX, Np = estep(TY, s2, w)
        if Np <= 1e-300:
            raise SolverFailure(f"CPD lost all correspondences at iteration {it} (sigma2 = {s2:.3g}); "
                                "start from a larger sigma2 or pre-align the clouds", value=s2)
        F = PX - P1[:, None] * Yn
        sreg = lmbda * s2
        if exact:
            W = np.linalg.solve(P1[:, None] * G + sreg * np.eye(M), F)
            TY = Yn + G @ W
        else:
            dU = P1[:, None] * U
            S = sreg * np.diag(1.0 / lam) + U.T @ dU
            W = (F - dU @ np.linalg.solve(S, U.T @ F)) / sreg
            TY = Yn + U @ (lam[:, None] * (U.T @ W))
        s2_prev = s2
        xPx = float(Pt1 @ xx)
        yPy = float(P1 @ np.sum(TY * TY, axis=1))
        trPXY = float(np.sum(TY * PX))
        s2 = (xPx - 2 * trPXY + yPy) / (Np * D)
        it += 1
        if not s2 > 0:
            s2 = max(tolerance / 10, 1e-16)
            converged = True
            break
        diff = abs(s2 - s2_prev)
    converged = converged or diff <= tolerance
    if exact:
        centres, coef, rank = Yn, W, None
    else:
        centres, coef, rank = Z, Lmap @ W, int(lam.size)
    warp = NonrigidWarp(centres, coef, float(beta), my, sy, mx, sx)
    TYout = warp(Yfull) if Yfull is not None else TY * sx + mx
    return CPDResult("nonrigid", warp, TYout, float(s2), it, bool(converged), P1, method, rank)


def cpd_rigid(X: npt.ArrayLike, Y: npt.ArrayLike, *, w: float = 0.0, tolerance: float = 1e-3,
              max_iterations: int = 100, sigma2: float | None = None, scale: bool = True, normalize: bool = True,
              method: str = "exact") -> CPDResult:
    """Rigid CPD (6.8)-(6.10): find ``s, R, t`` so that ``s R y + t`` matches the target.

    Args:
        X: (N, D) target points, D in {2, 3}.
        Y: (M, D) template points.
        w: Outlier weight in [0, 1).
        tolerance: Stop when |Q - Q_prev| < tolerance (pycpd's rule).
        max_iterations: EM iteration cap.
        sigma2: Initial variance (default: pycpd's).
        scale: Estimate the scale ``s`` (else s = 1).
        normalize: Register normalised copies.
        method: "exact" (float64 dense E-step, = pycpd) or "fast" (float32 blocked E-step, one BLAS thread).

    Returns:
        CPDResult with a :class:`RigidWarp` (det R = +1).

    Raises:
        InvalidInput: empty or degenerate clouds, bad parameters.
        ShapeError: D not 2 or 3, or the clouds' dimensions differ.
        SolverFailure: all correspondences lost.
    """
    kw = {"w": w, "tolerance": tolerance, "max_iterations": max_iterations, "sigma2": sigma2, "scale": scale,
          "normalize": normalize, "method": method}
    if method == "exact":
        return _cpd_rigid(X, Y, **kw)  # type: ignore[arg-type]
    with single_thread_blas():
        return _cpd_rigid(X, Y, **kw)  # type: ignore[arg-type]


def cpd_nonrigid(X: npt.ArrayLike, Y: npt.ArrayLike, *, beta: float = 2.0, lmbda: float = 2.0, w: float = 0.0,
                 tolerance: float = 1e-3, max_iterations: int = 100, sigma2: float | None = None,
                 normalize: bool = True, method: str = "fast", rank_tol: float = 1e-8, max_rank: int | None = None,
                 max_points: int = 2500) -> CPDResult:
    """Non-rigid CPD (6.11)-(6.13): ``T(y) = y + G(y, Y) W`` with motion coherence.

    Args:
        X: (N, D) target.
        Y: (M, D) template.
        beta: Kernel width (normalised units when ``normalize``).
        lmbda: Regularisation lambda (pycpd's ``alpha``).
        w: Outlier weight in [0, 1).
        tolerance: Stop when |sigma2 - sigma2_prev| < tolerance (pycpd's rule).
        max_iterations: EM iteration cap.
        sigma2: Initial variance (default pycpd's mean squared distance / D).
        normalize: Register normalised copies (robust to units and offsets).
        method: "exact" (dense, pycpd-equivalent), "lowrank" or "fast" (see module docstring; both on
            one BLAS thread).
        rank_tol: Relative eigenvalue cut-off of the low-rank kernel.
        max_rank: Cap on the landmarks.
        max_points: "fast" registers subsamples of at most this many points per cloud.

    Returns:
        CPDResult with a :class:`NonrigidWarp` (apply it and its Jacobian to any point).

    Raises:
        InvalidInput: empty or degenerate clouds, bad parameters.
        SolverFailure: all correspondences lost (sigma2 too small to start).
    """
    kw = {"beta": beta, "lmbda": lmbda, "w": w, "tolerance": tolerance, "max_iterations": max_iterations,
          "sigma2": sigma2, "normalize": normalize, "method": method, "rank_tol": rank_tol, "max_rank": max_rank,
          "max_points": max_points}
    if method == "exact":
        return _cpd_nonrigid(X, Y, **kw)  # type: ignore[arg-type]
    with single_thread_blas():
        return _cpd_nonrigid(X, Y, **kw)  # type: ignore[arg-type]


def register(X: npt.ArrayLike, Y: npt.ArrayLike, kind: str = "nonrigid", **kwargs: Any) -> CPDResult:
    """Dispatch to :func:`cpd_rigid`, :func:`cpd_affine` or :func:`cpd_nonrigid` by ``kind``.

    Args:
        X: (N, D) target.
        Y: (M, D) template.
        kind: "rigid", "affine" or "nonrigid".
        **kwargs: The chosen function's keyword arguments.

    Returns:
        The registration.

    Raises:
        InvalidInput: an unknown ``kind`` (or the chosen function's errors).
    """
    fn = {"rigid": cpd_rigid, "affine": cpd_affine, "nonrigid": cpd_nonrigid}.get(kind)
    if fn is None:
        raise InvalidInput(f"kind must be 'rigid', 'affine' or 'nonrigid', got {kind!r}", value=kind)
    return fn(X, Y, **kwargs)


def mean_nn_residual(A: npt.ArrayLike, B: npt.ArrayLike) -> float:
    """Symmetric mean nearest-neighbour distance (6.17)-(6.19) between clouds A (n, D) and B (m, D)."""
    A = as_array(A, "A", (None, None))
    B = as_array(B, "B", (None, None))
    if len(A) == 0 or len(B) == 0:
        raise InvalidInput("residual of an empty cloud is undefined", value=(A.shape, B.shape))
    da, _ = cKDTree(B).query(A)
    db, _ = cKDTree(A).query(B)
    return 0.5 * (float(da.mean()) + float(db.mean()))
