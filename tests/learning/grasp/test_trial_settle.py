"""The trial's cameras look at a resting object: a toy arm that falls over is waited for."""
import mujoco
import numpy as np

from robointel.learning.grasp import Placement, primitive_object, scene_xml, toy_arm
from robointel.learning.grasp.trial import REST_HOLD, SETTLE_MAX, settle_until_at_rest


def _scene(obj):
    m = mujoco.MjModel.from_xml_string(scene_xml([Placement(obj, 0.55, 0.0, 0.3)], dynamic=True))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return m, d, m.body("obj0").id


def test_a_falling_toy_arm_is_at_rest_when_the_cameras_look():
    m, d, body = _scene(toy_arm(robot="ur5", rng=102))  # the benchmark's toy_ur5_2: it tips over
    t = settle_until_at_rest(m, d, body, 0.3)
    assert 0.3 + REST_HOLD < t < SETTLE_MAX  # still tipping at 0.3 s; at rest well before the cap
    pose = d.xpos[body].copy(), d.xquat[body].copy()
    for _ in range(int(0.5 / m.opt.timestep)):
        mujoco.mj_step(m, d)
    assert np.linalg.norm(d.xpos[body] - pose[0]) < 1e-3  # it does not move any more
    assert abs(abs(float(d.xquat[body] @ pose[1])) - 1.0) < 1e-4


def test_a_box_at_rest_is_looked_at_after_the_least_time():
    m, d, body = _scene(primitive_object("box", 12))
    t = settle_until_at_rest(m, d, body, 0.3)
    assert 0.3 <= t < 0.3 + 2 * REST_HOLD + 0.05
