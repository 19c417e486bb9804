"""The hold model (mass, centre of mass, the shake's torque about the jaw axis) and the shape classes."""
import numpy as np
import pytest
import trimesh

from robointel.errors import InvalidInput
from robointel.learning.grasp import grasp_from_axis, grasp_quality
from robointel.learning.grasp.hold import GRAVITY, PartEstimate, Shake, contact_patch, estimate_part, hold, hull_volume
from robointel.learning.grasp.quality import NARROW_GRIPPER
from robointel.learning.grasp.shape import shape_class, shape_cost

DOWN = [0.0, 0.0, -1.0]


def _box_points(extents, n=4000, seed=0, at=(0.0, 0.0)):
    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_translation([at[0], at[1], extents[2] / 2])
    pts, _ = trimesh.sample.sample_surface(mesh, n, seed=np.random.default_rng(seed))
    return np.asarray(pts)


def test_the_torque_about_the_jaw_axis_is_the_weight_times_the_lever_and_the_margin_falls_with_it():
    """Without a shake the torque about the closing axis is m g times the centre of mass's horizontal
    distance along the part; the margin falls as the grasp moves away from it (a bar 0.2 kg, 160 mm long)."""
    P = _box_points([0.16, 0.03, 0.03])
    part = PartEstimate(0.2, np.array([0.0, 0.0, 0.015]))
    still = Shake(0.0, 0.0)
    margins = []
    for x in (0.0, 0.03, 0.06):
        g = grasp_from_axis([x, 0.0, 0.015], [0, 1, 0], DOWN)
        q = grasp_quality(P, g)
        assert q.quality > 0
        h = hold(g, q.contacts, P, part, NARROW_GRIPPER, shake=still)
        assert h.lever == pytest.approx(x, abs=1e-9)
        assert h.torque == pytest.approx(0.2 * GRAVITY * x, rel=1e-6)
        margins.append(h.margin)
    assert margins[0] > margins[1] > margins[2]
    # the shake only adds load
    g = grasp_from_axis([0.06, 0.0, 0.015], [0, 1, 0], DOWN)
    q = grasp_quality(P, g)
    assert hold(g, q.contacts, P, part, NARROW_GRIPPER, base=(-0.5, 0.0)).margin < margins[2]
    h = hold(g, q.contacts, P, part, NARROW_GRIPPER)
    assert h.cost(2.0) == pytest.approx(max(0.0, 1.0 - h.margin / 2.0)) and 0.0 <= h.cost(1e6) <= 1.0


def test_the_contact_patch_is_larger_on_a_flat_side_than_on_a_thin_edge():
    """A 30 mm cube's side under pads whose tips reach 15 mm down it: a 18 x 15 mm patch (radius 7.5 mm);
    a 2 mm plate's edge gives ~1 mm."""
    cube = _box_points([0.03, 0.03, 0.03])
    g = grasp_from_axis([0, 0, 0.02], [0, 1, 0], DOWN)
    assert contact_patch(cube, g, 0.015, NARROW_GRIPPER) == pytest.approx(0.0075, abs=0.001)
    plate = _box_points([0.06, 0.02, 0.002])
    g = grasp_from_axis([0, 0, 0.001], [0, 1, 0], DOWN)
    assert contact_patch(plate, g, 0.01, NARROW_GRIPPER) < 0.0015


def test_estimate_part_scales_the_template_mass_by_the_warp_growth():
    small = _box_points([0.05, 0.05, 0.05])
    big = 2.0 * small  # 8x the volume
    v = hull_volume(small)
    assert v == pytest.approx(0.05 ** 3, rel=0.05)
    e = estimate_part(big, mass=0.1, template_volume=v)
    assert e.mass == pytest.approx(0.4, rel=1e-6)  # the growth is bounded at 4x
    assert e.com == pytest.approx(big.mean(0))
    assert estimate_part(small, density=400.0).mass == pytest.approx(400 * 0.05 ** 3, rel=0.05)
    with pytest.raises(InvalidInput):
        estimate_part(small[:3])
    with pytest.raises(InvalidInput):
        estimate_part(small, mass=-1.0)
    with pytest.raises(InvalidInput):
        hold(grasp_from_axis([0, 0, 0.02], [0, 1, 0], DOWN), np.zeros((3, 3)), small, e, NARROW_GRIPPER)


def test_shape_classes_of_a_tin_a_utensil_and_a_round_can():
    """A rectangular footprint under a flat top is a box (closing across its short side costs least),
    a long low part is long (cheapest near its centre of mass), a cylinder is other (no rule)."""
    tin = _box_points([0.10, 0.06, 0.085])
    tin = tin[tin[:, 2] > 0.004]  # the cameras never see the underside
    s = shape_class(tin)
    assert s.kind == "box"
    assert abs(s.long_axis @ [1, 0]) == pytest.approx(1, abs=0.02)
    assert s.extents[:2] == pytest.approx([0.10, 0.06], abs=0.005)
    across = grasp_from_axis([0, 0, 0.05], [0, 1, 0], DOWN)
    lengthwise = grasp_from_axis([0, 0, 0.05], [1, 0, 0], DOWN)
    at_end = grasp_from_axis([0.04, 0, 0.05], [0, 1, 0], DOWN)
    assert shape_cost(across, s) < 0.05 < shape_cost(at_end, s) < shape_cost(lengthwise, s)
    bar = _box_points([0.18, 0.02, 0.01])
    s = shape_class(bar)
    assert s.kind == "long"
    near = grasp_from_axis([0.01, 0, 0.005], [0, 1, 0], DOWN)
    far = grasp_from_axis([0.07, 0, 0.005], [0, 1, 0], DOWN)
    assert shape_cost(near, s, com=[0, 0, 0.005], observed=bar) < shape_cost(far, s, com=[0, 0, 0.005], observed=bar)
    can = trimesh.creation.cylinder(radius=0.03, height=0.1, sections=64)
    pts, _ = trimesh.sample.sample_surface(can, 3000, seed=np.random.default_rng(1))
    s = shape_class(np.asarray(pts) + [0, 0, 0.05])
    assert s.kind == "other" and shape_cost(across, s) == 0.0
    with pytest.raises(InvalidInput):
        shape_class(np.zeros((2, 3)))


def test_shape_grasps_take_a_tin_across_its_short_side_and_a_utensil_near_its_centre_of_mass():
    from robointel.learning.grasp.quality import WIDE_GRIPPER
    from robointel.learning.grasp.shape import box_sides, shape_grasps

    tin = _box_points([0.10, 0.06, 0.085], at=(0.5, 0.0))
    tin = tin[tin[:, 2] > 0.004]
    s = shape_class(tin)
    gs = shape_grasps(s, tin, WIDE_GRIPPER)
    assert gs and all(abs(g.axis @ [0, 1, 0]) > 0.99 and g.approach[2] == pytest.approx(-1.0) for g in gs)
    deepest = min(g.centre[2] for g in gs)  # the palm 3 mm over the top, the fingers as deep as they go
    assert deepest == pytest.approx(0.085 + 0.003 - (WIDE_GRIPPER.finger_length - WIDE_GRIPPER.tip_depth), abs=0.003)
    assert any(np.linalg.norm(g.centre[:2] - [0.5, 0.0]) < 0.003 for g in gs)
    sides = box_sides(s)
    assert np.abs(np.abs(sides[:, 1]) - 0.03).min() < 0.003 and sides[:, 2].max() < 0.086
    bar = _box_points([0.18, 0.02, 0.01])
    s = shape_class(bar)
    gs = shape_grasps(s, bar, NARROW_GRIPPER, com=[0.03, 0.0, 0.005])
    assert gs[0].centre[:2] == pytest.approx([0.03, 0.0], abs=0.003)  # the first at the centre of mass
    assert all(abs(g.axis @ [0, 1, 0]) > 0.99 and abs(g.centre[0] - 0.03) <= 0.0301 for g in gs)
    assert all(0.005 <= g.centre[2] <= 0.01 for g in gs)
    assert shape_grasps(shape_class(np.asarray(trimesh.creation.icosphere(radius=0.03).vertices)), bar,
                        NARROW_GRIPPER) == []
