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

from dataclasses import dataclass, field

import numba
import numpy as np
from scipy.spatial import cKDTree

from robointel._validate import as_array
from robointel.errors import InvalidInput, ShapeError, SolverFailure

__all__ = [
    "RigidWarp", "AffineWarp", "NonrigidWarp", "CPDResult", "cpd_rigid", "cpd_affine", "cpd_nonrigid",
    "register", "mean_nn_residual", "farthest_point_sample", "single_thread_blas",
]


# ----------------------------------------------------------------------------------------------
# warps: T(x) for any point, with its Jacobian


@dataclass(frozen=True)
class RigidWarp:
    """``T(x) = s R x + t`` (6.8). ``R`` (D, D) proper rotation, ``t`` (D,), ``s`` > 0."""

    s: float
    R: np.ndarray
    t: np.ndarray

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, float)
        return self.s * x @ self.R.T + self.t

    def jacobian(self, x) -> np.ndarray:
        """dT/dx at each point: (K, D, D) (constant ``s R``)."""
        x = np.atleast_2d(np.asarray(x, float))
        return np.broadcast_to(self.s * self.R, (x.shape[0],) + self.R.shape).copy()


@dataclass(frozen=True)
class AffineWarp:
    """``T(x) = B x + t``. ``B`` (D, D), ``t`` (D,)."""

    B: np.ndarray
    t: np.ndarray

    def __call__(self, x) -> np.ndarray:
        return np.asarray(x, float) @ self.B.T + self.t

    def jacobian(self, x) -> np.ndarray:
        """dT/dx at each point: (K, D, D) (constant ``B``)."""
        x = np.atleast_2d(np.asarray(x, float))
        return np.broadcast_to(self.B, (x.shape[0],) + self.B.shape).copy()


@dataclass(frozen=True)
class NonrigidWarp:
    """The non-rigid CPD warp (6.11) extended to any point of space.

    In normalised coordinates ``u = (x - in_shift) / in_scale``:
    ``v(u) = u + sum_k exp(-|u - c_k|^2 / (2 beta^2)) a_k`` and ``T(x) = out_scale v(u) + out_shift``.
    For the exact solver the centres ``c`` are the template points and ``a = W``; for the low-rank
    solver they are Nystrom landmarks with ``a = G_LL^-1 G_LY W``.
    """

    centres: np.ndarray  # (K, D)
    coef: np.ndarray  # (K, D)
    beta: float
    in_shift: np.ndarray
    in_scale: float
    out_shift: np.ndarray
    out_scale: float

    def _kernel(self, u: np.ndarray) -> np.ndarray:
        d2 = _sqdist(u, self.centres)
        return np.exp(-d2 / (2.0 * self.beta ** 2))

    def __call__(self, x) -> np.ndarray:
        """Warp points ``x`` (K, D) -> (K, D), in the caller's units."""
        x = np.asarray(x, float)
        one = x.ndim == 1
        x = np.atleast_2d(x)
        out = np.empty_like(x)
        for i in range(0, len(x), 4096):
            u = (x[i:i + 4096] - self.in_shift) / self.in_scale
            v = u + self._kernel(u) @ self.coef
            out[i:i + 4096] = v * self.out_scale + self.out_shift
        return out[0] if one else out

    def jacobian(self, x) -> np.ndarray:
        """dT/dx at each point: (K, D, D) = (out_scale/in_scale)(I - beta^-2 sum_k G_k a_k (u - c_k)^T)."""
        x = np.atleast_2d(np.asarray(x, float))
        u = (x - self.in_shift) / self.in_scale
        G = self._kernel(u)  # (K, L)
        D = x.shape[1]
        # sum_l G_kl a_l (u_k - c_l)^T = (G a)_k u_k^T - sum_l G_kl a_l c_l^T
        Ga = G @ self.coef  # (K, D)
        term = Ga[:, :, None] * u[:, None, :] - np.einsum("kl,ld,le->kde", G, self.coef, self.centres)
        J = np.eye(D)[None] - term / self.beta ** 2
        return J * (self.out_scale / self.in_scale)


@dataclass
class CPDResult:
    """A fitted registration.

    Attributes:
        kind: "rigid", "affine" or "nonrigid".
        warp: the fitted T; ``warp(points)`` and ``warp.jacobian(points)`` work for any points.
        TY: (M, D) the template after registration, caller's units.
        sigma2: final GMM variance (normalised units when ``normalize=True``).
        iterations: EM iterations run.
        converged: the tolerance was met (or sigma2 collapsed to 0: an exact fit).
        P1: (M,) posterior mass of each template point (useful to spot unmatched template points).
        method: the variant that ran.
    """

    kind: str
    warp: object
    TY: np.ndarray
    sigma2: float
    iterations: int
    converged: bool
    P1: np.ndarray = field(repr=False, default=None)
    method: str = "exact"
    rank: int | None = None


# ----------------------------------------------------------------------------------------------
# helpers


_BLAS_CONTROLLER = None


def single_thread_blas():
    """Context manager limiting BLAS to one thread. The fast variants issue many small, thin GEMMs
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


def _sqdist(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a_i - b_j|^2 (I, J) computed with per-dimension differences (no cancellation)."""
    d2 = np.zeros((a.shape[0], b.shape[0]), dtype=np.result_type(a, b))
    for k in range(a.shape[1]):
        diff = a[:, k, None] - b[None, :, k]
        d2 += diff * diff
    return d2


def _check_clouds(X, Y):
    X = as_array(X, "X (target)", (None, None))
    Y = as_array(Y, "Y (template)", (None, None))
    if X.shape[0] == 0 or Y.shape[0] == 0:
        raise InvalidInput(f"empty point cloud: target has {X.shape[0]} points, template {Y.shape[0]}; "
                           "register non-empty clouds", value=(X.shape, Y.shape))
    if X.shape[1] != Y.shape[1] or X.shape[1] < 1:
        raise ShapeError(f"target and template must have the same dimension D >= 1, got {X.shape[1]} "
                         f"and {Y.shape[1]}", value=(X.shape, Y.shape))
    return X, Y


def _check_params(w, tolerance, max_iterations, sigma2):
    if not (0.0 <= w < 1.0):
        raise InvalidInput(f"outlier weight w must be in [0, 1), got {w}", value=w)
    if not (tolerance >= 0.0):
        raise InvalidInput(f"tolerance must be >= 0, got {tolerance}", value=tolerance)
    if int(max_iterations) != max_iterations or max_iterations < 0:
        raise InvalidInput(f"max_iterations must be a non-negative integer, got {max_iterations}",
                           value=max_iterations)
    if sigma2 is not None and not (np.isfinite(sigma2) and sigma2 > 0):
        raise InvalidInput(f"initial sigma2 must be positive and finite, got {sigma2}", value=sigma2)


def _normalise(P: np.ndarray, name: str):
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


def _estep_exact(X, TY, sigma2, w):
    """(6.5)-(6.7) dense, float64, exactly as pycpd: returns P (M, N), Pt1, P1, Np."""
    M, D = TY.shape
    N = X.shape[0]
    P = np.exp(-_sqdist(TY, X) / (2.0 * sigma2))
    c = (2.0 * np.pi * sigma2) ** (D / 2.0) * w / (1.0 - w) * M / N
    den = P.sum(axis=0)
    den[den == 0] = np.finfo(float).eps
    den += c
    P /= den
    return P, P.sum(axis=0), P.sum(axis=1), float(P.sum())


def _estep_fast(X32, xx32, TY, sigma2, w):
    """The same E-step in float32 with one GEMM for the exponent and SIMD exp.

    Returns Pt1 (N,), P1 (M,), PX (M, D), Np without forming P twice.
    """
    M, D = TY.shape
    N = X32.shape[0]
    f = 1.0 / sigma2
    A = np.empty((M, D + 2), np.float32)
    A[:, :D] = TY * f
    A[:, D] = -0.5 * f * np.einsum("ij,ij->i", TY, TY)
    A[:, D + 1] = 1.0
    B = np.empty((N, D + 2), np.float32)
    B[:, :D] = X32
    B[:, D] = 1.0
    B[:, D + 1] = -0.5 * f * xx32
    c = (2.0 * np.pi * sigma2) ** (D / 2.0) * w / (1.0 - w) * M / N
    # blocks of targets so that the (M, block) kernel slab stays in cache
    blk = max(16, min(N, (1 << 17) // max(M, 1)))
    S = np.zeros((M, D + 1), np.float32)
    Pt1 = np.empty(N)
    R = np.empty((blk, D + 1), np.float32)
    for j in range(0, N, blk):
        Bj = B[j:j + blk]
        nb = Bj.shape[0]
        K = A @ Bj.T  # -|y - x|^2 / (2 sigma2)
        np.clip(K, -80.0, 0.0, out=K)  # exp(-80) ~ 2e-35 stays a normal float32 (denormals are slow)
        np.exp(K, out=K)
        ksum = K.sum(axis=0).astype(np.float64)
        den = np.maximum(ksum, np.finfo(np.float32).eps) + c
        inv = 1.0 / den
        Pt1[j:j + nb] = ksum * inv
        R[:nb, 0] = inv
        R[:nb, 1:] = X32[j:j + nb] * inv[:, None]
        S += K @ R[:nb]
    S = S.astype(np.float64)
    P1 = S[:, 0]
    PX = S[:, 1:]
    return Pt1, P1, PX, float(P1.sum())


@numba.njit(fastmath=True, cache=True)
def _estep_kernel(x0, x1, x2, y0, y1, y2, inv2s2, c, pt1, s0, s1, s2, s3, kb, ib, n0, n1):  # pragma: no cover - numba
    """Fused float32 E-step: one pass over targets, the kernel column held in ``kb``.

    exp(-d^2 / (2 sigma2)) is evaluated as 2^t with t = -d^2 log2(e) / (2 sigma2) split into integer
    and fraction: the fraction by a degree-5 polynomial (relative error < 2e-7), the integer written
    straight into the float32 exponent bits (``ib`` viewed as float32), so that the loops vectorise.
    """
    fb = ib.view(np.float32)
    M = y0.shape[0]
    for m in range(M):
        s0[m] = 0.0
        s1[m] = 0.0
        s2[m] = 0.0
        s3[m] = 0.0
    for n in range(n0, n1):
        a0 = x0[n]
        a1 = x1[n]
        a2 = x2[n]
        for m in range(M):
            d0 = a0 - y0[m]
            d1 = a1 - y1[m]
            d2 = a2 - y2[m]
            t = -(d0 * d0 + d1 * d1 + d2 * d2) * inv2s2 * np.float32(1.4426950408889634)
            t = max(t, np.float32(-126.0))
            fl = np.floor(t)
            f = t - fl
            kb[m] = np.float32(1.0) + f * (np.float32(0.6931472) + f * (np.float32(0.2402265) + f * (
                np.float32(0.05550411) + f * (np.float32(0.009618129) + f * np.float32(0.001333355)))))
            ib[m] = (np.int32(fl) + np.int32(127)) << 23
        den = np.float32(0.0)
        for m in range(M):
            k = kb[m] * fb[m]
            kb[m] = k
            den += k
        ksum = den
        if den < np.float32(1.1920929e-07):
            den = np.float32(1.1920929e-07)
        inv = np.float32(1.0) / (den + c)
        pt1[n] = ksum * inv
        b1 = a0 * inv
        b2 = a1 * inv
        b3 = a2 * inv
        for m in range(M):
            k = kb[m]
            s0[m] += k * inv
            s1[m] += k * b1
            s2[m] += k * b2
            s3[m] += k * b3


@numba.njit(parallel=True, cache=True)
def _estep_chunks(x0, x1, x2, y0, y1, y2, inv2s2, c, pt1, S, KB, IB):  # pragma: no cover - numba
    """The fused E-step on ``S.shape[0]`` threads: chunk j of the targets accumulates into S[j]
    (4, M) with its own kernel buffers KB[j], IB[j]; the caller sums S over the chunks.
    """
    C = S.shape[0]
    N = x0.shape[0]
    for j in numba.prange(C):
        _estep_kernel(x0, x1, x2, y0, y1, y2, inv2s2, c, pt1, S[j, 0], S[j, 1], S[j, 2], S[j, 3],
                      KB[j], IB[j], j * N // C, (j + 1) * N // C)


class _FastEstep:
    """The fast E-step for one target cloud: numba kernel for D <= 3, blocked numpy otherwise."""

    def __init__(self, X: np.ndarray, M: int) -> None:
        self.N, self.D = X.shape
        self.M = M
        self.X32 = X.astype(np.float32)
        if self.D <= 3:
            cols = [np.ascontiguousarray(self.X32[:, i]) if i < self.D else np.zeros(self.N, np.float32)
                    for i in range(3)]
            self.x = cols
            self.pt1 = np.empty(self.N, np.float32)
            # one chunk of targets per thread when the work pays for the threads (>= ~0.25 M pairs)
            C = max(1, min(numba.get_num_threads(), self.N * M // 250_000))
            self.S = np.empty((C, 4, M), np.float32)
            self.KB = np.empty((C, M), np.float32)
            self.IB = np.empty((C, M), np.int32)
        else:
            self.xx32 = np.einsum("ij,ij->i", self.X32, self.X32)

    def __call__(self, TY: np.ndarray, sigma2: float, w: float):
        """Pt1 (N,), P1 (M,), PX (M, D), Np."""
        if self.D > 3:
            return _estep_fast(self.X32, self.xx32, TY, sigma2, w)
        D, M, N = self.D, self.M, self.N
        y = [np.ascontiguousarray(TY[:, i], dtype=np.float32) if i < D else np.zeros(M, np.float32)
             for i in range(3)]
        c = (2.0 * np.pi * sigma2) ** (D / 2.0) * w / (1.0 - w) * M / N
        _estep_chunks(*self.x, *y, np.float32(1.0 / (2.0 * sigma2)), np.float32(c), self.pt1, self.S,
                      self.KB, self.IB)
        Ssum = self.S.sum(axis=0, dtype=np.float64)
        P1 = Ssum[0]
        PX = Ssum[1:1 + D].T.copy()
        return self.pt1.astype(np.float64), P1, PX, float(P1.sum())


@numba.njit(cache=True)
def _fps(P, k, start):
    n, D = P.shape
    idx = np.empty(k, dtype=np.int64)
    d = np.full(n, np.inf)
    j = start
    for i in range(k):
        idx[i] = j
        best, bj = -1.0, 0
        for a in range(n):
            s = 0.0
            for b in range(D):
                t = P[a, b] - P[j, b]
                s += t * t
            if s < d[a]:
                d[a] = s
            if d[a] > best:
                best = d[a]
                bj = a
        j = bj
    return idx


def farthest_point_sample(P: np.ndarray, k: int, start: int = 0) -> np.ndarray:
    """Indices of ``k`` points of ``P`` (n, D) spread by farthest-point sampling (deterministic)."""
    P = np.ascontiguousarray(P, dtype=float)
    return _fps(P, min(int(k), P.shape[0]), int(start))


def _nystrom(Y: np.ndarray, beta: float, rank_tol: float, max_rank: int | None):
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


def _cpd_rigid(X, Y, *, w: float = 0.0, tolerance: float = 1e-3, max_iterations: int = 100,
              sigma2: float | None = None, scale: bool = True, normalize: bool = True,
              method: str = "exact") -> CPDResult:
    """Rigid CPD (6.8)-(6.10): find ``s, R, t`` so that ``s R y + t`` matches the target.

    Args:
        X: (N, D) target points, D in {2, 3}. Y: (M, D) template points.
        w: outlier weight in [0, 1). tolerance: stop when |Q - Q_prev| < tolerance (pycpd's rule).
        max_iterations: EM iteration cap. sigma2: initial variance (default: pycpd's).
        scale: estimate the scale ``s`` (else s = 1). normalize: register normalised copies.
        method: "exact" (float64 dense E-step, = pycpd) or "fast" (float32 blocked E-step).

    Returns:
        CPDResult with a :class:`RigidWarp` (det R = +1).
    """
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
    N, M = Xn.shape[0], Yn.shape[0]
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


def cpd_affine(X, Y, *, w: float = 0.0, tolerance: float = 1e-3, max_iterations: int = 100,
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


def _cpd_nonrigid(X, Y, *, beta: float = 2.0, lmbda: float = 2.0, w: float = 0.0, tolerance: float = 1e-3,
                 max_iterations: int = 100, sigma2: float | None = None, normalize: bool = True,
                 method: str = "fast", rank_tol: float = 1e-8, max_rank: int | None = None,
                 max_points: int = 2500) -> CPDResult:
    """Non-rigid CPD (6.11)-(6.13): ``T(y) = y + G(y, Y) W`` with motion coherence.

    Args:
        X: (N, D) target. Y: (M, D) template.
        beta: kernel width (normalised units when ``normalize``). lmbda: regularisation lambda
            (pycpd's ``alpha``). w: outlier weight in [0, 1).
        tolerance: stop when |sigma2 - sigma2_prev| < tolerance (pycpd's rule). max_iterations: cap.
        sigma2: initial variance (default pycpd's mean squared distance / D).
        normalize: register normalised copies (robust to units and offsets).
        method: "exact" (dense, pycpd-equivalent), "lowrank" or "fast" (see module docstring).
        rank_tol: relative eigenvalue cut-off of the low-rank kernel. max_rank: cap on landmarks.
        max_points: "fast" registers subsamples of at most this many points per cloud.

    Returns:
        CPDResult with a :class:`NonrigidWarp` (apply it and its Jacobian to any point).

    Raises:
        InvalidInput: empty or degenerate clouds, bad parameters. SolverFailure: all
        correspondences lost (sigma2 too small to start).
    """
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


def cpd_rigid(X, Y, **kwargs) -> CPDResult:
    return _threaded(_cpd_rigid, X, Y, kwargs.get("method", "exact") != "exact", **kwargs)


def cpd_nonrigid(X, Y, **kwargs) -> CPDResult:
    return _threaded(_cpd_nonrigid, X, Y, kwargs.get("method", "fast") != "exact", **kwargs)


cpd_rigid.__doc__ = _cpd_rigid.__doc__
cpd_nonrigid.__doc__ = _cpd_nonrigid.__doc__


def _threaded(fn, X, Y, single: bool, **kwargs):
    if not single:
        return fn(X, Y, **kwargs)
    with single_thread_blas():
        return fn(X, Y, **kwargs)


def register(X, Y, kind: str = "nonrigid", **kwargs) -> CPDResult:
    """Dispatch to :func:`cpd_rigid`, :func:`cpd_affine` or :func:`cpd_nonrigid` by ``kind``."""
    fn = {"rigid": cpd_rigid, "affine": cpd_affine, "nonrigid": cpd_nonrigid}.get(kind)
    if fn is None:
        raise InvalidInput(f"kind must be 'rigid', 'affine' or 'nonrigid', got {kind!r}", value=kind)
    return fn(X, Y, **kwargs)


def mean_nn_residual(A, B) -> float:
    """Symmetric mean nearest-neighbour distance (6.17)-(6.19) between clouds A (n, D) and B (m, D)."""
    A = as_array(A, "A", (None, None))
    B = as_array(B, "B", (None, None))
    if len(A) == 0 or len(B) == 0:
        raise InvalidInput("residual of an empty cloud is undefined", value=(A.shape, B.shape))
    da, _ = cKDTree(B).query(A)
    db, _ = cKDTree(A).query(B)
    return 0.5 * (float(da.mean()) + float(db.mean()))
