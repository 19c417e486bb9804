"""Classification (6.17)-(6.19): footprint-aligned registration starts (minimum-area rectangle) and the
normal-obliqueness shape term of the score."""
import numpy as np
import pytest
import trimesh

from robointel.errors import InvalidInput
from robointel.learning.grasp.classify import (
    Template,
    classify,
    fit_template,
    footprint_rectangle,
    normal_obliqueness,
    yaw_matrix,
)


def _visible(mesh: trimesh.Trimesh, n: int, seed: int, yaw: float, at=(0.5, 0.1, 0.0)) -> np.ndarray:
    """``n`` surface points of ``mesh`` (resting on z = 0) turned by ``yaw`` and moved to ``at``, without
    the underside (the two cameras look down from opposite sides: the table hides the bottom)."""
    P, f = trimesh.sample.sample_surface_even(mesh, 2 * n, seed=seed)
    P = np.asarray(P)[mesh.face_normals[f][:, 2] > -0.5] @ yaw_matrix(yaw).T
    return P[np.random.default_rng(seed).permutation(len(P))[:n]] + np.asarray(at)


def _box(ex, ey, ez):
    m = trimesh.creation.box(extents=[ex, ey, ez])
    m.apply_translation([0, 0, ez / 2])
    return m


@pytest.mark.parametrize("yaw", [0.0, 0.3, np.pi / 4, 1.2, 2.9])
def test_footprint_rectangle_recovers_heading_and_extents(yaw):
    P = np.asarray(trimesh.sample.sample_surface_even(_box(0.10, 0.04, 0.06), 1500, seed=1)[0])
    P = P @ yaw_matrix(yaw).T + [0.4, -0.2, 0.0]
    angle, ext = footprint_rectangle(P, percentile=0.0)
    assert 0.0 <= angle < np.pi / 2
    d = np.mod(angle - yaw, np.pi / 2)
    assert min(d, np.pi / 2 - d) < np.radians(2.0)
    # the long side lies along the rectangle's first axis when the heading is the box's own (mod pi)
    assert sorted(ext[:2]) == pytest.approx([0.04, 0.10], abs=0.004)
    assert ext[2] == pytest.approx(0.06, abs=0.002)


def test_footprint_rectangle_degenerate_and_bad_input():
    line = np.c_[np.linspace(0, 0.1, 20), np.zeros(20), np.linspace(0, 0.05, 20)]  # collinear footprint
    angle, ext = footprint_rectangle(line, percentile=0.0)
    assert np.isfinite(angle) and np.all(np.isfinite(ext))
    with pytest.raises(InvalidInput):
        footprint_rectangle(np.zeros((5, 2)))


def test_footprint_starts_register_a_diagonal_square_block():
    """A square block (91 x 90 x 206 mm, like YCB 036_wood_block) at 45 degrees against a thin box
    template (49 x 94 x 176 mm, like the sugar box): from the yaw grid alone the template's
    world-axis extents are matched to the diagonal's, and the fit stays in a worse local minimum; the
    footprint-aligned starts lower the score, and the block is read as a box, not a can."""
    box_t = Template("thin box", "box", np.asarray(trimesh.sample.sample_surface_even(_box(0.049, 0.094, 0.176),
                                                                                     800, seed=0)[0]))
    cyl = trimesh.creation.cylinder(radius=0.034, height=0.102, sections=48)
    cyl.apply_translation([0, 0, 0.051])
    can_t = Template("cylinder", "can", np.asarray(trimesh.sample.sample_surface_even(cyl, 800, seed=0)[0]))
    X = _visible(_box(0.091, 0.090, 0.206), 1200, seed=3, yaw=np.pi / 4 + 0.05)
    grid = fit_template(X, box_t, footprint=False)
    fp = fit_template(X, box_t, footprint=True)
    assert fp.residual < 0.95 * grid.residual
    c = classify(X, [can_t, box_t])
    assert c.category == "box"
    # the fitted template sits on the target, not beside it
    assert np.allclose(c.best.warp(box_t.points).mean(0)[:2], X.mean(0)[:2], atol=0.02)


def test_footprint_starts_only_in_the_classification_fit():
    """The table-resting and isotropic fits (used by the planner for grasp transfer) are unchanged by
    the ``footprint`` option."""
    t = Template("thin box", "box", np.asarray(trimesh.sample.sample_surface_even(_box(0.049, 0.094, 0.176),
                                                                                 600, seed=0)[0]))
    X = _visible(_box(0.091, 0.090, 0.206), 600, seed=4, yaw=0.7)
    for kw in ({"rest_z": 0.0, "starts": 1}, {"anisotropic": 0.0, "starts": 1}):
        a = fit_template(X, t, footprint=True, **kw)
        b = fit_template(X, t, footprint=False, **kw)
        assert a.residual == b.residual
        assert np.array_equal(a.warped, b.warped)


def _cylinder(r, h):
    m = trimesh.creation.cylinder(radius=r, height=h, sections=64)
    m.apply_translation([0, 0, h / 2])
    return m


def _sample(mesh, n, seed=0):
    return np.asarray(trimesh.sample.sample_surface_even(mesh, n, seed=seed)[0])


def test_normal_obliqueness_sphere_vs_upright_prisms():
    """|sin 2 phi| of a sphere's normals averages 2/3 (|n_z| is uniform on a sphere); upright boxes and
    cylinders have horizontal and vertical faces (only edges and rims count); tilting a box 45 degrees
    makes most of its faces oblique. Scale and heading do not matter."""
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.037)
    ob_sphere = normal_obliqueness(_sample(sphere, 800))
    assert 0.55 < ob_sphere < 0.72
    assert normal_obliqueness(2.5 * _sample(sphere, 800) @ yaw_matrix(1.0).T) == pytest.approx(ob_sphere, abs=0.02)
    box = _sample(_box(0.09, 0.05, 0.12), 800)
    assert normal_obliqueness(box) < 0.2
    assert normal_obliqueness(box @ yaw_matrix(0.7).T) == pytest.approx(normal_obliqueness(box), abs=1e-9)
    assert normal_obliqueness(_sample(_cylinder(0.034, 0.10), 800)) < 0.25
    c = np.cos(np.pi / 4)
    tilt = np.array([[1.0, 0, 0], [0, c, -c], [0, c, c]])  # 45 degrees about x
    assert normal_obliqueness(box @ tilt.T) > 0.5
    with pytest.raises(InvalidInput):
        normal_obliqueness(np.zeros((2, 3)))


def test_shape_term_separates_a_squashed_ball_from_a_flat_can():
    """A flat cylinder (86 x 34 mm, like YCB 007_tuna_fish_can) against a ball and a tall can template:
    the smooth warp squashes the ball onto it, but the warped ball keeps its oblique shoulders, so its
    shape difference is many times the can's and the shape term widens the ball/can score ratio."""
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.037)
    ball = Template("ball", "ball", _sample(sphere, 800) + [0, 0, 0.037])
    can = Template("can", "can", _sample(_cylinder(0.034, 0.102), 800))
    rng = np.random.default_rng(0)
    X = _visible(_cylinder(0.043, 0.034), 500, seed=1, yaw=0.8)
    X = X + rng.normal(scale=0.001, size=X.shape)
    fb, fc = fit_template(X, ball), fit_template(X, can)
    assert fb.shape > 5 * fc.shape
    assert fb.residual == pytest.approx(fb.distance * (1 + 2.0 * fb.normals) * (1 + 0.5 * fb.shape))
    fb0, fc0 = fit_template(X, ball, shape_weight=0.0), fit_template(X, can, shape_weight=0.0)
    assert fb.residual / fc.residual > 1.1 * fb0.residual / fc0.residual
    assert classify(X, [ball, can]).category == "can"
