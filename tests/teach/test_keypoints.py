"""Key points, blended Cartesian trajectory and joint velocity reference (Figs. 3.11-3.12)."""
import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.teach.keypoints import blended_trajectory, extract_keypoints, joint_velocity_reference, rdp_indices


def _guided_path(rng):
    """An L-shaped guided path with a pause at the corner, hand tremor noise."""
    corners = np.array([[0.5, -0.2, 0.4], [0.5, 0.1, 0.4], [0.5, 0.1, 0.6]])
    segs, ts, t0 = [], [], 0.0
    for a, b in zip(corners[:-1], corners[1:]):
        n = 300
        s = 0.5 - 0.5 * np.cos(np.linspace(0, np.pi, n))
        segs.append(a + np.outer(s, b - a)); ts.append(t0 + np.linspace(0, 1.5, n)); t0 += 1.5 + 1e-3
        segs.append(np.repeat(b[None], 200, 0)); ts.append(t0 + np.linspace(0, 1.0, 200)); t0 += 1.0 + 1e-3
    P = np.concatenate(segs) + rng.normal(0, 2e-4, (sum(map(len, segs)), 3))
    return np.concatenate(ts), P, corners


def test_keypoints_find_corners_and_dwells():
    t, P, corners = _guided_path(np.random.default_rng(0))
    k = extract_keypoints(t, P, tolerance=0.01)
    assert k[0] == 0 and k[-1] == len(t) - 1
    kp = P[k]
    for c in corners:  # every true corner has a key point within 1 cm
        assert np.min(np.linalg.norm(kp - c, axis=1)) < 0.01
    assert len(k) <= 5  # not the noise


def test_rdp_straight_line_keeps_ends():
    P = np.c_[np.linspace(0, 1, 50), np.zeros(50), np.zeros(50)]
    np.testing.assert_array_equal(rdp_indices(P, 1e-6), [0, 49])


@pytest.mark.parametrize("kind", ["cubic", "quintic"])
def test_blended_trajectory_properties(kind):
    pts = np.array([[0.0, 0, 0], [0.3, 0, 0], [0.3, 0.2, 0], [0.3, 0.2, 0.25]])
    tr = blended_trajectory(pts, speed=0.2, blend_time=0.3, kind=kind)
    t = np.linspace(0, tr.duration, 20001)
    p, v, a = tr(t)
    np.testing.assert_allclose(p[0], pts[0], atol=1e-12)
    np.testing.assert_allclose(p[-1], pts[-1], atol=1e-12)
    np.testing.assert_allclose(v[[0, -1]], 0, atol=1e-12)
    # position and velocity continuous, velocity is the derivative of position
    dt = t[1] - t[0]
    assert np.max(np.linalg.norm(np.diff(p, axis=0), axis=1)) < 0.25 * dt * 1.01 + 1e-9
    np.testing.assert_allclose(np.gradient(p, t, axis=0)[1:-1], v[1:-1], atol=2e-3)
    ok = np.ones(len(t), bool)
    if kind == "cubic":  # acceleration jumps at blend ends: compare away from them
        for tk, tau in zip(tr.times, tr.blend):
            for e in (tk - tau / 2, tk + tau / 2):
                ok &= np.abs(t - e) > 3 * dt
    np.testing.assert_allclose(np.gradient(v, t, axis=0)[ok][5:-5], a[ok][5:-5], atol=0.05 * np.abs(a).max() + 1e-6)
    assert np.max(np.linalg.norm(v, axis=1)) <= 0.2 * (1 + 1e-9) + 1e-12
    # passes close to every interior key point
    for c in pts[1:-1]:
        assert np.min(np.linalg.norm(p - c, axis=1)) <= 0.3 * 0.2 * np.sqrt(2) / 8 + 1e-6
    if kind == "quintic":  # acceleration continuous
        assert np.max(np.linalg.norm(np.diff(a, axis=0), axis=1)) < 0.01


def test_blended_trajectory_bad_input():
    with pytest.raises(InvalidInput):
        blended_trajectory([[0, 0, 0], [0, 0, 0]])
    with pytest.raises(InvalidInput):
        blended_trajectory([[0, 0, 0], [1, 0, 0]], kind="septic")


def test_joint_velocity_reference_tracks(lrmate):
    q0 = np.array([0.0, 0.1, -0.2, 0.0, -1.2, 0.0])
    p0 = lrmate.fk(q0)[:3, 3]
    pts = p0 + np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0], [0.1, 0.1, -0.1]])
    tr = blended_trajectory(pts, speed=0.2, blend_time=0.2)
    t, Q, dQ = joint_velocity_reference(lrmate, q0, tr, dt=0.002)
    pd, _, _ = tr(t)
    err = np.array([np.linalg.norm(lrmate.fk(q)[:3, 3] - p) for q, p in zip(Q[::10], pd[::10])])
    assert err.max() < 2e-3
    np.testing.assert_allclose(lrmate.fk(Q[-1])[:3, :3], lrmate.fk(q0)[:3, :3], atol=1e-3)


def test_reproduce_path_with_orientations(lrmate):
    """A guided path (kinematic) whose tool turns: the reproduction passes the key points with
    their orientations and stays within the tolerance of the guided path."""
    from scipy.spatial.transform import Rotation

    from robointel.teach.keypoints import orientation_reference, reproduce_path

    q0 = np.array([0.0, 0.1, -0.2, 0.0, -1.2, 0.0])
    T0 = lrmate.fk(q0)
    t = np.linspace(0, 3, 1501)
    s = np.clip(t / 1.5, 0, 1)
    s2 = np.clip(t / 1.5 - 1, 0, 1)
    P = T0[:3, 3] + np.outer(s, [0.12, 0, 0]) + np.outer(s2, [0, 0.1, 0])
    R = np.array([T0[:3, :3] @ Rotation.from_rotvec([0, 0, 0.4 * a]).as_matrix() for a in s2])
    rep = reproduce_path(lrmate, t, P, q0, rotations=R, tolerance=0.005, speed=0.1, blend_time=0.3)
    assert len(rep.keypoints) == 3
    assert rep.path_error < 0.006
    Rd = orientation_reference(rep.cartesian, R[rep.keypoints], [0.0, rep.cartesian.duration])
    np.testing.assert_allclose(Rd[-1], R[-1], atol=1e-9)
    np.testing.assert_allclose(lrmate.fk(rep.trajectory.q[-1])[:3, :3], R[-1], atol=2e-3)
    np.testing.assert_allclose(lrmate.fk(rep.trajectory.q[-1])[:3, 3], P[-1], atol=1e-3)
