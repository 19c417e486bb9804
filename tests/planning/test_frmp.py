"""The FRMP on the Table 7.1 workcell: scene file, plan, dense checks, MuJoCo execution; scene errors."""
from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np
import pytest
import yaml

from robointel.errors import CollisionAtStart, InvalidInput, LimitViolation, NotFinite
from robointel.io.trajectory import load_trajectory, save_trajectory
from robointel.outcome import Failure
from robointel.planning.frmp import check_trajectory, execute, plan_scene
from robointel.planning.scene import SCENES, load_scene, scene_from_dict


@pytest.fixture(scope="module")
def scene():
    return load_scene("table71")


@pytest.fixture(scope="module")
def result(scene):
    return plan_scene(scene)


@pytest.fixture(scope="module")
def raw():
    return yaml.safe_load((SCENES / "table71.yaml").read_text())


def test_table71_scene_shape(scene):
    assert len(scene.waypoints) == 6 and scene.steps == [19] * 5 and scene.total_steps == 95
    assert scene.fixed_time == pytest.approx(15.0)
    assert [o.name for o in scene.obstacles] == ["box_A", "box_B", "table", "floor"]  # + the workcell


def test_frmp_plan_is_collision_free_within_limits_and_faster(scene, result):
    assert result.blocked == [False, False, True, True, False]
    assert all(s.feasible for s in result.segments)
    # every segment ran CFS, and the blocked ones needed more than one iteration
    assert all(s.iterations >= 1 for s in result.segments)
    assert all(s.iterations >= 2 for s, b in zip(result.segments, result.blocked) if b)
    assert result.check.min_clearance >= scene.d_min - 1e-3
    assert result.check.limit_violations == 0
    assert result.operational_time_fixed == pytest.approx(15.0)
    assert result.operational_time_frmp < 0.6 * result.operational_time_fixed
    # the trajectory stops at every waypoint and passes through it
    tr = result.trajectory
    for w in scene.waypoints:
        k = int(np.argmin(np.linalg.norm(tr.q - w, axis=1)))
        np.testing.assert_allclose(tr.q[k], w, atol=1e-9)
        np.testing.assert_allclose(tr.qd[k], 0.0, atol=1e-9)
    # independent re-check with a denser grid
    chk = check_trajectory(tr, scene.robot, scene.obstacles, scene.vmax, scene.amax, dt=0.0005)
    assert chk.limit_violations == 0 and chk.min_clearance >= scene.d_min - 1e-3
    out = result.outcome
    assert out.success and out.figures["min_clearance_m"] == result.check.min_clearance
    assert out.figures["duration_s"] == pytest.approx(result.operational_time_frmp)
    hit = replace(result, check=replace(result.check, min_clearance=-0.001)).outcome
    assert not hit.success and hit.reason is Failure.COLLISION
    fast = replace(result, check=replace(result.check, limit_violations=3)).outcome
    assert not fast.success and fast.reason is Failure.LIMIT


def test_frmp_executes_in_mujoco_without_touching_obstacles(result):
    ex = execute(result)
    assert not ex.collided and ex.obstacle_contacts == 0
    assert ex.min_distance_m > 0.0
    assert ex.max_error_rad < 0.01 and ex.max_tcp_error_m < 0.005
    assert ex.outcome.success and ex.outcome.figures["obstacle_contacts"] == 0
    assert replace(ex, collided=True, obstacle_contacts=4).outcome.reason is Failure.COLLISION


def test_trajectory_file_round_trip(result, tmp_path):
    for suffix in (".npz", ".json"):
        p = save_trajectory(result.trajectory, tmp_path / f"traj{suffix}")
        back = load_trajectory(p)
        np.testing.assert_allclose(back.q, result.trajectory.q)
        np.testing.assert_allclose(back.t, result.trajectory.t)
        assert back.joint_names == result.trajectory.joint_names


def test_scene_errors(raw):
    d = copy.deepcopy(raw)
    d["waypoints"][2] = {"name": "lift", "q_deg": [0.0, 40.0, -10.0, 0.0, -40.0, 0.0]}  # inside box_A
    with pytest.raises(CollisionAtStart, match="box_A"):
        plan_scene(scene_from_dict(d))
    d = copy.deepcopy(raw)
    d["waypoints"][1]["q_deg"][1] = float("nan")
    with pytest.raises(InvalidInput):
        scene_from_dict(d)
    d = copy.deepcopy(raw)
    d["waypoints"][1] = {"name": "far", "pose": {"xyz": [2.0, 0.0, 0.3], "rpy_deg": [0, 90, 0]}}
    with pytest.raises(InvalidInput, match="unreachable"):
        scene_from_dict(d)
    d = copy.deepcopy(raw)
    d["limits"] = {"velocity_scale": 0.0}
    with pytest.raises(LimitViolation, match="impossible"):
        scene_from_dict(d)
    d = copy.deepcopy(raw)
    d["waypoints"][0]["q_deg"][1] = 170.0
    with pytest.raises(LimitViolation, match="home"):
        scene_from_dict(d)
    with pytest.raises(InvalidInput):
        load_scene("no_such_scene")


def test_nan_rejected_by_planner(scene):
    from robointel.planning.frmp import make_planners

    pl = make_planners(scene)[19]
    with pytest.raises(NotFinite):
        pl.plan_segment(scene.waypoints[0], np.full(6, np.nan))
