"""Compiled (numba) edge checks of the motion planner's shortcut, every edge checked coarse to fine in one pass.

A candidate edge is checked by :func:`~robointel.planning._edge_kernels.edge_valid_bisect` at the
fine resolution itself: the middle of every stretch not yet proven first, so a collision anywhere on
the edge is met after a few checks (as a rejecting pass at a coarser resolution would), while an
edge that passes is proven once (no second walk). The guarantee is that of
:func:`~robointel.planning._edge_kernels.edge_valid`: an accepted edge keeps clearance >= thresh -
res / 2 everywhere (its end is checked >= thresh too), a rejected one has a point below thresh.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from robointel.planning._collision_kernels import config_valid
from robointel.planning._edge_kernels import edge_valid_bisect, root_split


@njit(cache=True)
def edge_fine(q0: np.ndarray, q1: np.ndarray, W: tuple, T: np.ndarray, C: np.ndarray, G: np.ndarray, out: np.ndarray,
              thresh: float, lever: np.ndarray, res: float) -> bool:  # pragma: no cover - compiled
    """The straight motion q0 -> q1 in world ``W``, q1 included, checked coarse to fine at ``res``.

    True when q1 keeps ``thresh`` and every point of the edge keeps thresh - res / 2 (a point
    with clearance c proves sphere travel c - thresh + res / 2 around itself).
    """
    if not config_valid(q1, W, T, C, G, out, thresh):
        return False
    return edge_valid_bisect(q0, q1, W, T, C, G, out, thresh, lever, res)


@njit(cache=True)
def root_edge_fine(q0: np.ndarray, q1: np.ndarray, Wr: tuple, W: tuple, root0: bool, root1: bool, rcap: float,
                   T: np.ndarray, C: np.ndarray, G: np.ndarray, out: np.ndarray, thresh: float, lever: np.ndarray,
                   res: float) -> bool:  # pragma: no cover - compiled
    """:func:`~robointel.planning._edge_kernels.root_edge` with every stretch checked by :func:`edge_fine`.

    Within ``rcap`` rad (max |dq|) of a root (q0 when ``root0``, q1 when ``root1``) the edge is
    checked in the relaxed world ``Wr``, the rest (and the split points) in ``W``.
    """
    if not root0 and not root1:
        return edge_fine(q0, q1, W, T, C, G, out, thresh, lever, res)
    L, a, b, qa, qb = root_split(q0, q1, root0, root1, rcap)
    if L <= 0.0:
        return True
    if a >= b:  # every point within rcap of a root
        return edge_fine(q0, q1, Wr, T, C, G, out, thresh, lever, res)
    if root0 and not edge_fine(q0, qa, Wr, T, C, G, out, thresh, lever, res):
        return False
    if not edge_fine(qa, qb, W, T, C, G, out, thresh, lever, res):  # qb included, in W
        return False
    return not root1 or edge_fine(qb, q1, Wr, T, C, G, out, thresh, lever, res)


#: how far the tightening pass (:func:`~robointel.planning._time_shortcut.tighten_time`) tries to move a vertex
#: toward its neighbours' midpoint, largest first
PULL_FRACTIONS = (1.0, 0.5, 0.25, 0.125)
