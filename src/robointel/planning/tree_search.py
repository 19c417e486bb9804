"""The motion planner's global search: RRT-Connect from the start to a goal set, and the re-check of its path.

:func:`search` runs the compiled kernel (:mod:`robointel.planning._rrt_kernels`) in chunks of
iterations between which it watches the clock; :func:`path_valid` re-checks a found path's edges
at the fine resolution.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from robointel.planning import _batch_edges as BE
from robointel.planning import _rrt_kernels as R
from robointel.planning.budget_clock import now as clock_now
from robointel.planning.environment import Environment
from robointel.planning.motion_settings import MotionSettings


def batch_state(env: Environment) -> tuple:
    """The environment's batch state (:func:`~robointel.planning._batch_edges.batch_state`), built on first use.

    It depends on the obstacles and the robot's spheres and self-collision pairs, which every world of
    the environment (:meth:`Environment.use`) shares.
    """
    bs = getattr(env, "_batch_state", None)
    if bs is None:
        bs = BE.batch_state(env.world)
        env._batch_state = bs  # type: ignore[attr-defined]
    return bs


def warm_search(env: Environment) -> None:
    """Compile (or load from numba's disk cache) the search kernel for ``env``'s world layout."""
    W, s = env.world, env.scratch
    q = np.clip(np.zeros(env.robot.nq), env.robot.lower, env.robot.upper)
    X = np.zeros((2, len(q), 4))
    X[:, :, 0] = q
    parent = np.full((2, 4), -1, np.int64)
    count = np.array([1, 1], np.int64)
    R.rrt_connect(X, parent, count, env.robot.lower, env.robot.upper, 0, np.ones(3), np.zeros((2, 2), np.int64),
                  W, W, count, 0.2, s.T, s.C, s.G, s.out, 0.0, env.lever, 0.01, np.zeros(2, np.int64), batch_state(env),
                  np.full((2, 4), np.inf), np.inf)


def path_valid(env: Environment, path: np.ndarray, d_min: float, resolution: float, W: tuple,
               Wr: tuple, rcap: float = float("inf")) -> bool:
    """Every edge of ``path`` passes the edge check at ``resolution``.

    The first and last edge are checked in ``Wr`` within ``rcap`` rad (max |dq|) of the start and
    the goal and in ``W`` beyond, the others in ``W``.
    """
    s, BS = env.scratch, batch_state(env)
    last = len(path) - 2
    return all(BE.root_edge_batch(a, b, Wr, W, k == 0, k == last, float(rcap), BS, float(d_min), float(resolution),
                                  s.out)
               for k, (a, b) in enumerate(zip(path[:-1], path[1:])))


#: iterations of the first call of the compiled search (the clock is read between calls)
CHUNK = 32
#: the most iterations per call: the calls double while one takes less than half of :data:`CHUNK_S`
MAX_CHUNK = 1024
#: the wall time one call of the compiled search aims at, s: long enough that calling it (typing its
#: arguments, about 11 us) costs little, short enough that the deadline is read about every millisecond
CHUNK_S = 1e-3

#: the packed world's entries that place the spheres and obstacles and pick the self-collision pairs (the
#: radii aside): trees carry over only between worlds equal in all of them
_SHAPE = (5, 6, 8, 9, 11, 12, 13, 14, 15, 16, 17, 18, 19)
#: the radii: obstacle spheres and groups, self-collision spheres and groups
_RADII = (7, 10, 21, 22)


@dataclass
class SearchTrees:
    """The trees of a search that found no path, for a later search in a world no stricter to go on from.

    Every node of them is free, and every edge valid, in the worlds they were grown in at clearance
    ``thr`` and resolution ``res``; so in any world with the same spheres, obstacles and self-collision
    pairs and no radius larger (e.g. the fitted spheres after the covering ones, or grown half as far).

    Attributes:
        X: (2, n, cap) the nodes of each tree joint by joint, rad.
        parent: (2, cap) parent of each node (-1: a root).
        count: (2,) nodes in each tree.
        rng: (3,) the trees' adapted ranges and the range asked for, rad.
        win: (2, 2) each tree's range-adaptation window.
        dom: (2, cap) each node's dynamic domain, rad (:mod:`robointel.planning._rrt_kernels`).
        W: the world the nodes were checked in.
        radii: per radius entry of the packed world, the smaller of its values in ``W`` and in the
            relaxed world of the root edges (each node and edge was checked in one of them), m.
        thr: the clearance kept, m.
        res: the edge-check resolution, m of sphere-centre travel.
    """

    X: np.ndarray
    parent: np.ndarray
    count: np.ndarray
    rng: np.ndarray
    win: np.ndarray
    dom: np.ndarray
    W: tuple
    radii: tuple
    thr: float
    res: float

    def placed_alike(self, W: tuple, n: int, cap: int) -> bool:
        """Whether ``W`` places the same spheres, obstacles and self-collision pairs (the radii aside)."""
        return self.X.shape == (2, n, cap) and all(W[k] is self.W[k] or np.array_equal(W[k], self.W[k])
                                                   for k in _SHAPE)

    def fits(self, W: tuple, Wr: tuple, thr: float, res: float, n: int, cap: int) -> bool:
        """Whether every node and edge is still valid when checked in ``W`` (root edges in ``Wr``)."""
        if thr != self.thr or res < self.res or not self.placed_alike(W, n, cap):
            return False
        return all(np.all(np.maximum(W[k], Wr[k]) <= r) for k, r in zip(_RADII, self.radii))

    @classmethod
    def of(cls, X: np.ndarray, parent: np.ndarray, count: np.ndarray, rng: np.ndarray, win: np.ndarray,
           dom: np.ndarray, W: tuple, Wr: tuple, thr: float, res: float) -> SearchTrees:
        """The trees grown with nodes checked in ``W`` and root edges in ``Wr`` (their radii the smaller)."""
        return cls(X, parent, count, rng, win, dom, W, tuple(np.minimum(W[k], Wr[k]) for k in _RADII), thr, res)


class TreeCarry:
    """Holds the trees of the last search (:class:`SearchTrees`), or None.

    A search that found no path leaves its trees for the next search in a world no stricter, which goes
    on from them as they are. A search that found a path leaves them too, for a search in a stricter
    world (the links the collision meshes caught grown, a finer resolution): that one keeps the nodes
    still free and reached by edges still valid (:func:`~robointel.planning._rrt_kernels.revalidate`)
    and goes on from them. The caller drops them (``trees = None``) when the next search must look
    for another way in the same world.
    """

    def __init__(self) -> None:
        self.trees: SearchTrees | None = None


def search(env: Environment, q0: np.ndarray, goals: np.ndarray, st: MotionSettings, res: float,
           deadline: float, W: tuple, Wr: tuple, attempt: int = 0,
           thr: float | None = None, rcap: float = float("inf"),
           stall: int = 0, walled: int | None = None,
           carry: TreeCarry | None = None) -> tuple[np.ndarray | None, int, str]:
    """RRT-Connect from q0 to the goal set (a direct edge first): (path, goal index, why not).

    Nodes and edges are checked in ``W``, edges leaving the start or a goal in ``Wr`` for their
    first ``rcap`` rad (max |dq|) and in ``W`` beyond. ``stall`` > 0: the search also gives up
    when neither tree has gained a node in its last ``stall`` iterations (a root walled in by the
    spheres of ``W``; the caller has another model to try; counted from the end of the last call of the
    compiled kernel that added a node), its reason then starting ``"stalled"``;
    with ``walled``, only while one of the trees holds at most that many nodes besides its roots.
    With ``carry``, the search goes on from the trees it holds (same start and goals, the same
    spheres placed alike): as they are when they :meth:`~SearchTrees.fits` this world, else from the
    nodes still free and reached by valid edges in it (:func:`~robointel.planning._rrt_kernels.revalidate`);
    it leaves its own trees there, whether it found a path or not.
    """
    s, BS = env.scratch, batch_state(env)
    thr, lever = float(st.d_min if thr is None else thr), env.lever
    for k, g in enumerate(goals):
        if attempt == 0 and BE.root_edge_batch(q0, g, Wr, W, True, True, rcap, BS, thr, res, s.out):
            return np.array([q0, g]), k, ""
    n = len(q0)
    cap = int(st.max_nodes)
    nroot = np.array([1, len(goals)], np.int64)
    old = None if carry is None else carry.trees
    if old is not None and old.placed_alike(W, n, cap) and np.array_equal(old.X[0, :, 0], q0) and \
            np.array_equal(old.X[1, :, :len(goals)], goals.T) and float(old.rng[2]) == float(st.rrt_range):
        X, parent, count, rng, win, dom = old.X, old.parent, old.count, old.rng, old.win, old.dom
        if not old.fits(W, Wr, thr, res, n, cap):  # a stricter world: the nodes and edges still valid in it
            R.revalidate(X, parent, count, nroot, W, Wr, rcap, s.T, s.C, s.G, s.out, thr, res, BS, dom)
    else:
        X = np.empty((2, n, cap))  # the trees' nodes joint by joint (the kernel's nearest-neighbour scan)
        parent = np.full((2, cap), -1, np.int64)
        count = nroot.copy()
        X[0, :, 0], X[1, :, :len(goals)] = q0, goals.T
        rng, win = np.full(3, float(st.rrt_range)), np.zeros((2, 2), np.int64)  # each tree's range adapts
        dom = np.full((2, cap), np.inf)  # each node's dynamic domain
    if carry is not None:
        carry.trees = None
    link = np.zeros(2, np.int64)
    R.seed(int(st.seed) + 7 * attempt)
    robot = env.robot
    status, grown, idle, size, why = 0, 0, 0, int(count.sum()), ""
    rdom = float(st.rrt_domain)
    chunk = CHUNK  # (the search does not depend on how its iterations are cut into calls)
    while status != 1 and clock_now() < deadline:
        if status < 0:  # the trees are full: start over from the roots (the random stream goes on)
            grown += int(count.sum())
            count[:] = nroot
            parent[:] = -1
            dom[:] = np.inf
        iters = min(chunk, stall - idle) if 0 < stall and idle < stall else chunk  # (a stall: after ``stall``)
        t0 = time.perf_counter()
        status = R.rrt_connect(X, parent, count, robot.lower, robot.upper, iters, rng, win, W, Wr, nroot, rcap,
                               s.T, s.C, s.G, s.out, thr, lever, res, link, BS, dom, rdom)
        took = time.perf_counter() - t0
        grew, size = int(count.sum()) != size, int(count.sum())
        idle = 0 if grew or status != 0 else idle + iters
        if took < 0.5 * CHUNK_S and chunk < MAX_CHUNK:
            chunk *= 2
        elif took > 2.0 * CHUNK_S and chunk > CHUNK:
            chunk //= 2
        if stall and idle >= stall and (walled is None or int((count - nroot).min()) <= walled):
            why = f"stalled: no node added in {idle} iterations ({grown + size} nodes)"
            break
    if carry is not None:
        carry.trees = SearchTrees.of(X, parent, count, rng, win, dom, W, Wr, thr, res)
    if status != 1:
        return None, -1, why or f"the time budget of {st.time_budget_s:g} s ran out ({grown + int(count.sum())} nodes)"
    a, b = [], []
    i = int(link[0])
    while i >= 0:
        a.append(X[0, :, i])
        i = int(parent[0, i])
    i, last = int(link[1]), 0
    while i >= 0:
        b.append(X[1, :, i])
        last = i
        i = int(parent[1, i])
    return np.array(a[::-1] + b), last, ""
