"""Checks at the public boundary: shapes, finiteness, limits."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from robointel.errors import LimitViolation, NotFinite, ShapeError


def as_array(x: ArrayLike, name: str, shape: Sequence[int | None] | None = None, *,
             dtype: DTypeLike = float) -> np.ndarray:
    """Return ``x`` as a finite float array of the given shape (``None`` matches any size).

    Raises:
        ShapeError: wrong number of dimensions or sizes.
        NotFinite: NaN or inf present.
    """
    try:
        a = np.asarray(x, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise ShapeError(f"{name} must be numeric array-like, got {type(x).__name__}: {exc}", value=x) from None
    if shape is not None:
        if a.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, a.shape)):
            dims = ["N" if s is None else str(s) for s in shape]
            want = "(" + ", ".join(dims) + ("," if len(dims) == 1 else "") + ")"
            raise ShapeError(f"{name} must have shape {want}, got {a.shape}", value=x)
    if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[:3].tolist()
        raise NotFinite(f"{name} contains NaN or inf (first at index {bad}); pass finite values", value=x)
    return a


def check_limits(q: np.ndarray, lower: np.ndarray, upper: np.ndarray, names: Sequence[str],
                 what: str = "q", tol: float = 1e-9) -> None:
    """Raise :class:`LimitViolation` naming the first joint outside ``[lower, upper]``."""
    bad = np.flatnonzero((q < lower - tol) | (q > upper + tol))
    if bad.size:
        i = int(bad[0])
        raise LimitViolation(
            f"{what}[{i}] ({names[i]}) = {q[i]:.6g} is outside its limits "
            f"[{lower[i]:.6g}, {upper[i]:.6g}]; clip it or choose another configuration", value=q)
