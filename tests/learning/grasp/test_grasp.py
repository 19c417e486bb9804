"""Grasp transfer (6.14)-(6.16), quality (6.20), orientation search (6.21), classification (6.17)-(6.19)."""
import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.learning.grasp.classify import Template, classify, confusion_matrix, yaw_matrix
from robointel.learning.grasp.cpd import AffineWarp, RigidWarp, cpd_nonrigid
from robointel.learning.grasp.objects import primitive_object, sample_points, taught_grasps
from robointel.learning.grasp.quality import OFF_AXIS, SLIP, TOO_WIDE, ParallelGripper, estimate_normals, grasp_quality
from robointel.learning.grasp.search import orientation_search
from robointel.learning.grasp.transfer import Grasp, grasp_from_axis, nearest_rotation, transfer_grasp


def test_nearest_rotation_never_reflects():
    rng = np.random.default_rng(0)
    for _ in range(20):
        A = rng.normal(size=(3, 3))
        R = nearest_rotation(A)
        assert np.allclose(R.T @ R, np.eye(3), atol=1e-10)
        assert np.isclose(np.linalg.det(R), 1.0)
    R = nearest_rotation(np.diag([1.0, 1.0, -1.0]))  # a pure reflection
    assert np.isclose(np.linalg.det(R), 1.0)


def test_transfer_under_rigid_and_reflecting_affine_warp():
    g = grasp_from_axis([0.1, 0.0, 0.05], [1, 0, 0], [0, 0, -1], 0.03)
    th = 0.7
    R = yaw_matrix(th)
    w = RigidWarp(2.0, R, np.array([0.3, -0.1, 0.0]))
    h = transfer_grasp(w, g)
    assert np.allclose(h.centre, 2.0 * R @ g.centre + [0.3, -0.1, 0.0])
    assert np.allclose(h.rotation, R @ g.rotation, atol=1e-12)
    assert np.isclose(h.width, 0.06)
    mirror = AffineWarp(np.diag([-1.0, 1.0, 1.0]), np.zeros(3))
    m = transfer_grasp(mirror, g)
    assert np.isclose(np.linalg.det(m.rotation), 1.0)


def test_transfer_through_cpd_follows_the_surface():
    cup_a, cup_b = primitive_object("cup", 1), primitive_object("cup", 2)
    A, B = sample_points(cup_a, 500, 0), sample_points(cup_b, 500, 1)
    res = cpd_nonrigid(B, A, beta=2.0, lmbda=3.0, w=0.0, method="lowrank", max_iterations=80, tolerance=1e-6)
    g = taught_grasps(cup_a)[0]
    h = transfer_grasp(res.warp, g)
    r_b = 0.5 * cup_b.mesh.extents[0]
    assert abs(np.hypot(*h.centre[:2]) - r_b) < 0.006  # still on the rim wall of the new cup
    assert abs(h.approach @ [0, 0, -1]) > 0.95  # still from above


def test_quality_box_and_negative_codes():
    box = primitive_object("box", 3)
    P = sample_points(box, 4000, 0)
    g = taught_grasps(box)[0]
    q = grasp_quality(P, g)
    assert 0.0 < q.quality <= 1.0 and q.reason == "ok"
    assert q.width == pytest.approx(box.mesh.extents[1], abs=0.004)
    # across the long side: wider than the 48 mm stroke
    wide = grasp_from_axis(g.centre, [1, 0, 0] if box.mesh.extents[0] > box.mesh.extents[1] else [0, 1, 0], [0, 0, -1])
    assert grasp_quality(P, wide).quality == TOO_WIDE
    # axis that misses the object
    miss = Grasp(g.centre + [0, 0, 0.5], g.rotation)
    assert grasp_quality(P, miss).quality == OFF_AXIS
    # slanted axis through a flat face: outside the friction cone
    along_y = g.axis[1] > 0.5
    slant = grasp_from_axis(g.centre, [0.0, 1.0, 1.2] if along_y else [1.0, 0, 1.2],
                            [1, 0, 0] if along_y else [0, 1, 0])
    assert grasp_quality(P, slant).quality in (SLIP, TOO_WIDE)


def test_normals_unit_and_outward_on_sphere():
    rng = np.random.default_rng(0)
    P = rng.normal(size=(800, 3))
    P /= np.linalg.norm(P, axis=1, keepdims=True)
    n = estimate_normals(P, 10)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    assert np.mean(np.sum(n * P, axis=1)) > 0.98


def test_orientation_search_with_lrmate_ik(lrmate):
    from robointel.learning.grasp.pipeline import lrmate_with_gripper
    gripper = ParallelGripper()
    robot = lrmate_with_gripper(gripper)
    box = primitive_object("box", 3)
    P = sample_points(box, 3000, 0) + [0.5, 0.0, 0.0]
    g = taught_grasps(box)[0].transformed(np.r_[np.c_[np.eye(3), [0.5, 0, 0]], [[0, 0, 0, 1]]])
    r = orientation_search(g, P, robot, gripper=gripper, table_z=0.0)
    assert r.feasible and r.q is not None
    assert np.allclose(robot.fk(r.q), r.grasp.pose, atol=1e-6)
    assert not gripper.collides(r.grasp, P, table_z=0.0)
    # far out of reach: every angle penalised, result infeasible
    far = g.transformed(np.r_[np.c_[np.eye(3), [3.0, 0, 0]], [[0, 0, 0, 1]]])
    assert not orientation_search(far, P + [3.0, 0, 0], robot, gripper=gripper, table_z=0.0).feasible


def test_classify_held_out_primitives():
    cats = ["cup", "box", "ball", "long_tool"]
    templates = []
    for i, c in enumerate(cats):
        o = primitive_object(c, 100 + i)
        templates.append(Template(o.name, c, sample_points(o, 400, i), taught_grasps(o)))
    rng = np.random.default_rng(7)
    true, pred = [], []
    for i, c in enumerate(cats):
        for k in range(2):
            o = primitive_object(c, 200 + 10 * i + k)
            P = sample_points(o, 400, rng) @ yaw_matrix(rng.uniform(0, 6.28)).T + [0.5, 0.1, 0]
            true.append(c)
            pred.append(classify(P, templates, n_points=200).category)
    C, labels = confusion_matrix(true, pred, cats)
    assert C.sum() == 8 and np.trace(C) >= 7
    with pytest.raises(InvalidInput):
        classify(np.zeros((10, 3)), [])


def test_anisotropic_init_recovers_aspect_ratio():
    """A flat cylinder (tuna-can-like) against a tall can template: the bounded per-axis scale of the
    initial alignment fits it better than isotropic scaling alone, and the fitted warp still maps the
    template into the target's frame (rigid stage only, so the comparison is about the init)."""
    import trimesh

    from robointel.learning.grasp.classify import fit_template

    tall = trimesh.creation.cylinder(radius=0.033, height=0.10, sections=48)
    flat = trimesh.creation.cylinder(radius=0.042, height=0.035, sections=48)
    Y = np.asarray(trimesh.sample.sample_surface_even(tall, 600, seed=0)[0])
    X = np.asarray(trimesh.sample.sample_surface_even(flat, 600, seed=1)[0]) @ yaw_matrix(0.4).T + [0.5, 0.1, 0.0]
    t = Template("tall", "can", Y)
    iso = fit_template(X, t, nonrigid=False, anisotropic=0.0)
    ani = fit_template(X, t, nonrigid=False, anisotropic=1.5)
    assert ani.residual < 0.95 * iso.residual
    assert np.allclose(ani.warp(Y).mean(0)[:2], X.mean(0)[:2], atol=0.01)


def test_normal_disagreement_parallel_vs_crossed_planes():
    from robointel.learning.grasp.classify import normal_disagreement

    rng = np.random.default_rng(0)
    a = np.c_[rng.uniform(0, 0.1, (300, 2)), np.zeros(300)]  # plane z = 0
    b = np.c_[rng.uniform(0, 0.1, (300, 2)), np.full(300, 0.002)]  # parallel plane 2 mm above
    c = np.c_[rng.uniform(0, 0.1, 300), np.full(300, 0.05), rng.uniform(-0.05, 0.05, 300)]  # plane y = 0.05
    assert normal_disagreement(a, b) < 0.02
    assert normal_disagreement(a, c) > 0.9


def test_rest_z_fit_keeps_a_flat_object_on_the_table():
    """A flat bar seen from above (no underside points) against a tall bar template: the centroid
    init puts the template half below the table; the table-resting init keeps it on top."""
    import trimesh

    from robointel.learning.grasp.classify import fit_template

    tall = trimesh.creation.box(extents=[0.19, 0.03, 0.036])
    tall.apply_translation([0, 0, 0.018])
    flat = trimesh.creation.box(extents=[0.19, 0.025, 0.014])
    flat.apply_translation([0.5, 0.0, 0.007])
    Y = np.asarray(trimesh.sample.sample_surface_even(tall, 800, seed=0)[0])
    X = np.asarray(trimesh.sample.sample_surface_even(flat, 800, seed=1)[0])
    X = X[X[:, 2] > 0.004]  # what the cameras keep: nothing at the table
    t = Template("tall", "long_tool", Y)
    rest = fit_template(X, t, rest_z=0.0, anisotropic=0.0)
    iso = fit_template(X, t, anisotropic=0.0)
    assert rest.warp(Y)[:, 2].min() > -0.004
    assert iso.warp(Y)[:, 2].min() < rest.warp(Y)[:, 2].min() - 0.004


def test_refine_position_finds_the_height_of_a_flat_handle():
    """A grasp transferred below the table plane under a 14 mm high handle (as a warp fitted without
    the unseen underside does): the re-heighted upright candidates of refine_position hold it with
    positive quality (6.20) after the orientation search (6.21) lifts the fingertips clear of the table;
    the grasp as transferred does not."""
    import trimesh

    from robointel.learning.grasp.search import refine_position

    bar = trimesh.creation.box(extents=[0.15, 0.02, 0.014])
    bar.apply_translation([0.5, 0.0, 0.007])
    P = np.asarray(trimesh.sample.sample_surface_even(bar, 3000, seed=0)[0])
    P = P[P[:, 2] > 0.004]
    g = grasp_from_axis([0.5, 0.0, -0.012], [0.3, 1.0, -0.4], [0, 0, -1], 0.02)
    assert grasp_quality(P, g).quality < 0
    gripper = ParallelGripper()
    cands = refine_position(g, P, gripper=gripper, table_z=0.0)
    results = [orientation_search(c, P, None, gripper=gripper, table_z=0.0) for c in cands]
    ok = [r for r in results if r.feasible and r.quality > 0]
    assert ok and all(r.grasp.centre[2] >= gripper.tip_depth + 0.003 - 1e-9 for r in ok)
    assert not orientation_search(g, P, None, gripper=gripper, table_z=0.0).feasible


def test_quality_unseen_contact_when_only_the_completion_is_there():
    """A box seen on one side only, completed by a model of the other side: the grasp across it
    scores normally on the completed cloud, and UNSEEN when contacts must lie on perceived points."""
    from scipy.spatial import cKDTree

    from robointel.learning.grasp.quality import UNSEEN

    box = primitive_object("box", 3)
    P = sample_points(box, 4000, 0)
    g = taught_grasps(box)[0]
    seen = P[(P - g.centre) @ g.axis > 0]  # the camera saw only the +axis half
    assert grasp_quality(P, g).quality > 0
    assert grasp_quality(P, g, observed=cKDTree(P)).quality > 0
    q = grasp_quality(P, g, observed=cKDTree(seen))
    assert q.quality == UNSEEN and q.reason == "unseen"


def test_rim_normals_on_a_thin_plate_seen_from_above():
    """A 3 mm plate seen only from above (its top face, 5 mm grid): PCA normals at the jaw contacts are
    the face normal (SLIP); with ``edge_normals`` the contacts are the plate's rims, normal along the
    closing axis, and the grasp across the plate scores."""
    xs, ys = np.meshgrid(np.arange(-0.04, 0.0401, 0.005), np.arange(-0.008, 0.0081, 0.004))
    top = np.c_[xs.ravel(), ys.ravel(), np.full(xs.size, 0.003)]
    g = grasp_from_axis([0.0, 0.0, 0.003], [0, 1, 0], [0, 0, -1])
    assert grasp_quality(top, g).quality == SLIP
    q = grasp_quality(top, g, edge_normals=True)
    assert q.quality > 0 and q.reason == "ok"
    assert abs(q.normals[0] @ [0, 1, 0]) > 0.95 and abs(q.normals[1] @ [0, 1, 0]) > 0.95
    assert q.width == pytest.approx(0.016, abs=1e-9)


def test_carve_above_seen_drops_floating_and_outside_completion():
    from robointel.learning.grasp.pipeline import carve_above_seen

    xs, ys = np.meshgrid(np.arange(0.0, 0.05, 0.005), np.arange(0.0, 0.02, 0.005))
    seen = np.c_[xs.ravel(), ys.ravel(), np.full(xs.size, 0.010)]
    below = seen[:5] - [0, 0, 0.008]  # under the seen top: an unseen underside, kept
    above = seen[5:10] + [0, 0, 0.015]  # in space the cameras saw empty
    beside = seen[:3] + [0, 0.05, 0]  # beside the footprint, where the table was seen
    W = np.vstack([below, above, beside])
    out = carve_above_seen(W, seen)
    assert np.allclose(out, below)
    assert len(carve_above_seen(W, seen, footprint=None)) == len(below) + len(beside)


def test_pad_reach_and_sloped_rims():
    """A part seen as two strips (its 12 mm top face at z = 12 mm, and a 16 mm wide section at z = 6 mm
    seen beside it: a rounded handle). Jaws centred 16 mm up reach only the top strip (fingertips at
    11 mm). With ``pad_reach`` and rim
    normals the top strip's rims are not a grasp: the part is wider past the fingertips (its side
    slopes out). Jaws centred at 9 mm reach the wide section: the pad reach changes nothing there."""
    xs = np.arange(-0.03, 0.0301, 0.004)
    top = np.array([[x, y, 0.012] for x in xs for y in np.arange(-0.006, 0.00601, 0.003)])
    low = np.array([[x, y, 0.006] for x in xs for y in (-0.008, 0.008)])
    P = np.vstack([top, low])
    high = grasp_from_axis([0.0, 0.0, 0.016], [0, 1, 0], [0, 0, -1])
    assert grasp_quality(P, high, edge_normals=True, pad_reach=0.001).quality == SLIP
    mid = grasp_from_axis([0.0, 0.0, 0.009], [0, 1, 0], [0, 0, -1])
    qm = grasp_quality(P, mid, edge_normals=True, pad_reach=0.001)
    assert qm.width == pytest.approx(0.016, abs=1e-9)  # the pads reach the wide section
    assert qm.quality == grasp_quality(P, mid, edge_normals=True).quality
    # the pad reach alone: a grasp 12 mm above the top strip touches nothing
    over = grasp_from_axis([0.0, 0.0, 0.017], [0, 1, 0], [0, 0, -1])
    assert grasp_quality(P, over, pad_reach=0.001).quality == OFF_AXIS


def test_flat_pad_normal_on_rounded_sides_but_not_on_a_wedge():
    """Thin parts seen from above by the flat-pad model: a rounded bar (its sides sloped 45 deg about
    the bar's axis, as an oblique camera and 5 mm voxels smear a fork's handle) grips with the pads'
    normal; a wedge tapering 35 deg along the pad's breadth keeps its cloud normals and is SLIP;
    a wall that continues below the fingertips (a cup's rim seen from above) gets no rim normals."""
    xs = np.arange(-0.03, 0.0301, 0.003)
    prof = [(-0.008, 0.006), (-0.006, 0.008), (-0.003, 0.009), (0.0, 0.009), (0.003, 0.009), (0.006, 0.008),
            (0.008, 0.006)]
    bar = np.array([[x, y, z] for x in xs for y, z in prof])
    g = grasp_from_axis([0.0, 0.0, 0.008], [0, 1, 0], [0, 0, -1])
    assert grasp_quality(bar, g, pad_reach=0.003).quality == SLIP  # cloud normals at the sloped edges
    q = grasp_quality(bar, g, pad_reach=0.003, edge_normals=True, table_z=0.0)
    assert q.quality > 0 and np.all(np.abs(q.normals[:, 1]) > 0.9)
    # a wedge: half-width 0.7 x (35 deg taper along x), top face at 8 mm, sides sampled
    wedge = np.array([[x, s * (0.004 + 0.7 * (x + 0.03)), z] for x in np.arange(-0.03, 0.0, 0.002)
                      for s in (-1, 1) for z in (0.004, 0.006, 0.008)])
    gw = grasp_from_axis([-0.015, 0.0, 0.009], [0, 1, 0], [0, 0, -1])
    assert grasp_quality(wedge, gw, pad_reach=0.003, edge_normals=True, table_z=0.0).quality == SLIP
    # a 4 mm wall 60 mm tall seen from above and from its sides: its top ring is no rim
    wall = np.array([[x, y, z] for x in xs for y in (-0.002, 0.0, 0.002) for z in np.arange(0.0, 0.0601, 0.003)
                     if abs(y) == 0.002 or z > 0.059])
    gt = grasp_from_axis([0.0, 0.0, 0.057], [0, 1, 0], [0, 0, -1])
    qt = grasp_quality(wall, gt, pad_reach=0.003, edge_normals=True, table_z=0.0)
    qn = grasp_quality(wall, gt, pad_reach=0.003, table_z=0.0)
    assert qt.quality == qn.quality


def test_refine_position_slides_a_grasp_toward_the_centroid():
    """A grasp on a 25 cm bar lying on the table, 8 cm from its middle: with ``toward`` (the cloud's
    centroid) and ``com_weight`` the best refined candidate lies nearer the middle (gravity's lever on
    the grip shorter); without, it stays near where it was transferred."""
    import trimesh

    from robointel.learning.grasp.search import refine_position

    bar = trimesh.creation.box(extents=[0.25, 0.02, 0.02])
    bar.apply_translation([0.5, 0.0, 0.01])
    P = np.asarray(trimesh.sample.sample_surface_even(bar, 4000, seed=0)[0])
    P = P[P[:, 2] > 0.004]
    g = grasp_from_axis([0.58, 0.0, 0.012], [0.0, 1.0, 0.0], [0, 0, -1], 0.02)
    gripper = ParallelGripper()
    centroid = P.mean(axis=0)
    plain = refine_position(g, P, gripper=gripper, table_z=0.0)
    toward = refine_position(g, P, gripper=gripper, table_z=0.0, toward=centroid, com_weight=2.0)
    assert abs(plain[1].centre[0] - 0.58) < 0.02
    assert abs(toward[1].centre[0] - 0.5) < abs(plain[1].centre[0] - 0.5) - 0.03
    assert grasp_quality(P, toward[1], gripper=gripper, table_z=0.0).quality > 0


def test_orientation_search_needs_the_pre_grasp_reachable(lrmate):
    """A grasp approached horizontally toward the LR Mate's base at 0.5 m, 5 cm up: the grasp and the
    pose 10 cm above it are reachable, the pre-grasp 8 cm back along the approach (farther out) is not
    (the closed-form IK has no solution there), and the search calls it infeasible unless the pre-grasp
    is left out of the check."""
    from robointel.learning.grasp.pipeline import lrmate_with_gripper
    from robointel.learning.grasp.search import PRE_GRASP

    gripper = ParallelGripper()
    robot = lrmate_with_gripper(gripper)
    g = grasp_from_axis([0.50, 0.0, 0.05], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], 0.02)
    import trimesh

    cube = trimesh.creation.box(extents=[0.02, 0.02, 0.02])
    P = np.asarray(trimesh.sample.sample_surface_even(cube, 2000, seed=0)[0]) + g.centre
    kw = dict(gripper=gripper, angles=[0.0])
    assert orientation_search(g, P, robot, pre_grasp=None, **kw).feasible
    r = orientation_search(g, P, robot, **kw)
    assert not r.feasible and PRE_GRASP == pytest.approx(0.08)
