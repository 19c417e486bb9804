"""benchmarks/_mbm_checker: the independent exact checker of MBM trajectories (coal on the URDF meshes)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from _mbm_checker import MBMChecker  # noqa: E402


@pytest.fixture(scope="module")
def setup(shared_data):
    root = shared_data("mbm", "ur5")
    checker = MBMChecker(root / "ur5.urdf", root / "ur5.srdf")
    raw = json.loads((root / "problems.json").read_text())["problems"]
    return checker, raw


def _valid(raw, family, k=0):
    return [p for p in raw[family] if p["valid"]][k]


def test_self_pairs_honour_srdf_and_adjacency(setup):
    c, _ = setup
    names = {frozenset((c.links[a], c.links[b])) for a, b in c.self_pairs}
    assert frozenset(("base_link", "upper_arm_link")) in names  # non-adjacent, not disabled
    assert frozenset(("shoulder_link", "upper_arm_link")) not in names  # adjacent
    assert frozenset(("wrist_1_link", "wrist_3_link")) not in names  # SRDF-disabled
    assert frozenset(("wrist_1_link", "fts_robotside")) in names


def test_valid_endpoints_are_collision_free(setup):
    c, raw = setup
    n = 0
    for family in raw:
        for k in range(3):
            p = _valid(raw, family, k)
            for q in [p["start"], *p["goals"]]:
                v = c.check_configuration(np.asarray(q), p)
                assert not v.collision and v.min_clearance > 0, (family, p["index"], v)
                n += 1
    assert n == 42


def test_hand_made_collisions_are_caught(setup):
    c, raw = setup
    p = _valid(raw, "cage")
    v = c.check_configuration(np.array([0.0, -1.57, 3.1, 0.0, 0.0, 0.0]), p)  # elbow folded onto the shoulder
    assert v.collision and set(v.pair) == {"shoulder_link", "forearm_link"}
    v = c.check_configuration(np.zeros(6), p)  # stretched out through the cage wall
    assert v.collision and v.pair[0] == "upper_arm_link" and v.pair[1].startswith("side_")
    # a small ball placed between the finger tips of the goal configuration
    q = np.asarray(p["goals"][0])
    import pinocchio as pin

    pin.forwardKinematics(c.model, c.data, q)
    pin.updateFramePlacements(c.model, c.data)
    tip = c.data.oMf[c.model.getFrameId("robotiq_85_left_finger_tip_link")].translation
    ball = {"sphere": [{"name": "ball", "position": tip.tolist(), "radius": 0.01}], "box": [], "cylinder": [],
            "start": p["start"], "goals": p["goals"]}
    v = c.check_configuration(q, ball)
    assert v.collision and v.pair[1] == "ball" and "robotiq" in v.pair[0]


def test_pair_skipping_gives_the_brute_force_minimum(setup):
    c, raw = setup
    p = _valid(raw, "box")
    s, g = np.asarray(p["start"]), np.asarray(p["goals"][0])
    Q = s + (g - s) * np.linspace(0.55, 0.75, 40)[:, None]  # a stretch of the straight line, 40 samples
    brute = min(c.check_configuration(q, p).min_clearance for q in Q)
    v = c.check_path(Q, p)
    assert not v.collision
    assert v.min_clearance == pytest.approx(brute, abs=1e-9)
    assert v.evaluations < 40 * (len(c.self_pairs) + len(c.geom.geometryObjects) * 7)


def test_straight_line_through_the_box_collides_and_limits_are_checked(setup):
    c, raw = setup
    p = _valid(raw, "box")
    s, g = np.asarray(p["start"]), np.asarray(p["goals"][0])
    T = np.abs(g - s).max() / c.vmax[0]
    v = c.check_trajectory([0.0, T], [s, g], p)  # joint-space straight line at full speed
    assert v.collision and v.t_collision is not None and 0 < v.t_collision < T
    assert v.reaches_goal
    v = c.check_trajectory([0.0, T / 2], [s, g], p)  # twice too fast
    assert v.limit_violation is not None and "velocity" in v.limit_violation
    v = c.check_trajectory([0.0, T], [s, s + 0.1], p)
    assert not v.reaches_goal
