"""The exact mesh check's proof that a clearance measured at a trajectory's samples holds between them.

An independent check resamples a trajectory's cubic at other instants than the planner's samples: a
clearance at the samples says nothing of the motion between them unless it keeps a margin for that
motion. :func:`half_steps` is that margin per sample; where a (part, obstacle) pair is measured closer
than the threshold plus it, :func:`prove_between` halves the two steps next to the sample until the pair
is proven clear over each piece, by collision queries with the piece's travel as their security margin.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from robointel.planning.budget_clock import now as clock_now
from robointel.planning.exact_geometry import MeshGeometry
from robointel.trajectory import Trajectory

#: how many times the motion between two samples is halved to prove a clearance measured close to the threshold
#: (a 2 mm half step becomes 0.5 um: what is left unproven there is a contact)
BETWEEN_DEPTH = 12
#: collision queries between two looks at the clock
QUERY_CHUNK = 64


class OutOfTime(Exception):
    """The time budget ran out inside :func:`prove_between`."""


class _Points:
    """The trajectory's configuration, acceleration and link placements at the times asked, each computed once."""

    def __init__(self, mg: MeshGeometry, dense: Trajectory, deadline: float) -> None:
        self.mg, self.dense, self.deadline = mg, dense, deadline
        self.at: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self.queries = 0

    def add(self, t: float, q: np.ndarray, a: np.ndarray) -> None:
        """Keep the configuration q (n,) and acceleration a (n,) of time t, s."""
        q = np.ascontiguousarray(q, dtype=float)
        self.at[t] = (q, np.asarray(a, float), self.mg.link_placements(q))

    def get(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, acceleration, link placements) at time t, s."""
        got = self.at.get(t)
        if got is None:
            q, _, a = (x[0] for x in self.dense.sample([t]))
            self.add(t, q, a)
            got = self.at[t]
        return got

    def clear(self, i: int, t: float, margin: float) -> bool:
        """Whether pair i is proven at least ``margin`` (m) apart at time t (one collision query)."""
        self.queries += 1
        if self.queries % QUERY_CHUNK == 0 and clock_now() >= self.deadline:
            raise OutOfTime
        return self.mg.pair_clear(self.get(t)[2], i, margin)


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
        qa, aa, _ = pts.get(ta)
        qb, ab, _ = pts.get(tb)
        dt = tb - ta
        move = float(lever @ (0.5 * np.abs(qb - qa) + 0.125 * dt * dt * np.maximum(np.abs(aa), np.abs(ab))))
        if clear(ta, thr + move) and clear(tb, thr + move):
            return True
        if depth == 0:
            return False
        tm = 0.5 * (ta + tb)
        return clear(tm, thr) and step(ta, tm, depth - 1) and step(tm, tb, depth - 1)

    return all(step(ta, tb, BETWEEN_DEPTH) for ta, tb in zip(ts[:-1], ts[1:]))


def prove_between(mg: MeshGeometry, dense: Trajectory, k: int, which: np.ndarray, thr: float,
                  known: np.ndarray | None = None, *, deadline: float = float("inf")) -> int:
    """The first of the pairs ``which`` not proven to keep ``thr`` from sample k - 1 to k + 1 of ``dense``, or -1.

    Pair by pair, each of the two steps is halved until the pair is proven at least ``thr`` plus half
    the step's travel (the pair's lever times the joints' change, plus the cubic's bend off the chord)
    from the obstacle at both of its ends, at most :data:`BETWEEN_DEPTH` times; a midpoint closer than
    ``thr``, or a step not proven at the deepest level, refuses the pair. Each proof is a collision
    query with that distance as its margin (:meth:`MeshGeometry.pair_clear`); a time's proven and
    refuted margins are kept, so a margin between them costs no query.

    Args:
        mg: the exact geometry.
        dense: the trajectory, sampled at its check's step.
        k: the sample.
        which: (m,) the (part, obstacle) pairs (p * O + o).
        thr: the clearance to keep, m.
        known: (m,) lower bounds of the pairs' distances at sample k, m (e.g. as measured there), or None.
        deadline: :func:`~robointel.planning.budget_clock.now` past which the proof gives up.

    Returns:
        The position in ``which`` of the first pair refused, -1 when every pair is proven.

    Raises:
        OutOfTime: past ``deadline`` (looked at every :data:`QUERY_CHUNK` queries).
    """
    idx = [j for j in (k - 1, k, k + 1) if 0 <= j < len(dense.t)]
    ts = [float(t) for t in dense.t[idx]]
    pts = _Points(mg, dense, deadline)
    q3, _, a3 = dense.sample(dense.t[idx])
    for t, q, a in zip(ts, q3, a3):
        pts.add(t, q, a)
    tk = float(dense.t[k])
    for u, i in enumerate(np.asarray(which).tolist()):
        if not _prove_pair(pts, i, ts, thr, None if known is None else (tk, float(known[u]))):
            return u
    return -1


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


__all__ = ["BETWEEN_DEPTH", "OutOfTime", "QUERY_CHUNK", "half_steps", "prove_between"]
