"""The exact mesh check's proof that a clearance measured at a trajectory's samples holds between them.

An independent check resamples a trajectory's cubic at other instants than the planner's samples: a
clearance at the samples says nothing of the motion between them unless it keeps a margin for that
motion. :func:`half_steps` is that margin per sample; where a (part, obstacle) pair is measured closer
than the threshold plus it, :func:`prove_between` halves the two steps next to the sample until the pair
is proven clear over each piece, by collision queries with the piece's travel as their security margin.
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
    """The time budget ran out inside :func:`prove_between`."""


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


class _Points:
    """The trajectory's configuration, acceleration and placements at the times asked, each computed once."""

    def __init__(self, mg: PairGeometry, dense: Trajectory, deadline: float) -> None:
        self.mg, self.dense, self.deadline = mg, dense, deadline
        self.at: dict[float, tuple[np.ndarray, np.ndarray]] = {}  # t -> (q, qd)
        self.placed: dict[float, np.ndarray] = {}
        self.queries = 0

    def add(self, t: float, q: np.ndarray, qd: np.ndarray) -> None:
        """Keep the configuration q (n,) and velocity qd (n,) of time t, s."""
        self.at[t] = (np.ascontiguousarray(q, dtype=float), np.asarray(qd, float))

    def get(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(q, qd) of the trajectory's cubic at time t, s."""
        got = self.at.get(t)
        if got is None:
            q, qd, _ = (x[0] for x in self.dense.sample([t]))
            self.add(t, q, qd)
            got = self.at[t]
        return got

    def clear(self, i: int, t: float, margin: float) -> bool:
        """Whether pair i is proven at least ``margin`` (m) apart at time t (one collision query)."""
        self.queries += 1
        if self.queries % QUERY_CHUNK == 0 and clock_now() >= self.deadline:
            raise OutOfTime
        T = self.placed.get(t)
        if T is None:
            T = self.placed[t] = self.mg.link_placements(self.get(t)[0])
        return self.mg.pair_clear(T, i, margin)


def _prove_pair(pts: _Points, i: int, ts: list[float], thr: float, known: tuple[float, float] | None) -> bool:
    """Whether pair i keeps ``thr`` over the motion through the times ``ts`` (:func:`prove_between`'s rule)."""
    lever = pts.mg.pair_lever[i]
    # per time: the largest margin proven clear, the smallest refuted
    bounds: dict[float, list[float]] = {}
    if known is not None:
        bounds[known[0]] = [known[1], np.inf]

    def clear(t: float, margin: float) -> bool:
        lo_hi = bounds.setdefault(t, [-np.inf, np.inf])
        if margin <= lo_hi[0]:
            return True
        if margin >= lo_hi[1]:
            return False
        ok = pts.clear(i, t, margin)
        lo_hi[0 if ok else 1] = margin
        return ok

    def step(ta: float, tb: float, depth: int) -> bool:
        (qa, va), (qb, vb) = pts.get(ta), pts.get(tb)
        h = tb - ta
        d = qb - qa
        # the cubic on [ta, tb] leaves its chord by at most h^2 / 8 times its largest acceleration there,
        # which is at an end (linear in t): its ends' accelerations from its Hermite data
        acc = np.maximum(np.abs(6.0 * d / h - 4.0 * va - 2.0 * vb), np.abs(6.0 * d / h - 2.0 * va - 4.0 * vb)) / h
        move = float(lever @ (0.5 * np.abs(d) + 0.125 * h * h * acc))
        if clear(ta, thr + move) and clear(tb, thr + move):
            return True
        if depth == 0:
            return False
        tm = 0.5 * (ta + tb)
        return clear(tm, thr) and step(ta, tm, depth - 1) and step(tm, tb, depth - 1)

    return all(step(ta, tb, BETWEEN_DEPTH) for ta, tb in zip(ts[:-1], ts[1:]))


def prove_between(mg: PairGeometry, dense: Trajectory, k: int, which: np.ndarray, thr: float,
                  known: np.ndarray | None = None, *, deadline: float = float("inf")) -> int:
    """The first of the pairs ``which`` not proven to keep ``thr`` from sample k - 1 to k + 1 of ``dense``, or -1.

    Pair by pair, each of the two steps is halved until the pair is proven at least ``thr`` plus half
    the step's travel (the pair's lever times the joints' change, plus the cubic's bend off the chord)
    apart at both of its ends, at most :data:`BETWEEN_DEPTH` times; a midpoint closer than
    ``thr``, or a step not proven at the deepest level, refuses the pair. Each proof is a collision
    query with that distance as its margin (``mg.pair_clear``); a time's proven and refuted margins
    are kept, so a margin between them costs no query.

    Args:
        mg: the exact geometry (robot-obstacle or self pairs).
        dense: the trajectory, sampled at its check's step.
        k: the sample.
        which: (m,) the pairs (indices into ``mg.pair_lever``).
        thr: the clearance to keep, m.
        known: (m,) lower bounds of the pairs' distances at sample k, m (e.g. as measured there), or None.
        deadline: :func:`~robointel.planning.budget_clock.now` past which the proof gives up.

    Returns:
        The position in ``which`` of the first pair refused, -1 when every pair is proven.

    Raises:
        OutOfTime: past ``deadline`` (looked at every :data:`QUERY_CHUNK` queries).
    """
    idx = [j for j in (k - 1, k, k + 1) if 0 <= j < len(dense.t)]
    ts = [float(dense.t[j]) for j in idx]
    pts = _Points(mg, dense, deadline)
    for t, j in zip(ts, idx):  # (the cubic interpolates the samples' positions and velocities)
        pts.add(t, dense.q[j], dense.qd[j])
    tk = float(dense.t[k])
    for u, i in enumerate(np.asarray(which).tolist()):
        if not _prove_pair(pts, i, ts, thr, None if known is None else (tk, float(known[u]))):
            return u
    return -1


def pair_half_steps(Q: np.ndarray, k: int, lever: np.ndarray) -> np.ndarray:
    """:func:`half_steps` at sample k of ``Q`` (K, n) for each pair's own ``lever`` (m, n), m: (m,), each <= it.

    A pair measured above its threshold by this much keeps it over the motion halfway to each neighbouring
    sample; only a pair closer than that needs :func:`prove_between`.
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


__all__ = ["BETWEEN_DEPTH", "OutOfTime", "PairGeometry", "QUERY_CHUNK", "half_steps", "pair_half_steps",
           "prove_between"]
