"""The motion planner's global search: RRT-Connect from the start to a goal set, and the re-check of its path.

:func:`search` runs the compiled kernel (:mod:`robointel.planning._rrt_kernels`) in chunks of
iterations between which it watches the clock; :func:`path_valid` re-checks a found path's edges
at the fine resolution.
"""
from __future__ import annotations

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
                  W, W, count, 0.2, s.T, s.C, s.G, s.out, 0.0, env.lever, 0.01, np.zeros(2, np.int64), batch_state(env))


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


#: iterations per call of the compiled search (the clock is read between calls)
CHUNK = 32


def search(env: Environment, q0: np.ndarray, goals: np.ndarray, st: MotionSettings, res: float,
           deadline: float, W: tuple, Wr: tuple, attempt: int = 0,
           thr: float | None = None, rcap: float = float("inf"),
           stall: int = 0, walled: int | None = None) -> tuple[np.ndarray | None, int, str]:
    """RRT-Connect from q0 to the goal set (a direct edge first): (path, goal index, why not).

    Nodes and edges are checked in ``W``, edges leaving the start or a goal in ``Wr`` for their
    first ``rcap`` rad (max |dq|) and in ``W`` beyond. ``stall`` > 0: the search also gives up
    when neither tree has gained a node in its last ``stall`` iterations (a root walled in by the
    spheres of ``W``; the caller has another model to try), its reason then starting ``"stalled"``;
    with ``walled``, only while one of the trees holds at most that many nodes besides its roots.
    """
    s, BS = env.scratch, batch_state(env)
    thr, lever = float(st.d_min if thr is None else thr), env.lever
    for k, g in enumerate(goals):
        if attempt == 0 and BE.root_edge_batch(q0, g, Wr, W, True, True, rcap, BS, thr, res, s.out):
            return np.array([q0, g]), k, ""
    n = len(q0)
    cap = int(st.max_nodes)
    X = np.empty((2, n, cap))  # the trees' nodes joint by joint (the kernel's nearest-neighbour scan)
    parent = np.full((2, cap), -1, np.int64)
    count = np.array([1, len(goals)], np.int64)
    nroot = count.copy()
    X[0, :, 0], X[1, :, :len(goals)] = q0, goals.T
    link = np.zeros(2, np.int64)
    rng, win = np.full(3, float(st.rrt_range)), np.zeros((2, 2), np.int64)  # each tree's range adapts
    R.seed(int(st.seed) + 7 * attempt)
    robot = env.robot
    status, grown, idle, size = 0, 0, 0, int(count.sum())
    while status != 1 and clock_now() < deadline:
        if status < 0:  # the trees are full: start over from the roots (the random stream goes on)
            grown += int(count.sum())
            count[:] = nroot
            parent[:] = -1
        status = R.rrt_connect(X, parent, count, robot.lower, robot.upper, CHUNK, rng, win, W, Wr, nroot, rcap,
                               s.T, s.C, s.G, s.out, thr, lever, res, link, BS)
        grew, size = int(count.sum()) != size, int(count.sum())
        idle = 0 if grew or status != 0 else idle + CHUNK
        if stall and idle >= stall and (walled is None or int((count - nroot).min()) <= walled):
            return None, -1, f"stalled: no node added in {idle} iterations ({grown + size} nodes)"
    if status != 1:
        return None, -1, f"the time budget of {st.time_budget_s:g} s ran out ({grown + int(count.sum())} nodes)"
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
