"""Arms as their makers ship them plan with the automatic collision model (no sphere file).

A Kinova Gen3-style arm with continuous joints and a Unitree Z1 whose frame names repeat, both from
the installed ``example-robot-data``: random start/goal pairs that the exact geometry finds free,
around a box, planned and judged by the independent exact-mesh checker of the benchmarks.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest

from robointel.errors import CollisionAtStart, InvalidInput
from robointel.geometry.obstacles import Box
from robointel.planning import Environment, MotionSettings, plan_motion
from robointel.planning.budget_clock import budget_clock
from robointel.planning.budget_clock import now as budget_now
from robointel.planning.exact_self import self_geometry
from robointel.planning.hybrid_check import mesh_geometry
from robointel.robot import Robot
from robointel.robot.catalogue import example_robot_urdf

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from _mbm_checker import MBMChecker  # noqa: E402

ARMS = {"kinova": ("kinova_description/robots/kinova.urdf", "kinova_description/srdf/kinova.srdf"),
        "z1": ("z1_description/urdf/z1.urdf", "z1_description/srdf/z1.srdf")}


def _free_pair(env: Environment, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Two configurations >= 5 mm clear on the exact geometry."""
    r, mg, sg = env.robot, mesh_geometry(env), self_geometry(env.robot, env.disabled)
    out = []
    while len(out) < 2:
        q = r.random_configuration(rng)
        if mg.clearance(q, thresh=0.01)[0] >= 0.005 and sg.clearance(q, thresh=0.01)[0] >= 0.005:
            out.append(q)
    return out[0], out[1]


@pytest.mark.parametrize("arm", sorted(ARMS))
def test_arm_from_example_robot_data_plans_with_its_own_spheres(arm):
    urdf, srdf = (example_robot_urdf(p) for p in ARMS[arm])
    robot = Robot.load(urdf, srdf=srdf)
    box = Box(center=np.array([0.35, 0.0, 0.15]), size=np.array([0.1, 0.3, 0.3]), name="block")
    env = Environment(robot, [box])
    assert env.exact_self and robot.fitted_spheres
    checker = MBMChecker(urdf, srdf, joints=robot.joint_names, package_dirs=[str(urdf.parents[4])])
    rng = np.random.default_rng(3)
    for _ in range(2):  # the budget in CPU time: the same work on a loaded machine as on an idle one
        q0, q1 = _free_pair(env, rng)
        plan = plan_motion(robot, env, q0, q1, settings=MotionSettings(d_min=0.002, time_budget_s=3.0,
                                                                         budget_clock="cpu"))
        assert plan.success, plan.reason
        tr = plan.trajectory
        raw = {"start": q0.tolist(), "goals": [robot.wrap_goal(q1, q0).tolist()], "sphere": [], "cylinder": [],
               "box": [{"name": "block", "position": [0.35, 0.0, 0.15], "half_extents": [0.05, 0.15, 0.15],
                        "orientation_quat_xyzw": [0.0, 0.0, 0.0, 1.0]}]}
        v = checker.check_trajectory(tr.t, tr.q, raw, qd=tr.qd, dt=4e-3)
        assert not v.collision and v.reaches_goal, (v.pair, v.min_clearance)


def test_budget_clock_counts_the_process_cpu_time():
    with budget_clock("cpu") as clock:
        assert clock is time.process_time and budget_now() == pytest.approx(time.process_time(), abs=0.05)
    assert budget_now() == pytest.approx(time.perf_counter(), abs=0.05)  # the wall clock again after the block
    with pytest.raises(InvalidInput, match="budget_clock"):
        with budget_clock("gpu"):
            pass


def test_a_sphere_file_does_not_decide_self_collision(shared_data):
    """VAMP's Fetch spheres keep the base and the right finger 4 mm apart where their meshes touch."""
    root = shared_data("mbm", "fetch")
    robot = Robot.load(root / "fetch.urdf", srdf=root / "fetch.srdf", joints=[
        "torso_lift_joint", "shoulder_pan_joint", "shoulder_lift_joint", "upperarm_roll_joint", "elbow_flex_joint",
        "forearm_roll_joint", "wrist_flex_joint", "wrist_roll_joint"])
    q = np.array([0.1588, -0.43938, 0.35267, 0.24127, 1.03646, -0.10060, 1.00662, -1.03483])
    trusted = Environment(robot, [], spheres=root / "fetch_spherized.urdf", exact_self=False)
    assert trusted.self_clearance(q) > 0.003  # the file's spheres alone find it free
    env = Environment(robot, [], spheres=root / "fetch_spherized.urdf")
    assert env.exact_self
    assert self_geometry(robot, env.disabled).clearance(q, thresh=0.001)[0] <= 0.0
    with pytest.raises(CollisionAtStart, match="r_gripper_finger_link|base_link"):
        plan_motion(robot, env, q, q + 0.05, settings=MotionSettings(d_min=0.001, time_budget_s=1.0))
