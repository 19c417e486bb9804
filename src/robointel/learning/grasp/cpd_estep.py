"""The Gaussian-mixture E-step of CPD (6.5)-(6.7) and farthest-point sampling.

The Gaussian-mixture E-step of CPD (6.5)-(6.7): exact float64 and the fused float32 numba kernel,
and farthest-point sampling (landmarks and subsamples).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["farthest_point_sample"]

LANES = 16  # partial sums of the kernel column in the fused E-step
MAX_CHUNKS = 8  # target chunks of the fused E-step: the summation order, whatever the thread count


def _sqdist(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a_i - b_j|^2 (I, J) computed with per-dimension differences (no cancellation)."""
    d2 = np.zeros((a.shape[0], b.shape[0]), dtype=np.result_type(a, b))
    for k in range(a.shape[1]):
        diff = a[:, k, None] - b[None, :, k]
        d2 += diff * diff
    return d2


def _estep_exact(X: np.ndarray, TY: np.ndarray, sigma2: float, w: float,
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
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


def _estep_fast(X32: np.ndarray, xx32: np.ndarray, TY: np.ndarray, sigma2: float, w: float,
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
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


@numba.njit(fastmath={"nnan", "ninf", "nsz", "arcp", "afn"}, cache=True)
def _estep_kernel(x0: np.ndarray, x1: np.ndarray, x2: np.ndarray, y0: np.ndarray, y1: np.ndarray, y2: np.ndarray,
                  inv2s2: float, c: float, pt1: np.ndarray, s0: np.ndarray, s1: np.ndarray, s2: np.ndarray,
                  s3: np.ndarray, kb: np.ndarray, ib: np.ndarray, n0: int, n1: int) -> None:  # pragma: no cover - numba
    """Fused float32 E-step: one pass over targets, the kernel column held in ``kb``.

    exp(-d^2 / (2 sigma2)) is evaluated as 2^t with t = -d^2 log2(e) / (2 sigma2) split into integer
    and fraction: the fraction by a degree-5 polynomial (relative error < 2e-7), the integer written
    straight into the float32 exponent bits (``ib`` viewed as float32), so that the loops vectorise.
    Fast-math without reassociation or contraction: the sums run in the order written, so the
    result is the same bits whether the code was just compiled or loaded from numba's cache.
    """
    fb = ib.view(np.float32)
    acc = np.empty(LANES, np.float32)
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
        for m in range(M):
            kb[m] *= fb[m]
        acc[:] = 0.0  # LANES partial sums in a fixed order: vectorised without reassociation
        for m0 in range(0, M - LANES + 1, LANES):
            for j in range(LANES):
                acc[j] += kb[m0 + j]
        for m in range(M - M % LANES, M):
            acc[m % LANES] += kb[m]
        den = np.float32(0.0)
        for j in range(LANES):
            den += acc[j]
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
def _estep_chunks(x0: np.ndarray, x1: np.ndarray, x2: np.ndarray, y0: np.ndarray, y1: np.ndarray, y2: np.ndarray,
                  inv2s2: float, c: float, pt1: np.ndarray, S: np.ndarray, KB: np.ndarray,
                  IB: np.ndarray) -> None:  # pragma: no cover - numba
    """Run the fused E-step on ``S.shape[0]`` threads.

    The fused E-step on ``S.shape[0]`` threads: chunk j of the targets accumulates into S[j]
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
            # one chunk per ~0.25 M pairs (what pays for a thread), at most MAX_CHUNKS; not the thread
            # count, so that the summation order and the result are the same on any number of threads
            C = max(1, min(MAX_CHUNKS, self.N * M // 250_000))
            self.S = np.empty((C, 4, M), np.float32)
            self.KB = np.empty((C, M), np.float32)
            self.IB = np.empty((C, M), np.int32)
        else:
            self.xx32 = np.einsum("ij,ij->i", self.X32, self.X32)

    def __call__(self, TY: np.ndarray, sigma2: float, w: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Pt1 (N,), P1 (M,), PX (M, D), Np."""
        if self.D > 3:
            return _estep_fast(self.X32, self.xx32, TY, sigma2, w)
        D, M, N = self.D, self.M, self.N
        y = [np.ascontiguousarray(TY[:, i], dtype=np.float32) if i < D else np.zeros(M, np.float32)
             for i in range(3)]
        c = (2.0 * np.pi * sigma2) ** (D / 2.0) * w / (1.0 - w) * M / N
        if self.S.shape[0] == 1:
            # one chunk: the serial kernel, no parallel launch (its end waits for every numba thread to
            # have been scheduled: on a loaded machine that wait, per E-step, was ~15x the arithmetic)
            S = self.S[0]
            _estep_kernel(*self.x, *y, np.float32(1.0 / (2.0 * sigma2)), np.float32(c), self.pt1,  # type: ignore[call-arg, arg-type]
                          S[0], S[1], S[2], S[3], self.KB[0], self.IB[0], 0, N)
        else:
            _estep_chunks(*self.x, *y, np.float32(1.0 / (2.0 * sigma2)), np.float32(c), self.pt1,  # type: ignore[call-arg, arg-type]
                          self.S, self.KB, self.IB)
        Ssum = self.S.sum(axis=0, dtype=np.float64)
        P1 = Ssum[0]
        PX = Ssum[1:1 + D].T.copy()
        return self.pt1.astype(np.float64), P1, PX, float(P1.sum())


@numba.njit(cache=True)
def _fps(P: np.ndarray, k: int, start: int) -> np.ndarray:
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
