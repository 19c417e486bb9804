"""The CPD warps (6.8), (6.11) and the registration result: T(x) for any point, with its Jacobian."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import numpy.typing as npt

from robointel.learning.grasp.cpd_estep import _sqdist

__all__ = ["AffineWarp", "CPDResult", "NonrigidWarp", "RigidWarp", "Warp"]


class Warp(Protocol):
    """A map of space ``T`` with its Jacobian: what a registration fits and a grasp is transferred through."""

    def __call__(self, x: npt.ArrayLike) -> np.ndarray:
        """``T(x)`` for points ``x`` (K, D) (or one point (D,))."""
        ...

    def jacobian(self, x: npt.ArrayLike) -> np.ndarray:
        """``dT/dx`` at points ``x`` (K, D): (K, D, D)."""
        ...


@dataclass(frozen=True)
class RigidWarp:
    """``T(x) = s R x + t`` (6.8). ``R`` (D, D) proper rotation, ``t`` (D,), ``s`` > 0."""

    s: float
    R: np.ndarray
    t: np.ndarray

    def __call__(self, x: npt.ArrayLike) -> np.ndarray:
        """``T(x)`` for points ``x`` (K, D)."""
        x = np.asarray(x, float)
        return self.s * x @ self.R.T + self.t

    def jacobian(self, x: npt.ArrayLike) -> np.ndarray:
        """dT/dx at each point: (K, D, D) (constant ``s R``)."""
        x = np.atleast_2d(np.asarray(x, float))
        return np.broadcast_to(self.s * self.R, (x.shape[0],) + self.R.shape).copy()


@dataclass(frozen=True)
class AffineWarp:
    """``T(x) = B x + t``. ``B`` (D, D), ``t`` (D,)."""

    B: np.ndarray
    t: np.ndarray

    def __call__(self, x: npt.ArrayLike) -> np.ndarray:
        """``T(x)`` for points ``x`` (K, D)."""
        return np.asarray(x, float) @ self.B.T + self.t

    def jacobian(self, x: npt.ArrayLike) -> np.ndarray:
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

    def __call__(self, x: npt.ArrayLike) -> np.ndarray:
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

    def jacobian(self, x: npt.ArrayLike) -> np.ndarray:
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
    warp: Warp
    TY: np.ndarray
    sigma2: float
    iterations: int
    converged: bool
    P1: np.ndarray | None = field(repr=False, default=None)
    method: str = "exact"
    rank: int | None = None
