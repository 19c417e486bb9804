"""The two parallel grippers (48 mm and 85 mm stroke): choice by grasp width, quality, MuJoCo trial."""
import mujoco
import numpy as np
import pytest
import trimesh

from robointel.errors import InvalidInput
from robointel.learning.grasp import (
    GraspPlanner,
    ObjectModel,
    Placement,
    Template,
    grasp_from_axis,
    grasp_quality,
    grasp_trial,
    holdable,
    sample_points,
    sampled_grasps,
    taught_grasps,
)
from robointel.learning.grasp.quality import NARROW_GRIPPER, TOO_WIDE, WIDE_GRIPPER, choose_gripper


def _can(radius: float, height: float, name: str, mass: float = 0.3) -> ObjectModel:
    mesh = trimesh.creation.cylinder(radius=radius, height=height, sections=48)
    mesh.apply_translation([0, 0, height / 2])
    return ObjectModel(name, "can", mesh, [mesh], mass)


def test_wide_gripper_is_the_85mm_class():
    g = WIDE_GRIPPER
    assert g.max_width == pytest.approx(0.085) and g.finger_breadth == pytest.approx(0.022)
    assert 20.0 <= g.grip_force <= 235.0 and g.mass == pytest.approx(0.9)
    assert NARROW_GRIPPER.max_width == pytest.approx(0.048) and NARROW_GRIPPER.grip_force == pytest.approx(20.0)
    assert g.name != NARROW_GRIPPER.name


def test_choose_gripper_by_width():
    both = [WIDE_GRIPPER, NARROW_GRIPPER]  # any order
    assert choose_gripper([0.030, 0.070], both) is NARROW_GRIPPER  # the part fits the narrow one somewhere
    assert choose_gripper([0.042, np.nan], both) is NARROW_GRIPPER
    assert NARROW_GRIPPER.grip_range[1] == pytest.approx(0.043)  # 2.5 mm room each side of the part
    assert choose_gripper([0.044], both) is WIDE_GRIPPER  # beyond the 48 mm gripper's range
    assert choose_gripper([0.044], both, margin=0.003) is NARROW_GRIPPER  # a margin given by the caller
    assert choose_gripper([0.068, 0.070], both) is WIDE_GRIPPER
    assert choose_gripper([0.120], both) is WIDE_GRIPPER  # none fits: the widest
    assert choose_gripper([np.nan], both) is NARROW_GRIPPER  # unknown: the default
    with pytest.raises(InvalidInput):
        choose_gripper([0.03], [])


def test_a_56mm_can_is_too_wide_for_the_narrow_gripper_only():
    P = sample_points(_can(0.028, 0.10, "can56"), 3000, 0)
    g = grasp_from_axis([0, 0, 0.06], [1, 0, 0], [0, 0, -1])
    assert grasp_quality(P, g, gripper=NARROW_GRIPPER).quality == TOO_WIDE
    q = grasp_quality(P, g, gripper=WIDE_GRIPPER)
    assert q.quality > 0 and q.width == pytest.approx(0.056, abs=0.004)


def test_planner_and_trial_put_the_wide_gripper_on_a_wide_can():
    """A 66 mm can (template: a 70 mm can) is planned with the 85 mm gripper, whose tool the IK uses,
    and held through the lift and shake with it on the LR Mate's flange in MuJoCo."""
    tmpl_obj = _can(0.035, 0.11, "can_t")
    tmpl = Template("can_t", "can", sample_points(tmpl_obj, 600, 0), taught_grasps(tmpl_obj))
    planner = GraspPlanner([tmpl])
    assert [g.name for g in planner.grippers] == [NARROW_GRIPPER.name, WIDE_GRIPPER.name]
    assert planner.robot_for(WIDE_GRIPPER) is not planner.robot_for(NARROW_GRIPPER)
    target = _can(0.033, 0.10, "can66")
    res = grasp_trial(target, Placement(target, 0.5, -0.05, 0.4), planner, rng=0)
    assert res.plan is not None and res.plan.gripper == WIDE_GRIPPER and res.gripper == WIDE_GRIPPER.name
    assert min(w for w in res.plan.widths if np.isfinite(w)) > NARROW_GRIPPER.max_width
    assert res.plan.search.feasible
    q = res.plan.search.q
    T = planner.robot_for(WIDE_GRIPPER).fk(q)
    assert np.allclose(T[:3, 3], res.plan.search.grasp.centre, atol=1e-6)
    assert res.success, res.reason
    assert res.final_height > 0.08


def test_holdable_is_a_grasp_found_by_either_gripper():
    """``holdable`` agrees with the teaching sampler: a 66 mm can only with the 85 mm gripper, a 110 mm
    can with neither."""
    mid, big = _can(0.033, 0.10, "can66"), _can(0.055, 0.10, "can110")
    assert not sampled_grasps(mid, 1, gripper=NARROW_GRIPPER) and sampled_grasps(mid, 1, gripper=WIDE_GRIPPER)
    assert holdable(mid) and not holdable(mid, (NARROW_GRIPPER,))
    assert not holdable(big)


@pytest.mark.parametrize("gripper", [NARROW_GRIPPER, WIDE_GRIPPER], ids=lambda g: g.name)
def test_the_closing_drive_squeezes_with_the_grip_force_at_any_width(gripper):
    """Commanded closed, each finger's drive pushes with the gripper's grip force on a 2 mm and on a
    40 mm part (a force-controlled electric gripper), not with a force that fades near the closed end."""
    from robointel.learning.grasp.scene import FINGER_KP, close_command, scene_xml

    m = mujoco.MjModel.from_xml_string(scene_xml([], dynamic=True, gripper=gripper))
    d = mujoco.MjData(m)
    adr = [m.jnt_qposadr[m.joint(n).id] for n in ("fp", "fn")]
    for part in (0.002, 0.040):
        d.qpos[adr] = (gripper.max_width - part) / 2  # finger travel when the jaws touch the part
        d.ctrl[-2:] = close_command(gripper)
        mujoco.mj_forward(m, d)
        assert d.actuator_force[-2:] == pytest.approx([gripper.grip_force] * 2)
        d.ctrl[-2:] = gripper.max_width / 2  # the closed end as a position: weaker on thin parts
        mujoco.mj_forward(m, d)
        assert d.actuator_force[-1] == pytest.approx(min(gripper.grip_force, FINGER_KP * part / 2))


def _squeeze_depth(gripper) -> float:
    """Deepest finger-part penetration (m) of a 0.1 kg, 20 mm thick bar squeezed at mid-height by the
    gripper (approach from above, gripper alone on its mocap weld) after 0.5 s closed."""
    from robointel.learning.grasp.scene import close_command, scene_xml

    mesh = trimesh.creation.box([0.02, 0.08, 0.02])
    mesh.apply_translation([0, 0, 0.01])
    bar = ObjectModel("bar", "long_tool", mesh, [mesh], 0.1)
    m = mujoco.MjModel.from_xml_string(scene_xml([Placement(bar, 0.5, 0.0, 0.0)], dynamic=True, gripper=gripper))
    d = mujoco.MjData(m)
    top = [0.0, 1.0, 0.0, 0.0]  # the grasp frame's z (approach) pointing down
    adr = m.jnt_qposadr[m.joint("gripper").id]
    d.qpos[adr:adr + 7] = [0.5, 0.0, 0.01, *top]
    d.mocap_pos[0], d.mocap_quat[0] = [0.5, 0.0, 0.01], top
    body = m.body("obj0").id
    fingers = {m.body("fp").id, m.body("fn").id}
    deepest = 0.0
    for k in range(int(0.6 / m.opt.timestep)):
        d.ctrl[-2:] = close_command(gripper) if k * m.opt.timestep > 0.1 else 0.0
        mujoco.mj_step(m, d)
    for c in d.contact[:d.ncon]:
        pair = {int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])}
        if body in pair and pair & fingers:
            deepest = max(deepest, -float(c.dist))
    assert deepest > 0.0  # the jaws closed on the bar
    return deepest


@pytest.mark.parametrize("gripper", [NARROW_GRIPPER, WIDE_GRIPPER], ids=lambda g: g.name)
def test_the_finger_pads_do_not_sink_into_a_light_part(gripper, monkeypatch):
    """A light part squeezed with the full grip force is touched by rigid pads: under 1 mm of
    penetration with the pads' contact stiffness (:data:`FINGER_SOLREF`; 0.68 mm with 20 N, 0.29 mm with
    40 N per finger), where MuJoCo's default (0.02 s), which scales with the part's mass, lets them sink
    in by more than 3 mm (7.3 mm, 3.7 mm)."""
    from robointel.learning.grasp import scene

    assert _squeeze_depth(gripper) < 0.001
    monkeypatch.setattr(scene, "FINGER_SOLREF", (0.02, 1.0))
    assert _squeeze_depth(gripper) > 0.003
