"""A robot's joint space: configurations checked against its limits, snapped, wrapped and sampled.

A mixin of :class:`robointel.robot.Robot`: it reads the robot's joint count ``nq``, ``joint_names``, the
limits ``lower``/``upper`` (rad or m) and the ``continuous`` mask (a continuous joint is an angle in
[-2 pi, 2 pi]).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from robointel._validate import as_array, check_limits
from robointel.errors import NotFinite

LIMIT_SNAP = 1e-5
"""A configuration this close outside a limit (rad or m) is put on it at the planner's boundary."""


class JointSpace:
    """Configuration checks and sampling for the robot that mixes this in."""

    nq: int
    joint_names: list[str]
    lower: np.ndarray
    upper: np.ndarray
    continuous: np.ndarray

    def check_q(self, q: ArrayLike, name: str = "q", *, limits: bool = False) -> np.ndarray:
        """Validate a configuration: shape (nq,), finite, and (``limits=True``) within limits."""
        if type(q) is np.ndarray and q.dtype == np.float64 and q.shape == (self.nq,):
            if not np.isfinite(q @ q):  # any NaN/inf (or absurd magnitude) makes this non-finite
                raise NotFinite(f"{name} contains NaN or inf: {q}; pass finite values", value=q)
        else:
            q = as_array(q, name, (self.nq,))
        if limits:
            check_limits(q, self.lower, self.upper, self.joint_names, name)
        return q

    def snap_to_limits(self, q: ArrayLike, tol: float = LIMIT_SNAP) -> np.ndarray:
        """``q`` (nq,) with values at most ``tol`` (rad or m) outside a limit put on it (rounding in stored files).

        Values farther out are left as they are (so that :meth:`check_q` names them).
        """
        q = np.array(self.check_q(q), dtype=float)
        near = ((q < self.lower) & (q >= self.lower - tol)) | ((q > self.upper) & (q <= self.upper + tol))
        q[near] = np.clip(q[near], self.lower[near], self.upper[near])
        return q

    def wrap_goal(self, goal: ArrayLike, ref: ArrayLike) -> np.ndarray:
        """``goal`` with each continuous joint turned by whole turns to the value nearest ``ref`` within limits.

        Args:
            goal: (nq,) configuration, rad.
            ref: (nq,) the configuration the motion starts from, rad.

        Returns:
            (nq,) the same pose of the robot, reached by the shorter turn of each continuous joint.
        """
        g = np.array(self.check_q(goal, "goal"), dtype=float)
        r = self.check_q(ref, "ref")
        for j in np.flatnonzero(self.continuous):
            k = np.round((r[j] - g[j]) / (2 * np.pi))
            for cand in (g[j] + 2 * np.pi * k, g[j] + 2 * np.pi * (k - 1), g[j] + 2 * np.pi * (k + 1)):
                if self.lower[j] <= cand <= self.upper[j] and abs(cand - r[j]) <= np.pi + 1e-12:
                    g[j] = cand
                    break
        return g

    def random_configuration(self, rng: np.random.Generator | int | None = None, n: int | None = None) -> np.ndarray:
        """Uniform random configuration(s) within the joint limits: (nq,) or (n, nq)."""
        rng = np.random.default_rng(rng)
        size = (self.nq,) if n is None else (n, self.nq)
        return rng.uniform(self.lower, self.upper, size=size)
