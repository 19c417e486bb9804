"""plan_motion on MotionBenchMaker UR5 problems (first valid problem of each family), re-checked
densely; the environment's kinematics against Pinocchio; goal sets, pose goals, bad input."""
from __future__ import annotations

import json

import numpy as np
import pytest

from robointel.errors import CollisionAtStart, DescriptionWarning, IKFailure, InvalidInput, NotFinite
from robointel.geometry.obstacles import Box, Cylinder, PointCloud, Sphere
from robointel.geometry.rotations import quat_to_matrix
from robointel.outcome import Failure
from robointel.planning import Environment, MotionSettings, plan_motion
from robointel.robot import Robot

FAMILIES = ["bookshelf_small", "bookshelf_tall", "bookshelf_thin", "box", "cage", "table_pick", "table_under_pick"]


def _obstacles(p: dict) -> list:
    """Obstacles of one problems.json entry (test-side reader, independent of robointel.io)."""
    out: list = []
    for b in p["box"]:
        x, y, z, w = b["orientation_quat_xyzw"]
        out.append(Box(center=b["position"], size=2 * np.asarray(b["half_extents"]),
                       rotation=quat_to_matrix([w, x, y, z]), name=b["name"]))
    for c in p["cylinder"]:
        x, y, z, w = c["orientation_quat_xyzw"]
        u = quat_to_matrix([w, x, y, z])[:, 2] * c["length"] / 2
        m = np.asarray(c["position"])
        out.append(Cylinder(a=m - u, b=m + u, radius=c["radius"], name=c["name"]))
    for s in p["sphere"]:
        out.append(Sphere(center=s["position"], radius=s["radius"], name=s["name"]))
    return out


@pytest.fixture(scope="module")
def mbm(shared_data):
    root = shared_data("mbm", "ur5")
    robot = Robot.load(root / "ur5.urdf")
    problems = json.loads((root / "problems.json").read_text())["problems"]
    return root, robot, problems


def _env(mbm, p, **kw) -> Environment:
    root, robot, _ = mbm
    return Environment(robot, _obstacles(p), srdf=root / "ur5.srdf", spheres=root / "ur5_spherized.urdf", **kw)


def _first_valid(mbm, family: str, k: int = 0) -> dict:
    return [p for p in mbm[2][family] if p["valid"]][k]


def _recheck(env: Environment, plan, start, goal, d_min: float) -> None:
    """Independent re-check: every 1 ms sample within limits and clear (knots already on a 1 ms
    grid, as the jerk-limited ones, are taken as given; others are Hermite-resampled)."""
    robot = env.robot
    tr = plan.trajectory
    if np.max(np.diff(tr.t)) > 1e-3 + 1e-12:
        tr = tr.resample(1e-3)
    assert np.allclose(tr.q[0], start, atol=1e-9) and np.allclose(tr.q[-1], goal, atol=1e-6)
    assert np.all(tr.q >= robot.lower - 1e-9) and np.all(tr.q <= robot.upper + 1e-9)
    assert np.all(np.abs(tr.qd) <= robot.velocity_limit * (1 + 1e-5))
    assert np.all(np.abs(tr.qdd) <= robot.acceleration_limit * (1 + 1e-5))
    d = np.array([env.clearance(q, cap=0.05) for q in tr.q[::5]])  # every 5 ms here, all in the planner
    assert d.min() >= d_min - 1e-3
    assert plan.min_clearance_m >= d_min - 1e-3


def test_kernel_kinematics_match_pinocchio(mbm):
    env = _env(mbm, _first_valid(mbm, "box"))
    robot = env.robot
    from robointel.planning import _collision_kernels as K

    order = env.sphere_order
    s = env.scratch
    for q in robot.random_configuration(3, 20):
        K.sphere_centres(q, env.world, s.T, s.C, s.G)
        assert np.allclose(s.C, env.spheres.positions(q)[order], atol=1e-12)


def test_edge_check_keeps_its_guarantee(mbm):
    """An accepted edge keeps clearance >= thresh - res / 2 at every point (dense samples), and an edge whose
    dense samples all clear thresh by a margin is accepted, in both walk orders."""
    from robointel.planning import _collision_kernels as K
    from robointel.planning import _edge_kernels as E

    env = _env(mbm, _first_valid(mbm, "cage"))
    robot, s, W = env.robot, env.scratch, env.world
    rng = np.random.default_rng(5)
    thresh, res = 0.001, 0.02
    accepted = rejected = 0
    for _ in range(150):
        q0, q1 = robot.random_configuration(rng), robot.random_configuration(rng)
        if not (K.config_valid(q0, W, s.T, s.C, s.G, s.out, thresh) and K.config_valid(q1, W, s.T, s.C, s.G, s.out,
                                                                                           thresh)):
            continue
        gap = 0.004  # largest sphere travel between two dense samples, m
        k = int(np.ceil(K.travel(q0, q1, env.lever) / gap)) + 1
        d = min(env.clearance(q, cap=0.3) for q in q0 + np.linspace(0, 1, k)[:, None] * (q1 - q0))
        for check in (E.edge_valid, E.edge_valid_bisect):  # walked from q0; coarse to fine
            if check(q0, q1, W, s.T, s.C, s.G, s.out, thresh, env.lever, res):
                accepted += 1
                assert d >= thresh - res / 2 - 1e-9
            else:
                rejected += 1
                assert d < thresh + gap + 1e-9  # a checked point below thresh: a sample within gap / 2 of travel
    assert accepted > 10 and rejected > 10


@pytest.mark.parametrize("family", FAMILIES)
def test_mbm_problem_planned_and_rechecked(mbm, family):
    p = _first_valid(mbm, family)
    env = _env(mbm, p)
    plan = plan_motion(env.robot, env, p["start"], p["goals"], settings=MotionSettings(time_budget_s=30.0))
    assert plan.success, plan.reason
    assert plan.failure is Failure.NONE and plan.reason == ""
    _recheck(env, plan, p["start"], p["goals"][0], 0.0)


def test_mbm_with_clearance_and_jerk_limit(mbm):
    p = _first_valid(mbm, "box", 1)
    env = _env(mbm, p)
    st = MotionSettings(d_min=0.002, jerk_limited=True, time_budget_s=30.0)
    plan = plan_motion(env.robot, env, p["start"], p["goals"], settings=st)
    assert plan.success, plan.reason
    _recheck(env, plan, p["start"], p["goals"][0], 0.002)
    tr = plan.trajectory
    jerk = np.abs(np.diff(tr.qdd, axis=0) / np.diff(tr.t)[:, None])
    assert np.all(jerk <= 10 * env.robot.acceleration_limit * (1 + 1e-3))


def test_goal_set_first_reached_and_colliding_goals_dropped(mbm):
    p = _first_valid(mbm, "table_pick")
    env = _env(mbm, p)
    bad = next(q for q in env.robot.random_configuration(0, 200) if env.clearance(q) < 0)
    plan = plan_motion(env.robot, env, p["start"], [bad, p["goals"][0]])
    assert plan.success and plan.goal_index == 1
    assert np.allclose(plan.trajectory.q[-1], p["goals"][0])


def test_pose_goal_uses_ik_and_unreachable_pose_raises(mbm):
    p = _first_valid(mbm, "box")
    env = _env(mbm, p)
    robot = env.robot
    target = robot.fk(np.array(p["goals"][0]))
    plan = plan_motion(robot, env, p["start"], target, settings=MotionSettings(time_budget_s=30.0))
    assert plan.success, plan.reason
    assert np.allclose(robot.fk(plan.trajectory.q[-1]), target, atol=1e-6)
    far = target.copy()
    far[:3, 3] += [5.0, 0.0, 0.0]
    with pytest.raises(IKFailure):
        plan_motion(robot, env, p["start"], far)


def test_start_in_collision_names_link_and_obstacle(mbm):
    p = _first_valid(mbm, "box")
    env = _env(mbm, p)
    robot = env.robot
    q = np.array(p["goals"][0])
    tcp = robot.frame_pose(q, "tool0")[:3, 3]
    env2 = Environment(robot, _obstacles(p) + [Sphere(center=tcp, radius=0.05, name="intruder")])
    with pytest.raises(CollisionAtStart, match="intruder"):
        plan_motion(robot, env2, q, p["start"])
    folded = next(q for q in robot.random_configuration(0, 500) if env.contact(q).self_collision
                  and env.contact(q).distance < 0)
    with pytest.raises(CollisionAtStart, match="from link"):
        plan_motion(robot, env, folded, p["goals"][0])


def test_bad_input_and_time_budget(mbm):
    p = _first_valid(mbm, "cage")
    env = _env(mbm, p)
    robot = env.robot
    with pytest.raises(NotFinite):
        plan_motion(robot, env, [np.nan] * 6, p["goals"][0])
    with pytest.raises(InvalidInput):
        plan_motion(robot, env, p["start"], np.zeros(5))
    with pytest.raises(InvalidInput):
        plan_motion(robot, env, p["start"], p["goals"][0], settings=MotionSettings(d_min=-1.0))
    with pytest.raises(InvalidInput):
        Environment(robot, [1, 2])
    plan = plan_motion(robot, env, p["start"], p["goals"][0],
                       settings=MotionSettings(time_budget_s=1e-6, search_resolution=0.002))
    if not plan.success:  # a direct edge may still exist; otherwise the budget stops the search
        assert plan.failure is Failure.TIMEOUT and "time budget" in plan.reason


def test_srdf_unknown_link_is_skipped_with_a_warning_and_a_malformed_entry_raises(mbm, tmp_path):
    root, robot, _ = mbm
    bad = tmp_path / "bad.srdf"
    bad.write_text('<robot name="x"><disable_collisions link1="base_link" link2="nope" reason="x"/></robot>')
    with pytest.warns(DescriptionWarning, match="nope"):
        env = Environment(robot, [], srdf=bad)
    assert env.disabled == set()
    bad.write_text('<robot name="x"><disable_collisions link1="base_link" reason="x"/></robot>')
    with pytest.raises(InvalidInput, match=r"bad\.srdf.*disable_collisions.*link2"):
        Environment(robot, [], srdf=bad)


def test_point_cloud_matches_primitives_and_updates(mbm):
    p = _first_valid(mbm, "box")
    env = _env(mbm, p)
    rng = np.random.default_rng(0)
    pts = []
    for o in env.obstacles:  # points on the surfaces of the boxes (the box family has one cylinder too)
        if isinstance(o, Box):
            u = rng.uniform(-1, 1, (20000, 3))
            ax = rng.integers(0, 3, len(u))
            u[np.arange(len(u)), ax] = np.sign(u[np.arange(len(u)), ax])
            pts.append(o.center + (u * o.half) @ o.rotation.T)
    cloud = np.vstack(pts)
    boxes = [o for o in env.obstacles if isinstance(o, Box)]
    root = mbm[0]
    env_b = Environment(env.robot, boxes, srdf=root / "ur5.srdf", spheres=root / "ur5_spherized.urdf")
    env_c = Environment(env.robot, [PointCloud(cloud[:10])], srdf=root / "ur5.srdf",
                        spheres=root / "ur5_spherized.urdf")
    env_c.update_pointcloud(cloud)
    for q in env.robot.random_configuration(1, 30):
        db, dc = env_b.clearance(q, cap=0.3), env_c.clearance(q, cap=0.3)
        assert dc >= db - 1e-9  # surface points lie in the solids
        if db > -0.01:  # outside (or barely inside) the solids the cloud is within its spacing
            assert dc <= db + 0.02
    plan = plan_motion(env.robot, env_c, p["start"], p["goals"][0], settings=MotionSettings(time_budget_s=30.0))
    assert plan.success, plan.reason


def test_attached_object_and_any_arm():
    robot = Robot.load("lrmate200id7l")
    wall = Box(center=[0.45, 0.0, 0.4], size=[0.05, 0.6, 0.3], name="wall")
    env = Environment(robot, [wall], floor=0.0)
    tool = Environment(robot, [wall], floor=0.0, attached=[Box(center=[0, 0, 0.1], size=[0.05, 0.05, 0.2])])
    assert len(tool.spheres) > len(env.spheres)
    q0 = np.array([0.9, 0.3, 0.0, 0.0, -0.5, 0.0])
    q1 = np.array([-0.9, 0.3, 0.0, 0.0, -0.5, 0.0])
    for e in (env, tool):
        plan = plan_motion(robot, e, q0, q1, settings=MotionSettings(d_min=0.01, time_budget_s=30.0))
        assert plan.success, plan.reason
        tr = plan.trajectory.resample(1e-3)
        assert min(e.clearance(q) for q in tr.q[::10]) >= 0.01 - 1e-3


def test_covering_spheres_bound_the_exact_mesh_distance(mbm):
    from robointel.planning.exact_geometry import MeshGeometry

    p = _first_valid(mbm, "bookshelf_thin")
    env = _env(mbm, p)
    mg = MeshGeometry(env.robot, env.obstacles)
    checked = 0
    rng = np.random.default_rng(5)
    for q in np.array(p["goals"][0]) + rng.normal(0.0, 0.1, (40, 6)):  # near a goal among the shelves
        c = env.contact(q, cap=0.3)
        if c.self_collision or c.distance >= 0.3:
            continue
        hull, _, _ = mg.clearance(q, cap=0.5, thresh=-1.0)  # hull distances (lower bounds)
        mesh, _, _ = mg.clearance(q, cap=0.5, thresh=1.0)  # refined on the meshes
        assert hull <= mesh + 1e-5  # (penetration depths are estimates in coal)
        assert c.distance <= mesh + 1e-3  # the covering spheres never overstate the mesh clearance
        checked += 1
    assert checked >= 5
