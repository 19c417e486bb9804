"""The loop closed at the hand: the part between the jaws before closing, an empty, partial or firm grip
after it, a slip after the lift; the planner steering away from a grasp that failed."""
import mujoco
import numpy as np
import pytest
import trimesh

from robointel.learning.grasp import GraspPlanner, ObjectModel, Placement, Template, grasp_from_axis, sample_points
from robointel.learning.grasp.hand import HandReading, after_close, after_lift, between_jaws, read_hand
from robointel.learning.grasp.objects import taught_grasps
from robointel.learning.grasp.quality import NARROW_GRIPPER
from robointel.learning.grasp.scene import close_command, scene_xml

DOWN = [0.0, 0.0, -1.0]


def _bar(extents=(0.02, 0.08, 0.02)) -> ObjectModel:
    mesh = trimesh.creation.box(extents=list(extents))
    mesh.apply_translation([0, 0, extents[2] / 2])
    return ObjectModel("bar", "box", mesh, [mesh], 0.1)


def test_between_jaws_wants_the_seen_part_centred_on_the_pads_and_clear_of_the_fingers():
    bar = _bar((0.08, 0.02, 0.02))  # 80 mm along x, 20 mm across
    seen = sample_points(bar, 2000, 0)
    seen = seen[seen[:, 2] > 0.004]
    ok = between_jaws(grasp_from_axis([0, 0, 0.012], [0, 1, 0], DOWN), seen, NARROW_GRIPPER)
    assert ok.ok, ok.detail
    # jaws at the bar's very end: only the pads' edge has the part between it
    end = between_jaws(grasp_from_axis([0.046, 0, 0.012], [0, 1, 0], DOWN), seen, NARROW_GRIPPER)
    assert not end.ok and end.state == "not between the jaws"
    beside = between_jaws(grasp_from_axis([0.0, 0.05, 0.012], [1, 0, 0], DOWN), seen, NARROW_GRIPPER)
    assert not beside.ok
    # closing along the bar's length: the fingers come down on it
    along = between_jaws(grasp_from_axis([0, 0, 0.012], [1, 0, 0], DOWN), seen, NARROW_GRIPPER)
    assert not along.ok and along.state == "finger on the part"


def test_after_close_and_after_lift_verdicts():
    g = NARROW_GRIPPER
    assert after_close(HandReading(0.019, (20.0, 19.5)), 0.02, g).ok
    assert after_close(HandReading(0.0002, (0.0, 0.0)), 0.02, g).state == "empty"
    assert after_close(HandReading(0.012, (20.0, 0.5)), 0.02, g).state == "partial"
    assert after_close(HandReading(0.004, (20.0, 20.0)), 0.03, g).state == "partial"  # a tip, not the part
    assert after_close(HandReading(0.004, (20.0, 20.0)), 0.006, g).ok  # a thin part is thin
    closed = HandReading(0.019, (20.0, 20.0))
    assert after_lift(closed, HandReading(0.0188, (19.0, 19.0)), g).ok
    assert after_lift(closed, HandReading(0.012, (20.0, 20.0)), g).ok  # turned in the jaws, still held
    assert after_lift(closed, HandReading(0.009, (20.0, 20.0)), g).state == "slipped"  # sliding out
    assert after_lift(closed, HandReading(0.0185, (2.0, 20.0)), g).state == "slipped"
    assert after_lift(closed, HandReading(0.0, (0.0, 0.0)), g).state == "empty"


def _squeeze(placements, seconds=0.6):
    """The 48 mm gripper alone, jaws 10 mm above the table at (0.5, 0), closed for ``seconds``: its sensors."""
    m = mujoco.MjModel.from_xml_string(scene_xml(placements, dynamic=True, gripper=NARROW_GRIPPER))
    d = mujoco.MjData(m)
    top = [0.0, 1.0, 0.0, 0.0]  # the grasp frame's z (approach) pointing down
    adr = m.jnt_qposadr[m.joint("gripper").id]
    d.qpos[adr:adr + 7] = [0.5, 0.0, 0.01, *top]
    d.mocap_pos[0], d.mocap_quat[0] = [0.5, 0.0, 0.01], top
    for k in range(int(seconds / m.opt.timestep)):
        d.ctrl[-2:] = close_command(NARROW_GRIPPER) if k * m.opt.timestep > 0.1 else 0.0
        mujoco.mj_step(m, d)
    return read_hand(m, d, (m.body("fp").id, m.body("fn").id), m.joint("fp").id, NARROW_GRIPPER)


def test_read_hand_tells_a_squeezed_bar_from_empty_jaws():
    """Closed on a 20 mm bar, the jaws read ~20 mm and each pad the grip force; closed on nothing, they meet."""
    held = _squeeze([Placement(_bar(), 0.5, 0.0, np.pi / 2)])
    assert held.opening == pytest.approx(0.02, abs=0.001)
    assert held.forces == pytest.approx((NARROW_GRIPPER.grip_force,) * 2, rel=0.15)
    assert after_close(held, 0.02, NARROW_GRIPPER).ok
    empty = _squeeze([Placement(_bar(), 0.5, 0.2, 0.0)])
    assert empty.opening < 0.0015 and max(empty.forces) < 1.0
    assert after_close(empty, 0.02, NARROW_GRIPPER).state == "empty"


def test_the_planner_avoids_a_grasp_that_failed():
    """Planned again with the first grasp marked failed, the planner takes another one (> 10 mm or 30 deg away)."""
    box = _bar((0.03, 0.08, 0.06))
    tmpl = Template("box_t", "box", sample_points(box, 300, 0), taught_grasps(box), 0.1)
    planner = GraspPlanner([tmpl], robot=None, refine=False, n_points=100)
    cloud = sample_points(box, 800, 3) + [0.5, 0.0, 0.0]
    cloud = cloud[cloud[:, 2] > 0.004]
    first = planner.plan(cloud).search.grasp
    again = planner.plan(cloud, avoid=[first]).search.grasp
    moved = np.linalg.norm(again.centre - first.centre)
    turned = np.degrees(np.arccos(min(1.0, abs(float(again.axis @ first.axis)))))
    assert moved > 0.01 or turned > 30


def test_a_trial_lets_go_of_a_stale_plan_and_grasps_again():
    """A plan made where the box stood before it moved 3 cm: at the pre-grasp the perceived box is not
    between the jaws (a finger would come down on it), so the trial backs off without closing, looks
    again, plans again (the same gripper) and holds the box through the lift and the shake on its
    second attempt."""
    import mujoco

    from robointel.learning.grasp import default_cameras, depth_image, grasp_trial, perceive, primitive_object

    box_t = primitive_object("box", 10)
    planner = GraspPlanner([Template("box_t", "box", sample_points(box_t, 600, 0), taught_grasps(box_t), 0.12)])
    target = primitive_object("box", 12)
    before = Placement(target, 0.5, 0.02, 0.6)
    cams = default_cameras()
    m0 = mujoco.MjModel.from_xml_string(scene_xml([]))
    d0 = mujoco.MjData(m0)
    mujoco.mj_forward(m0, d0)
    bgs = [depth_image(m0, d0, c, 0) for c in cams]
    m = mujoco.MjModel.from_xml_string(scene_xml([before]))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    stale = planner.plan(perceive(m, d, cams, bgs, rng=1)[0])
    assert stale.search.feasible
    res = grasp_trial(target, Placement(target, 0.5, 0.05, 0.6), planner, rng=0, plan=stale, attempts=2)
    assert res.attempts == 2
    assert len(res.let_go) == 1
    assert res.let_go[0].startswith(("attempt 1: not between the jaws", "attempt 1: finger on the part"))
    assert [s["phase"] for s in res.log if s["attempt"] == 1] == ["approach", "back off"]  # never closed
    assert res.success, res.reason
