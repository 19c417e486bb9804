"""Feel the face beside the hole, turn square, push in: the strategy, the person's demonstrations, the
learned rotation and the robot reproducing it where a constant push wedges."""

from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.geometry.rotations import rotation_about
from robointel.learning import insertion as I


def test_face_normal_recovers_a_tilted_plane_despite_lost_contacts():
    rng = np.random.default_rng(3)
    n_true = rotation_about(np.array([0.6, 0.8, 0.0]), np.radians(4.0)) @ np.array([0.0, 0.0, -1.0])
    u = np.cross(n_true, [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n_true, u)
    ph = np.linspace(0, 2 * np.pi, 120)
    P = 2e-3 * (np.outer(np.cos(ph), u) + np.outer(np.sin(ph), v)) + 1e-6 * rng.standard_normal((120, 3))
    P[::15] -= 30e-6 * n_true  # a few samples where the tip lost the face
    n = I.face_normal(P)
    assert np.degrees(np.arccos(np.clip(n @ n_true, -1, 1))) < 0.02
    assert n[2] < 0  # out of the face: against the tool axis


def test_face_normal_and_strategy_reject_bad_input():
    with pytest.raises(InvalidInput):
        I.face_normal(np.zeros((2, 3)))
    with pytest.raises(InvalidInput):
        I.FeltStrategy(centre=0.09, circle_radius=0.01)


def test_strategy_starts_by_moving_aside_and_the_reflex_saturates():
    s = I.FeltStrategy(centre=0.09)
    tw = s(np.zeros(6), np.eye(4))
    assert s.stage == "aside" and tw[0] > 0 and abs(tw[1]) < 1e-12 and np.allclose(tw[3:], 0)
    np.testing.assert_allclose(s.rotation(np.array([1e-3, -2e-3]), np.zeros(6)), [3e-3, -6e-3])
    assert np.isclose(np.linalg.norm(s.rotation(np.array([0.05, 0.05]), np.zeros(6))), s.w_max)


@pytest.fixture(scope="module")
def felt():
    task = I.PegHole()
    scene = I.HDDScene(task)
    rng = np.random.default_rng(0)
    demos = [I.demonstrate_felt(task, rng, scene=scene, name=f"d{i}") for i in range(3)]
    return demos, I.FeltSkill().fit(demos)


def test_the_person_feels_the_face_and_seats(felt):
    demos, _ = felt
    assert all(d.meta["seated"] for d in demos)
    assert max(d.meta["normal_error_rad"] for d in demos) < np.radians(0.1)
    d = demos[0]
    assert set(np.unique(d.labels)) == {0, 1, 2, 3}  # feel = approach, turn = rotation, push = insertion
    assert d.meta["command"].shape == (len(d), 5) and d.meta["tilt_error"].shape == (len(d), 2)


def test_the_skill_learns_the_commanded_rotation_from_the_felt_tilt(felt):
    demos, skill = felt
    assert np.all(skill.r2_ > 0.8), skill.r2_  # held-out demonstrations
    w = skill.predict(np.array([[0.0, 0.0], [0.01, 0.0], [0.0, -0.01]]))
    assert np.linalg.norm(w[0]) < 0.01  # square: no turn
    assert w[1, 0] > 0.01 and w[2, 1] < -0.01  # turns toward the felt normal
    with pytest.raises(InvalidInput):
        I.FeltSkill().fit([])
    pol = skill.policy(0.09)
    assert pol.proprioceptive and pol.rotation_model is not None


def test_the_learned_skill_seats_a_4p5_deg_start_where_a_constant_push_wedges(felt):
    _, skill = felt
    cell = I.RobotCell(I.PegHole())
    lat, tilt = I.random_start_errors(np.random.default_rng(100), 2)[1]  # a tuning start: 4.55 deg, 1.9 mm
    T0 = cell.start_pose(lat, tilt)
    r = cell.insert(skill.policy(cell.tool.tip - cell.tool.radius), T0, seed=1, time_limit=15.0)
    assert r.success, r.reason
    assert r.max_penetration < 0.5 * cell.task.clearance
    push = cell.insert(I.ConstantPush(), T0, seed=1, time_limit=6.0)
    assert not push.success
