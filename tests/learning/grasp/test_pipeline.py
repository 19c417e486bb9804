"""Grasp database, simulated perception, YCB/toy-arm objects and one MuJoCo lift-and-shake trial."""
import mujoco
import numpy as np
import pytest

from robointel.errors import DataMissing, InvalidInput
from robointel.learning.grasp import (
    GraspPlanner,
    Placement,
    Template,
    classify,
    default_cameras,
    depth_image,
    grasp_trial,
    perceive,
    perceived_template,
    primitive_object,
    random_placements,
    sample_points,
    scene_xml,
    seen_template,
    taught_grasps,
    toy_arm,
    ycb_object,
)
from robointel.learning.grasp.perception import voxel_downsample
from robointel.learning.grasp_database import GraspDatabase


def test_grasp_db_roundtrip(tmp_path):
    db = GraspDatabase(tmp_path / "g.h5")
    objs = [primitive_object("cup", 1), primitive_object("box", 2)]
    for o in objs:
        db.add(Template(o.name, o.category, sample_points(o, 100, 0), taught_grasps(o)), source="primitive")
    assert db.names() == [o.name for o in objs]
    t = db.load(objs[0].name)
    assert t.category == "cup" and t.points.shape == (100, 3)
    ref = taught_grasps(objs[0])
    assert [g.name for g in t.grasps] == [g.name for g in ref]
    assert np.allclose(t.grasps[1].rotation, ref[1].rotation)
    assert db.gripper().max_width == pytest.approx(0.048)
    with pytest.raises(InvalidInput):
        db.add(t)
    with pytest.raises(DataMissing):
        GraspDatabase(tmp_path / "none.h5").names()


def test_voxel_downsample_5mm():
    rng = np.random.default_rng(0)
    P = rng.uniform(0, 0.05, size=(5000, 3))
    V = voxel_downsample(P, 0.005)
    assert len(V) <= 1000 and len(V) > 900
    key = np.floor(V / 0.005)
    assert len(np.unique(key, axis=0)) == len(V)


def test_perception_finds_each_object():
    objs = [primitive_object("cup", 1), primitive_object("box", 2), primitive_object("ball", 3)]
    pl = random_placements(objs, 4)
    m0 = mujoco.MjModel.from_xml_string(scene_xml([]))
    d0 = mujoco.MjData(m0)
    mujoco.mj_forward(m0, d0)
    cams = default_cameras()
    bgs = [depth_image(m0, d0, c, 0) for c in cams]
    m = mujoco.MjModel.from_xml_string(scene_xml(pl))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    clouds = perceive(m, d, cams, bgs, rng=1)
    assert len(clouds) == 3
    centres = np.array([c.mean(0)[:2] for c in clouds])
    for p in pl:
        assert np.min(np.linalg.norm(centres - [p.x, p.y], axis=1)) < 0.03
    for c in clouds:  # on the 5 mm voxel grid: no two points closer than ~ a voxel apart on average
        assert c[:, 2].min() > 0.0


def test_ycb_and_toy_arm_objects(shared_data):
    shared_data("objects", "ycb", "065-a_cups", "mesh.ply")
    cup = ycb_object("065-a_cups")
    assert cup.category == "cup" and len(cup.pieces) > 10
    assert abs(cup.mesh.bounds[0, 2]) < 1e-9
    assert all(p.is_convex for p in cup.pieces[:5])
    a, b = toy_arm(rng=1), toy_arm(rng=2)
    assert a.category == "toy_arm" and len(a.pieces) >= 6
    assert 0.1 < a.height < 0.3
    assert not np.allclose(a.mesh.extents, b.mesh.extents)  # different joint angles


def test_lift_and_shake_trial_holds_a_box():
    tmpl_obj = primitive_object("box", 10)
    tmpl = Template("box_t", "box", sample_points(tmpl_obj, 600, 0), taught_grasps(tmpl_obj))
    ball = primitive_object("ball", 11)
    tball = Template("ball_t", "ball", sample_points(ball, 600, 0), taught_grasps(ball))
    planner = GraspPlanner([tmpl, tball])
    target = primitive_object("box", 12)
    res = grasp_trial(target, Placement(target, 0.5, 0.05, 0.6), planner, rng=0)
    assert res.category == "box"
    assert res.plan.search.feasible
    assert res.success, res.reason
    assert res.final_height > 0.08
    # the gripper comes in from above: nothing touches the box before the jaws close on it
    approach, descend = res.log[0], res.log[1]
    assert approach["phase"] == "approach" and approach["contacts"] == 0 and descend["contacts"] == 0
    assert abs(approach["obj_z"]) < 0.002


def test_seen_templates_tell_a_generated_cup_from_a_can():
    """A perceived generated cup is nearer the cup's seen template than the can's (full-model templates
    carry the unseen underside and far walls, and the can's won)."""
    cup, can = primitive_object("cup", 21, "cup_t"), primitive_object("can", 22, "can_t")
    templates = [seen_template(cup), seen_template(can)]
    assert all(len(t.points) > 50 and t.points[:, 2].min() > -0.01 for t in templates)
    target = primitive_object("cup", 23, "cup_target")
    cloud = perceived_template(target, rng=1, placement=Placement(target, 0.52, -0.04, 0.7))
    T = Placement(target, 0.52, -0.04, 0.7).pose
    cloud = cloud @ T[:3, :3].T + T[:3, 3]  # back in the world frame
    assert classify(cloud, templates, n_points=200).category == "cup"


def test_perceived_template_is_in_the_object_frame():
    from robointel.learning.grasp import perceived_template

    box = primitive_object("box", 5)
    P = perceived_template(box, rng=0)
    assert len(P) > 50
    lo, hi = box.mesh.bounds
    # a few noisy table pixels next to the object survive background removal: check the bulk
    assert np.all(np.percentile(P, 2, axis=0) > lo - 0.005) and np.all(np.percentile(P, 98, axis=0) < hi + 0.005)


@pytest.mark.parametrize("wide", [False, True])
def test_arm_scene_matches_the_robot_core_and_servos_track(lrmate, wide):
    """The LR Mate in the grasp scene: MuJoCo's gripper frame equals the robot core's forward
    kinematics (tool = grasp frame), and the joint servos hold a commanded pose under gravity; with
    the 48 mm and with the 85 mm gripper on the flange."""
    from robointel.learning.grasp.pipeline import lrmate_with_gripper
    from robointel.learning.grasp.quality import NARROW_GRIPPER, WIDE_GRIPPER
    from robointel.learning.grasp.scene import arm_scene

    g = WIDE_GRIPPER if wide else NARROW_GRIPPER
    robot = lrmate_with_gripper(g)
    m = arm_scene([], robot, g)
    d = mujoco.MjData(m)
    adr = [m.jnt_qposadr[m.joint("arm/" + n).id] for n in robot.joint_names]
    q = np.radians([10, 25, -5, 20, -60, 30])
    d.qpos[adr] = q
    mujoco.mj_forward(m, d)
    T = robot.fk(q)
    b = m.body("arm/gripper").id
    assert np.allclose(d.xpos[b], T[:3, 3], atol=1e-9)
    assert np.allclose(d.xmat[b].reshape(3, 3), T[:3, :3], atol=1e-9)
    d.ctrl[:6] = q
    for _ in range(500):
        mujoco.mj_step(m, d)
    assert np.abs(d.qpos[adr] - q).max() < 2e-3
    assert m.actuator("arm/afp").forcerange[1] == pytest.approx(g.grip_force)
    assert m.jnt_range[m.joint("arm/fp").id][1] == pytest.approx(g.max_width / 2)


def test_planner_classifies_with_k_templates_and_excludes_the_target():
    """Several classifying templates per category (6.17)-(6.19): the nearest wins, an excluded name is
    never fitted, and the grasps come from the category's taught template even when the nearest
    classifying template has none."""
    box_t = primitive_object("box", 10)
    tmpl = Template("box_t", "box", sample_points(box_t, 600, 0), taught_grasps(box_t))
    box_b = primitive_object("box", 12)
    tb = Template("box_b", "box", sample_points(box_b, 600, 0), [])
    ball = primitive_object("ball", 11)
    tball = Template("ball_t", "ball", sample_points(ball, 600, 0), taught_grasps(ball))
    planner = GraspPlanner([tmpl, tball], classifiers=[tmpl, tb, tball], robot=None)
    cloud = sample_points(box_b, 600, 1) + [0.5, 0.0, 0.0]
    plan = planner.plan(cloud)
    assert plan.classification.category == "box"
    assert len(plan.classification.fits) == 3
    assert len(plan.transferred) == len(tmpl.grasps)
    plan = planner.plan(cloud, exclude=("box_b",))
    assert [f.template.name for f in plan.classification.fits] == ["box_t", "ball_t"]
    assert plan.classification.category == "box"
    with pytest.raises(InvalidInput):
        planner.plan(cloud, exclude=("box_t", "box_b", "ball_t"))


def test_closing_tilt_is_the_closing_axis_elevation_whatever_the_turn_about_it():
    from robointel.learning.grasp.pipeline import closing_tilt
    from robointel.learning.grasp.transfer import Grasp

    def rot_x(a):
        c, s = np.cos(a), np.sin(a)
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])

    down = np.diag([1.0, -1.0, -1.0])  # approach straight down, closing axis along -y: level
    for deg in (0, 30, 45, 82, 90):
        g = Grasp(np.zeros(3), rot_x(np.radians(deg)) @ down)  # the closing axis raised by deg about x
        assert closing_tilt(g) == pytest.approx(np.radians(deg), abs=1e-9)
        for turn in (-1.2, 0.4):  # the orientation search turns about the closing axis: same tilt
            assert closing_tilt(g.rotated_about_axis(turn)) == pytest.approx(np.radians(deg), abs=1e-9)
