"""Scene files: round trips and bad input."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.planning.scene import builtin_scenes, load_scene, scene_from_dict


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
