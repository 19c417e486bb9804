"""The exact self-collision geometry: pair distances exact below the threshold, lower bounds above; levers bound."""
from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
import pytest

from robointel.planning.exact_geometry import contact_distance
from robointel.planning.exact_self import self_geometry
from robointel.robot import Robot
from robointel.robot.srdf import disabled_pairs


@pytest.fixture(scope="module")
def ur5_self(shared_data):
    root = shared_data("mbm", "ur5")
    robot = Robot.load(root / "ur5.urdf")
    return self_geometry(robot, disabled_pairs(root / "ur5.srdf", robot.link_names))


def _mesh_distance(sg, q: np.ndarray, p: int) -> float:
    robot = sg.robot
    pin.framesForwardKinematics(robot.model, robot.data, q)
    T = []
    for i in sg.pairs[p]:
        s = sg.solids[i]
        M = robot.data.oMf[s.frame].homogeneous @ s.placement
        T.append(coal.Transform3s(M[:3, :3], M[:3, 3]))
    a, b = (sg.solids[i] for i in sg.pairs[p])
    return contact_distance(a.geom, T[0], b.geom, T[1], coal.DistanceRequest())


def test_pair_distances_exact_below_the_threshold_lower_bounds_above(ur5_self):
    sg = ur5_self
    rng = np.random.default_rng(4)
    close = [p for p in range(len(sg.pairs)) if {sg.solids[i].link for i in sg.pairs[p]}
             in ({"forearm_link", "wrist_2_link"}, {"base_link", "upper_arm_link"})]
    seen_below = 0
    for q in sg.robot.random_configuration(rng, 40):
        which = np.array(close + [int(rng.integers(len(sg.pairs)))])
        for thresh in (0.0, 0.015):
            got = sg.pair_distances(q, which, thresh=thresh)
            for p, d in zip(which, got):
                ref = _mesh_distance(sg, q, int(p))
                if ref < thresh:
                    assert d < thresh and (ref < 0) == (d < 0)
                    if ref >= 0:
                        assert abs(d - ref) <= 1e-9
                    seen_below += 1
                else:
                    assert thresh <= d <= ref + 1e-9
    assert seen_below >= 3


def test_solid_levers_bound_every_vertex_displacement(ur5_self):
    sg = ur5_self
    robot = sg.robot
    lev = sg._levers()
    rng = np.random.default_rng(5)
    pts = [s.points() for s in sg.solids]
    worst = 0.0
    for _ in range(40):
        q0 = robot.random_configuration(rng)
        dq = rng.normal(0.0, 0.03, robot.nq)
        place = []
        for q in (q0, q0 + dq):
            pin.framesForwardKinematics(robot.model, robot.data, q)
            place.append([robot.data.oMf[s.frame].homogeneous @ s.placement for s in sg.solids])
        for i, (v, a, b) in enumerate(zip(pts, *place)):
            moved = np.linalg.norm(v @ (a[:3, :3] - b[:3, :3]).T + (a[:3, 3] - b[:3, 3]), axis=1).max()
            bound = float(lev[i] @ np.abs(dq))
            if bound > 0:
                worst = max(worst, moved / bound)
    assert 0.3 < worst <= 1.0  # a bound, and not a vacuous one


def test_pair_levers_bound_every_distance_change(ur5_self):
    """sum_k pair_lever[p, k] |dq_k| bounds how far each pair's mesh distance moves (slabs, turned-back bound)."""
    sg = ur5_self
    robot = sg.robot
    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(12):
        q0 = robot.random_configuration(rng)
        dq = rng.normal(0.0, 0.05, robot.nq)
        for p in range(len(sg.pairs)):
            bound = float(sg.pair_lever[p] @ np.abs(dq))
            change = abs(_mesh_distance(sg, q0 + dq, p) - _mesh_distance(sg, q0, p))
            assert change <= bound + 1e-9, (p, change, bound)
            if bound > 1e-3:
                worst = max(worst, change / bound)
    assert worst > 0.3  # not a vacuous bound


def test_self_check_agrees_with_every_sample_measured(ur5_self, shared_data):
    """The travel-bounded schedule finds a contact where measuring every sample does (or the motion into it)."""
    from robointel.planning import Environment
    from robointel.planning.hybrid_check import self_check
    from robointel.planning.motion_check import DenseCheck
    from robointel.planning.polyline_timing import polyline_timing

    sg = ur5_self
    robot = sg.robot
    env = Environment(robot, [], srdf=shared_data("mbm", "ur5") / "ur5.srdf")
    rng = np.random.default_rng(6)
    verdicts = []
    for _ in range(6):
        path = robot.random_configuration(rng, 2)
        tr = polyline_timing(path, 4 * robot.velocity_limit, 8 * robot.velocity_limit, dt=2e-3)
        got = self_check(env, tr, DenseCheck(True, "", "", 1.0, len(tr.t)), dt=2e-3)
        hit = next((k for k, q in enumerate(tr.q) if sg.clearance(q, cap=0.05, thresh=0.0)[0] < 0.0), None)
        assert got.ok == (hit is None), (got.reason, hit)
        if hit is not None:  # the first sample in contact, or the motion into it refused next to a sample before
            assert f"at t = {tr.t[hit]:.3f} s" in got.reason or any(
                f"next to t = {tr.t[j]:.3f} s" in got.reason for j in range(max(hit - 2, 0), hit)), got.reason
        verdicts.append(got.ok)
    assert 0 < sum(verdicts) < len(verdicts)


def test_tree_node_pairs_bound_every_solid_pair_below(ur5_self):
    """A node pair's hull distance is at most each checked solid pair's below it; its lever at least theirs."""
    sg = ur5_self
    tree = sg.tree
    below: dict[int, set[int]] = {}

    def leaves(k: int) -> set[int]:
        if k not in below:
            below[k] = {int(tree.leaf[k])} if tree.leaf[k] >= 0 else set().union(*(leaves(int(c))
                                                                                   for c in tree.children[k]))
        return below[k]

    rng = np.random.default_rng(8)
    inner = np.flatnonzero(tree.leaf < 0)
    assert len(tree.roots) > 0 and len(inner) > 0
    for q in sg.robot.random_configuration(rng, 5):
        d = tree.distances(q, inner, thresh=0.0)
        for k, dk in zip(inner, d):
            ps = sorted(leaves(int(k)))
            assert np.all(tree.lever[k] >= sg.pair_lever[ps].max(axis=0) - 1e-12)
            assert dk <= min(_mesh_distance(sg, q, p) for p in ps) + 1e-7
    assert set().union(*(leaves(int(r)) for r in tree.roots)) == set(range(len(sg.pairs)))


def test_tree_closest_below_agrees_with_every_pair(ur5_self):
    """The tree walk finds a pair below the threshold exactly when the pair-by-pair clearance does."""
    sg = ur5_self
    rng = np.random.default_rng(9)
    found = 0
    for q in sg.robot.random_configuration(rng, 30):
        for thr in (0.0, 0.02):
            ref, _, _ = sg.clearance(q, cap=thr + 0.05, thresh=thr)
            got = sg.tree.closest_below(q, thr)
            assert (got is not None) == (ref < thr)
            if got is not None:
                assert abs(got[0] - ref) <= 1e-9
                found += 1
    assert found >= 3


def test_the_schedule_front_and_the_joints_travel():
    from robointel.planning.hybrid_check import _front, _travel

    due = np.array([40, 7, 300, 9, 135, 136, 7000], np.int64)
    out = np.empty(len(due), np.int64)
    k, c = _front(due, 6, 128, out)  # the last entry is past m: not looked at
    assert (k, list(out[:c])) == (7, [0, 1, 3, 4])  # due by 7 + 128
    Q = np.random.default_rng(3).normal(size=(50, 4))
    Cq = _travel(Q)
    np.testing.assert_allclose(Cq[1:], np.cumsum(np.abs(np.diff(Q, axis=0)), axis=0), rtol=1e-14, atol=1e-14)
    assert not Cq[0].any()
