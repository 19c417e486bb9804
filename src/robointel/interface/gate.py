"""The safety gate every joint command passes before it reaches a backend (shared by all backends).

A target is refused when it is not finite, has the wrong shape, lies outside the joint position
limits, or is farther from the previous command than one controller period allows at the joint's
maximum speed: ``|q_k - q_{k-1}| <= margin * qd_max * period``.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput, UnsafeCommand


class SafetyGate:
    """Check joint position targets against the limits and the largest per-period jump.

    Args:
        joint_names: n joint names (for messages).
        lower: (n,) lower joint limits, rad.
        upper: (n,) upper joint limits, rad.
        velocity_limit: (n,) maximum joint speeds, rad/s.
        period: controller period, s.
        margin: allowed factor over ``velocity_limit * period`` (>= 1; rounding of resampled paths).

    Raises:
        InvalidInput: inconsistent shapes or non-positive limits.
    """

    def __init__(self, joint_names: Sequence[str], lower: npt.ArrayLike, upper: npt.ArrayLike,
                 velocity_limit: npt.ArrayLike, period: float, *, margin: float = 1.05) -> None:
        self.joint_names = list(joint_names)
        n = len(self.joint_names)
        self.lower = np.asarray(lower, dtype=float).reshape(-1)
        self.upper = np.asarray(upper, dtype=float).reshape(-1)
        self.velocity_limit = np.asarray(velocity_limit, dtype=float).reshape(-1)
        if not (self.lower.shape == self.upper.shape == self.velocity_limit.shape == (n,)):
            raise InvalidInput(f"limits must have {n} values each", value=(lower, upper, velocity_limit))
        if not (np.all(self.velocity_limit > 0) and np.all(self.lower < self.upper)):
            raise InvalidInput("velocity limits must be positive and lower < upper", value=(lower, upper))
        if not (np.isfinite(period) and period > 0) or not margin >= 1.0:
            raise InvalidInput(f"period must be > 0 and margin >= 1, got {period}, {margin}", value=period)
        self.period = float(period)
        self.max_step = margin * self.velocity_limit * self.period
        self.n = n
        # the per-target path in plain floats (see check): a numpy call costs ~20 us on a cold cache
        self._bounds = (tuple(zip(self.lower.tolist(), self.upper.tolist(), self.max_step.tolist(), strict=True))
                        if np.all(np.isfinite(self.lower)) and np.all(np.isfinite(self.upper)) else None)

    def check(self, q_target: npt.ArrayLike, q_previous: npt.NDArray[np.float64] | None) -> npt.NDArray[np.float64]:
        """Return ``q_target`` as a fresh (n,) float array if it is safe to send.

        Args:
            q_target: (n,) joint position target, rad.
            q_previous: (n,) previous command (or the measured position before the first), rad; None
                skips the jump check.

        Returns:
            (n,) the target, rad.

        Raises:
            UnsafeCommand: wrong shape, NaN/inf, outside the limits, or a jump over ``max_step``;
                ``.value`` is the target.
        """
        ok = self._accepts(q_target, q_previous)
        if ok is not None:
            return np.array(ok)
        q = self._as_vector(q_target)
        if not np.all(np.isfinite(q)):
            raise UnsafeCommand(f"joint target contains NaN or inf: {q.tolist()}; refused", value=q)
        out = (q < self.lower) | (q > self.upper)
        if out.any():
            i = int(np.flatnonzero(out)[0])
            raise UnsafeCommand(f"joint target {self.joint_names[i]} = {q[i]:.6g} rad is outside its limits "
                                f"[{self.lower[i]:.6g}, {self.upper[i]:.6g}]; refused", value=q)
        if q_previous is not None:
            step = np.abs(q - q_previous)
            far = step > self.max_step
            if far.any():
                i = int(np.flatnonzero(far)[0])
                raise UnsafeCommand(
                    f"joint target {self.joint_names[i]} jumps {step[i]:.4g} rad in one {self.period * 1e3:.3g} ms "
                    f"period; at most {self.max_step[i]:.4g} rad (the maximum speed) is allowed; refused", value=q)
        return q

    def _as_vector(self, q_target: object) -> npt.NDArray[np.float64]:
        """``q_target`` as an (n,) float array: a flat sequence of n real numbers, nothing else.

        Raises:
            UnsafeCommand: not a flat sequence of n numbers (strings, booleans, nested lists such as a
                1 x n list, other shapes), or a number too large for a float (``10**400``).
        """
        try:
            shape = np.shape(q_target) if isinstance(q_target, np.ndarray | list | tuple) else None
        except ValueError:  # a ragged nesting
            shape = None
        if shape != (self.n,):
            raise UnsafeCommand(f"joint target must be a flat sequence of {self.n} numbers, got "
                                f"{type(q_target).__name__} of shape {shape}", value=q_target)
        assert isinstance(q_target, np.ndarray | list | tuple)
        items = q_target.tolist() if isinstance(q_target, np.ndarray) else list(q_target)
        if not all(isinstance(x, int | float | np.integer | np.floating) and not isinstance(x, bool | np.bool_)
                   for x in items):
            raise UnsafeCommand(f"joint target must hold {self.n} numbers, got {[type(x).__name__ for x in items]}",
                                value=q_target)
        try:
            return np.array([float(x) for x in items], dtype=float)
        except OverflowError:
            raise UnsafeCommand("joint target holds a number too large for a float; refused",
                                value=q_target) from None

    def _accepts(self, q_target: npt.ArrayLike, q_previous: npt.NDArray[np.float64] | None) -> list[float] | None:
        """The target as n floats when it passes every check of :meth:`check`, else None (undecided).

        The same checks in plain Python floats, for the one shape a stream sends (a 1-D sequence of n
        numbers, a 1-D previous command): called once per controller period on a cache the rest of
        the machine has evicted, a dozen numpy calls cost ~75-155 µs here, this ~40-60 µs
        (docs/design/streaming.md). NaN fails every comparison and the limits are finite, so a
        non-finite target is never accepted here; whatever is not accepted goes through the numpy
        checks, which decide and word the refusal.
        """
        bounds = self._bounds
        if (bounds is None or not isinstance(q_target, np.ndarray | list | tuple)
                or (isinstance(q_target, np.ndarray) and q_target.ndim != 1) or len(q_target) != self.n):
            return None
        try:  # an array's tolist() gives Python numbers at once: no numpy scalar per element
            q = [float(x) for x in (q_target.tolist() if isinstance(q_target, np.ndarray) else q_target)
                 if isinstance(x, int | float) and not isinstance(x, bool)]
        except (TypeError, ValueError, OverflowError):
            return None
        if len(q) != self.n:  # something other than a number
            return None
        if q_previous is None:
            for x, (lo, hi, _) in zip(q, bounds, strict=True):
                if not lo <= x <= hi:
                    return None
            return q
        if not isinstance(q_previous, np.ndarray) or q_previous.shape != (self.n,):
            return None
        for x, y, (lo, hi, step) in zip(q, q_previous.tolist(), bounds, strict=True):
            if not (lo <= x <= hi and -step <= x - y <= step):
                return None
        return q

    def check_path(self, q: npt.NDArray[np.float64], q_previous: npt.NDArray[np.float64] | None) -> None:
        """Check a whole (K, n) path sampled at the period before any of it is sent.

        Raises:
            UnsafeCommand: the first sample that :meth:`check` would refuse (message names its index).
        """
        try:
            q = np.asarray(q, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise UnsafeCommand(f"path must be a (K, {self.n}) array of numbers", value=q) from None
        if q.ndim != 2 or q.shape[1] != self.n:
            raise UnsafeCommand(f"path must have shape (K, {self.n}), got {q.shape}", value=q)
        bad = ~np.all(np.isfinite(q), axis=1) | np.any((q < self.lower) | (q > self.upper), axis=1)
        prev = q[:-1] if q_previous is None else np.vstack([q_previous[None], q[:-1]])
        steps = np.abs(q[1:] - q[:-1]) if q_previous is None else np.abs(q - prev)
        jump = np.any(steps > self.max_step, axis=1)
        if q_previous is None:
            jump = np.concatenate([[False], jump])
        bad |= jump
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            try:
                self.check(q[k], None if (k == 0 and q_previous is None) else (prev[k - 1] if q_previous is None
                                                                               else prev[k]))
            except UnsafeCommand as exc:
                raise UnsafeCommand(f"trajectory sample {k}: {exc}", value=q[k]) from None
