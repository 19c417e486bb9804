"""The exact mesh check's proof that a clearance measured at a trajectory's samples holds between them.

An independent check resamples a trajectory's cubic at other instants than the planner's samples: a
clearance at the samples says nothing of the motion between them unless it keeps a margin for that
motion. :func:`half_steps` is that margin per sample; where a pair (a link and an obstacle, or two links) is
measured closer than the threshold plus its own (:func:`pair_half_steps`),
:meth:`BetweenProofs.first_refused` halves the two steps next to the sample until the pair is proven
clear over each piece, by collision queries with the piece's travel as their security margin.
"""
from __future__ import annotations

from typing import Protocol

import numpy as np
from numba import njit

from robointel.planning.budget_clock import now as clock_now
from robointel.trajectory import Trajectory

#: how many times the motion between two samples is halved to prove a clearance measured close to the threshold
#: (a 2 mm half step becomes 0.5 um: what is left unproven there is a contact)
BETWEEN_DEPTH = 12
#: collision queries between two looks at the clock
QUERY_CHUNK = 64


class OutOfTime(Exception):
    """The time budget ran out inside a between-sample proof."""


class PairGeometry(Protocol):
    """Pairs of placed geometries whose clearance can be proven.

    The robot against obstacles (:class:`~robointel.planning.exact_geometry.MeshGeometry`) or against
    itself (:class:`~robointel.planning.exact_self.SelfGeometry`).
    """

    #: (P, n) per pair, how fast its distance can change per unit of each joint's motion, m/rad
    pair_lever: np.ndarray

    def link_placements(self, q: np.ndarray) -> np.ndarray:
        """The placements at q that :meth:`pair_clear` takes."""

    def pair_clear(self, T: np.ndarray, i: int, margin: float) -> bool:
        """Whether pair i is proven at least ``margin`` (m) apart at the placements T."""


class BetweenProofs:
    """The between-sample proofs of one trajectory's check, sharing their work across its samples.

    For a pair measured closer than the threshold plus its half steps at sample k,
    :meth:`first_refused` proves the two steps next to k. Each step is halved until the pair is proven
    at least ``thr`` plus half the piece's travel (the pair's lever times the joints' change, plus the
    cubic's bend off the chord) apart at both of its ends, at most :data:`BETWEEN_DEPTH` times; a
    midpoint closer than ``thr``, or a piece not proven at the deepest level, refuses the pair. Each
    proof is a collision query with that distance as its margin (``mg.pair_clear``). Kept for the
    whole check: the configurations and placements of the instants visited, per pair and instant the
    largest margin proven and the smallest refuted (a margin between them costs no query), and the
    steps proven (a pair measured at consecutive samples has their common step proven once).

    Args:
        mg: the exact geometry (robot-obstacle or self pairs).
        dense: the trajectory, sampled at its check's step.
        thr: the clearance to keep, m.
        deadline: :func:`~robointel.planning.budget_clock.now` past which a proof gives up.
    """

    def __init__(self, mg: PairGeometry, dense: Trajectory, thr: float, *, deadline: float = float("inf")) -> None:
        self.mg, self.dense, self.thr, self.deadline = mg, dense, thr, deadline
        self._at: dict[float, tuple[np.ndarray, np.ndarray]] = {}  # t -> (q, qd) of the cubic
        self._placed: dict[float, np.ndarray] = {}  # t -> mg.link_placements
        self._bounds: dict[tuple[int, float], list[float]] = {}  # (pair, t) -> [proven, refuted] margins
        self._done: set[tuple[int, int]] = set()  # (pair, j): the step from sample j to j + 1 proven
        self.queries = 0

    def first_refused(self, k: int, which: np.ndarray, known: np.ndarray | None = None) -> int:
        """The position in ``which`` of the first pair not proven to keep ``thr`` from sample k - 1 to k + 1, or -1.

        Args:
            k: the sample.
            which: (m,) the pairs (indices into ``mg.pair_lever``).
            known: (m,) lower bounds of the pairs' distances at sample k, m (e.g. as measured there), or None.

        Raises:
            OutOfTime: past the deadline (looked at every :data:`QUERY_CHUNK` queries).
        """
        dense = self.dense
        idx = [j for j in (k - 1, k, k + 1) if 0 <= j < len(dense.t)]
        for j in idx:  # (the cubic interpolates the samples' positions and velocities)
            self._at.setdefault(float(dense.t[j]), (np.ascontiguousarray(dense.q[j]), np.asarray(dense.qd[j])))
        tk = float(dense.t[k])
        for u, i in enumerate(np.asarray(which).tolist()):
            if known is not None:
                lo_hi = self._bounds.setdefault((i, tk), [-np.inf, np.inf])
                lo_hi[0] = max(lo_hi[0], float(known[u]))
            for j0, j1 in zip(idx[:-1], idx[1:]):
                if (i, j0) in self._done:
                    continue
                if not self._step(i, float(dense.t[j0]), float(dense.t[j1]), BETWEEN_DEPTH):
                    return u
                self._done.add((i, j0))
        return -1

    def _get(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(q, qd) of the trajectory's cubic at a sample's time or a midpoint visited, t (s)."""
        return self._at[t]

    def _clear(self, i: int, t: float, margin: float) -> bool:
        """Whether pair i is proven at least ``margin`` (m) apart at time t (a query unless the bounds decide)."""
        lo_hi = self._bounds.setdefault((i, t), [-np.inf, np.inf])
        if margin <= lo_hi[0]:
            return True
        if margin >= lo_hi[1]:
            return False
        self.queries += 1
        if self.queries % QUERY_CHUNK == 0 and clock_now() >= self.deadline:
            raise OutOfTime
        T = self._placed.get(t)
        if T is None:
            T = self._placed[t] = self.mg.link_placements(self._get(t)[0])
        ok = self.mg.pair_clear(T, i, margin)
        lo_hi[0 if ok else 1] = margin
        return ok

    def _step(self, i: int, ta: float, tb: float, depth: int) -> bool:
        """Whether pair i keeps ``thr`` over the motion from ta to tb (halved at most ``depth`` times)."""
        (qa, va), (qb, vb) = self._get(ta), self._get(tb)
        h = tb - ta
        d = qb - qa
        # the cubic on [ta, tb] leaves its chord by at most h^2 / 8 times its largest acceleration there,
        # which is at an end (linear in t): its ends' accelerations from its Hermite data
        acc = np.maximum(np.abs(6.0 * d / h - 4.0 * va - 2.0 * vb), np.abs(6.0 * d / h - 2.0 * va - 4.0 * vb)) / h
        margin = self.thr + float(self.mg.pair_lever[i] @ (0.5 * np.abs(d) + 0.125 * h * h * acc))
        if self._clear(i, ta, margin) and self._clear(i, tb, margin):
            return True
        if depth == 0:
            return False
        tm = 0.5 * (ta + tb)
        if tm not in self._at:  # the cubic's midpoint from its Hermite data
            self._at[tm] = (0.5 * (qa + qb) + 0.125 * h * (va - vb), 1.5 * d / h - 0.25 * (va + vb))
        return self._clear(i, tm, self.thr) and self._step(i, ta, tm, depth - 1) and self._step(i, tm, tb, depth - 1)


def pair_half_steps(Q: np.ndarray, k: int, lever: np.ndarray) -> np.ndarray:
    """:func:`half_steps` at sample k of ``Q`` (K, n) for each pair's own ``lever`` (m, n), m: (m,).

    A pair measured above its threshold by this much keeps it over the motion halfway to each neighbouring
    sample; only a pair closer than that needs :meth:`BetweenProofs.first_refused`.
    """
    K = len(Q)
    a = np.abs(Q[k] - Q[k - 1]) if k > 0 else np.zeros(Q.shape[1])
    b = np.abs(Q[k + 1] - Q[k]) if k < K - 1 else np.zeros(Q.shape[1])
    bend = np.zeros(Q.shape[1])
    for j in range(max(k - 1, 1), min(k + 2, K - 1)):
        bend = np.maximum(bend, np.abs(Q[j + 1] - 2.0 * Q[j] + Q[j - 1]))
    return 0.5 * np.maximum(lever @ a, lever @ b) + 0.125 * (lever @ bend)


@njit(cache=True)
def half_steps(Q: np.ndarray, reach: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Per sample of ``Q`` (K, n), how far any point of the robot may move toward the midpoints of its two steps, m.

    ``reach`` (n,): per joint, the most a point moves per rad of it (the largest of the pairs' levers).
    Half of each neighbouring step's travel, the larger, plus an eighth of the joints' second difference
    there (a cubic through the samples leaves their chord by about that): a clearance measured at a sample
    above the threshold by this much holds over the motion to halfway to each neighbouring sample.
    """
    K, n = Q.shape
    step = np.zeros(max(K - 1, 0))
    bend = np.zeros(K)
    for k in range(K - 1):
        t = 0.0
        for j in range(n):
            t += reach[j] * abs(Q[k + 1, j] - Q[k, j])
        step[k] = t
    for k in range(1, K - 1):
        t = 0.0
        for j in range(n):
            t += reach[j] * abs(Q[k + 1, j] - 2.0 * Q[k, j] + Q[k - 1, j])
        bend[k] = 0.125 * t
    h = np.zeros(K)
    for k in range(K):
        a = step[k - 1] if k > 0 else 0.0
        b = step[k] if k < K - 1 else 0.0
        c = max(bend[max(k - 1, 0)], bend[k], bend[min(k + 1, K - 1)])
        h[k] = 0.5 * max(a, b) + c
    return h


__all__ = ["BETWEEN_DEPTH", "BetweenProofs", "OutOfTime", "PairGeometry", "QUERY_CHUNK", "half_steps",
           "pair_half_steps"]
