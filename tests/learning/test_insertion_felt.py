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


def _circle(n_face, centre, radius=1.5e-3, n=150):
    u = np.cross(n_face, [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n_face, u)
    ph = np.linspace(0, 2 * np.pi, n)
    return centre + radius * (np.outer(np.cos(ph), u) + np.outer(np.sin(ph), v))


def test_plane_fit_quality_tells_a_face_from_an_edge():
    rng = np.random.default_rng(4)
    s = I.FeltStrategy(centre=0.09)
    flat = _circle(np.array([0.0, 0.0, -1.0]), np.zeros(3)) + 1e-6 * rng.standard_normal((150, 3))
    fit = I.fit_face(flat)
    assert s.trusted(fit) and fit.rms < 2e-6 and fit.kept > 0.9 and fit.spread > 1e-3
    # the ball rolling over the face's edge at x = 0.5 mm: its centre drops on a circle of the ball's radius
    r = 0.0127
    edge = flat.copy()
    beyond = np.clip(edge[:, 0] - 0.5e-3, 0, None)
    edge[:, 2] += r - np.sqrt(r ** 2 - beyond ** 2)  # down is +z in the tool frame
    assert not s.trusted(I.fit_face(edge))
    line = np.column_stack([np.linspace(-1e-3, 1e-3, 50), np.zeros(50), np.zeros(50)])
    line += 1e-9 * rng.standard_normal((50, 3))
    assert not s.trusted(I.fit_face(line))  # no spread: no plane


def test_strategy_holds_the_aside_target_and_feels_again_across_the_hole_after_a_bad_fit():
    s = I.FeltStrategy(centre=0.09)
    s(np.zeros(6), np.eye(4))  # the start
    T = np.eye(4)
    T[0, 3] = s.aside + 4e-3  # the arm ran 4 mm past the aside target
    s.stage = "touch"
    tw = s(np.zeros(6), T)
    assert tw[0] < 0 and tw[2] > 0  # pulled back while going down
    s.stage = "feel"
    s._points = list(np.array([[s.aside, 0.0, 0.0]]) + 1e-4 * np.random.default_rng(0).standard_normal((40, 3)))
    s._felt(np.array([s.aside, 0.0, 0.09]))
    assert s.stage == "cross" and s.normal is None and len(s.fits) == 1
    tw = s(np.zeros(6), T)
    assert tw[0] < 0  # over the hole to the other side
    s.stage = "feel"
    s._points = list(_circle(np.array([0.0, 0.0, -1.0]), np.array([-s.aside, 0.0, 0.09])))
    s._felt(np.array([-s.aside, 0.0, 0.09]))
    assert s.stage == "lift" and np.allclose(s.normal, [0.0, 0.0, -1.0]) and len(s.fits) == 2


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
