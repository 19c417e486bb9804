"""Trajectory files and scene files: round trips and bad input."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput, NotFinite, ShapeError
from robointel.io.trajectory import load_trajectory, save_trajectory
from robointel.planning.scene import builtin_scenes, load_scene, scene_from_dict
from robointel.trajectory import Trajectory


def test_trajectory_validation_and_resample(tmp_path):
    t = np.array([0.0, 1.0, 2.0])
    q = np.array([[0.0, 0.0], [1.0, 0.5], [2.0, 0.0]])
    qd = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]])
    tr = Trajectory(t, q, qd, np.zeros_like(q), ["a", "b"])
    d = tr.resample(0.001)
    assert d.t[-1] == pytest.approx(2.0) and len(d.t) == 2001
    np.testing.assert_allclose(d.q[::1000], q, atol=1e-12)
    with pytest.raises(InvalidInput):
        Trajectory([0.0, 0.0, 1.0], q, qd, qd)
    with pytest.raises(NotFinite):
        Trajectory(t, q * np.nan, qd, qd)
    with pytest.raises(ShapeError):
        Trajectory(t, q, qd[:2], qd)
    with pytest.raises(InvalidInput):
        save_trajectory(tr, tmp_path / "x.csv")
    with pytest.raises(InvalidInput):
        load_trajectory(tmp_path / "missing.npz")


def test_scene_round_trip_and_pose_waypoints(tmp_path):
    assert "table71" in builtin_scenes()
    s = load_scene("table71")
    p = s.save(tmp_path / "copy.yaml")
    s2 = load_scene(p)
    np.testing.assert_allclose(s2.waypoints, s.waypoints, atol=1e-9)
    assert s2.dt == pytest.approx(s.dt) and s2.steps == s.steps
    np.testing.assert_allclose(s2.vmax, s.vmax)
    # a pose waypoint is solved by IK
    T = s.robot.fk(s.waypoints[1])
    from robointel.geometry.rotations import matrix_to_rpy

    d = {"robot": "lrmate200id7l", "dt": 0.1, "steps": 10,
         "waypoints": [{"q": s.waypoints[0].tolist()},
                       {"name": "p", "pose": {"xyz": T[:3, 3].tolist(), "rpy": matrix_to_rpy(T[:3, :3]).tolist()}}]}
    sc = scene_from_dict(d)
    np.testing.assert_allclose(sc.robot.fk(sc.waypoints[1])[:3, 3], T[:3, 3], atol=1e-6)
    with pytest.raises(InvalidInput, match="steps"):
        scene_from_dict(dict(d, steps=[10, 10]))
    with pytest.raises(InvalidInput, match="dt or operational_time"):
        scene_from_dict({k: v for k, v in d.items() if k != "dt"})
    with pytest.raises(InvalidInput, match="unknown planner"):
        scene_from_dict(dict(d, planner={"bogus": 1}))
