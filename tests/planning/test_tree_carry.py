"""Trees carried from one search to the next.

The search in the mesh-covering spheres gives way to one in the spheres as given (smaller radii, same
centres): every node and edge of the first search's trees is valid there, so the second goes on from
them as they are. In a world with a radius larger (spheres grown after a mesh refusal), another
clearance or a finer resolution, the next search goes on from the nodes still free and reached by
edges still valid there.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from robointel.io.mbm import load_mbm_problems
from robointel.planning import Environment, MotionSettings
from robointel.planning import _batch_edges as BE
from robointel.planning import _collision_kernels as K
from robointel.planning.budget_clock import now as clock_now
from robointel.planning.motion import _goal_set, _warmup
from robointel.planning.tree_search import SearchTrees, TreeCarry, batch_state, search
from robointel.robot import Robot


@pytest.fixture(scope="module")
def cage(shared_data, tmp_path_factory):
    root = shared_data("mbm", "ur5")
    robot = Robot.load(root / "ur5.urdf")
    data = json.loads((root / "problems.json").read_text())
    one = tmp_path_factory.mktemp("carry") / "one.json"  # the reader on this problem alone
    one.write_text(json.dumps({**data, "problems": {"cage": [r for r in data["problems"]["cage"] if r["index"] == 4]}}))
    p = load_mbm_problems(one).select(index=4)[0]
    env = Environment(robot, p.obstacles, srdf=root / "ur5.srdf", spheres=root / "ur5_spherized.urdf")
    _warmup(env)
    return env, np.asarray(p.start, float), _goal_set(robot, p.goals, 0)


def _failed_search(cage, seed):
    """A search in the covering spheres cut short so that it finds no path: (env, q0, goals, settings, world,
    why, carry holding its trees)."""
    env, q0, goals = cage
    st = MotionSettings(d_min=0.001, seed=seed)
    env.use("cover")
    W = env.world
    for budget in (0.05, 0.03, 0.02, 0.01, 0.005):
        carry = TreeCarry()
        path, _, why = search(env, q0, goals, st, 0.02, clock_now() + budget, W, W, attempt=1, thr=0.001,
                              carry=carry)
        if path is None and carry.trees.count.sum() > len(goals) + 1:  # no path, and the trees grew
            return env, q0, goals, st, W, why, carry
    pytest.skip("every short search found a path or grew no tree")


def test_the_fitted_search_goes_on_from_the_covering_search_trees(cage):
    env, q0, goals, st, Wc, why, carry = _failed_search(cage, seed=3)
    trees = carry.trees
    assert trees is not None and why.startswith("the time budget")
    count = trees.count.copy()
    env.use("fitted")
    Wf = env.world
    assert trees.fits(Wf, Wf, 0.001, 0.02, len(q0), st.max_nodes)
    # the property the carry rests on: every node free and every edge valid in the fitted spheres
    s, BS = env.scratch, batch_state(env)
    X, parent = trees.X, trees.parent
    for t in range(2):
        for i in range(int(count[t])):
            q = X[t, :, i]
            assert env.clearance(q, cap=0.1) >= 0.001 - 1e-9
            if parent[t, i] >= 0:
                a = np.ascontiguousarray(X[t, :, parent[t, i]])
                assert BE.root_edge_batch(a, np.ascontiguousarray(q), Wf, Wf, False, False, np.inf, BS, 0.001, 0.02,
                                          s.out)
    # the next search starts from them: its trees hold at least as many nodes (it reports them on failure)
    path, _, why2 = search(env, q0, goals, st, 0.02, clock_now(), Wf, Wf, attempt=2, thr=0.001, carry=carry)
    assert path is None and f"({int(count.sum())} nodes)" in why2
    assert carry.trees is not None and carry.trees.X is X


def _assert_valid(env, trees, W, thr, res):
    """Every node of ``trees`` free and every edge valid in ``W`` (the property a carry rests on)."""
    s, BS = env.scratch, batch_state(env)
    X, parent = trees.X, trees.parent
    for t in range(2):
        for i in range(int(trees.count[t])):
            q = np.ascontiguousarray(X[t, :, i])
            if parent[t, i] >= 0:
                assert K.config_valid(q, W, s.T, s.C, s.G, s.out, thr)
                a = np.ascontiguousarray(X[t, :, parent[t, i]])
                assert parent[t, i] < i and BE.root_edge_batch(a, q, W, W, False, False, np.inf, BS, thr, res, s.out)


def test_a_stricter_world_keeps_the_nodes_still_valid(cage):
    env, q0, goals, st, Wc, _, carry = _failed_search(cage, seed=5)
    trees = carry.trees
    assert isinstance(trees, SearchTrees)
    n, cap = len(q0), st.max_nodes
    assert trees.fits(Wc, Wc, 0.001, 0.02, n, cap)
    assert trees.fits(Wc, Wc, 0.001, 0.04, n, cap)  # a coarser resolution: the proofs hold
    assert not trees.fits(Wc, Wc, 0.001, 0.005, n, cap)  # finer: they do not
    assert not trees.fits(Wc, Wc, 0.002, 0.02, n, cap)  # another clearance
    before = int(trees.count.sum())
    env.set_self_blend(1.0)  # the self-collision spheres grown toward the covering ones
    try:
        Wg = env.world_cover
        if np.all(Wg[21] <= Wc[21]):
            pytest.skip("the self-collision spheres did not grow")
        assert not trees.fits(Wg, Wg, 0.001, 0.02, n, cap) and trees.placed_alike(Wg, n, cap)
        path, _, why = search(env, q0, goals, st, 0.02, clock_now(), Wg, Wg, attempt=2, thr=0.001, carry=carry)
        assert path is None
        kept = carry.trees
        assert kept.X is trees.X and len(goals) + 1 <= int(kept.count.sum()) <= before
        assert f"({int(kept.count.sum())} nodes)" in why
        _assert_valid(env, kept, Wg, 0.001, 0.02)
    finally:
        env.set_self_blend(0.0)
        env.use("cover")


def test_a_finer_resolution_keeps_the_edges_that_pass_it(cage):
    env, q0, goals, st, Wc, _, carry = _failed_search(cage, seed=3)
    before = int(carry.trees.count.sum())
    path, _, why = search(env, q0, goals, st, 0.004, clock_now(), Wc, Wc, attempt=2, thr=0.002, carry=carry)
    assert path is None and len(goals) + 1 <= int(carry.trees.count.sum()) <= before
    _assert_valid(env, carry.trees, Wc, 0.002, 0.004)


def test_revalidate_drops_a_failing_node_with_its_subtree(cage):
    """Trees grown in the spheres as given, kept in the covering ones: the kernel keeps exactly the nodes whose
    parent is kept, which are free and whose edge from the parent is valid (checked here one by one)."""
    from robointel.planning import _rrt_kernels as R

    env, q0, goals = cage
    st = MotionSettings(d_min=0.001, seed=4)
    env.use("fitted")
    Wf = env.world
    carry = TreeCarry()
    path, _, _ = search(env, q0, goals, st, 0.02, clock_now() + 0.03, Wf, Wf, attempt=1, thr=0.001, carry=carry)
    env.use("cover")
    Wc, s, BS = env.world, env.scratch, batch_state(env)
    trees = carry.trees
    X, parent, count = trees.X.copy(), trees.parent.copy(), trees.count.copy()
    nroot = np.array([1, len(goals)], np.int64)
    want, dropped = [], 0
    for t in range(2):
        new = {i: i for i in range(nroot[t])}
        kept = []
        for i in range(nroot[t], int(count[t])):
            p = int(parent[t, i])
            q, a = np.ascontiguousarray(X[t, :, i]), np.ascontiguousarray(X[t, :, p])
            if p in new and K.config_valid(q, Wc, s.T, s.C, s.G, s.out, 0.001) and BE.root_edge_batch(
                    a, q, Wc, Wc, p < nroot[t], False, np.inf, BS, 0.001, 0.02, s.out):
                new[i] = int(nroot[t]) + len(kept)
                kept.append((q, new[p]))
            else:
                dropped += 1
        want.append(kept)
    assert dropped > 0, "no node of the fitted trees collides in the covering spheres"
    got = R.revalidate(X, parent, count, nroot, Wc, Wc, np.inf, s.T, s.C, s.G, s.out, 0.001, 0.02, BS,
                       trees.dom.copy())
    assert got == dropped
    for t in range(2):
        assert count[t] == nroot[t] + len(want[t])
        for m, (q, p) in enumerate(want[t], start=int(nroot[t])):
            assert np.array_equal(X[t, :, m], q) and parent[t, m] == p
    kept = SearchTrees(X, parent, count, trees.rng, trees.win, trees.dom, Wc, (), 0.001, 0.02)
    _assert_valid(env, kept, Wc, 0.001, 0.02)


def test_the_search_does_not_depend_on_how_its_iterations_are_cut_into_calls(cage, monkeypatch):
    import robointel.planning.tree_search as TS

    env, q0, goals = cage
    st = MotionSettings(d_min=0.001, seed=5)
    env.use("cover")
    W = env.world
    kernel, calls = TS.R.rrt_connect, []

    def counted(*args):
        calls[-1] += 1
        return kernel(*args)

    monkeypatch.setattr(TS.R, "rrt_connect", counted)
    found = []
    for most in (TS.CHUNK, TS.MAX_CHUNK):  # calls of 32 iterations each, then calls growing to 1,024
        monkeypatch.setattr(TS, "MAX_CHUNK", most)
        calls.append(0)
        path, gi, why = search(env, q0, goals, st, 0.02, clock_now() + 30.0, W, W, attempt=1, thr=0.001)
        assert path is not None, why
        found.append((path, gi))
    assert calls[0] > calls[1] >= 1 and calls[0] > 2  # cut differently ...
    assert found[0][1] == found[1][1] and np.array_equal(found[0][0], found[1][0])  # ... the same path
