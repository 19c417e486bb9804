"""Receding-horizon replanning with a moving obstacle; the OMPL peer on a blocked segment."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.geometry import Sphere, sphere_distances_batch
from robointel.planning.frmp import planner_settings
from robointel.planning.replan import receding_horizon
from robointel.planning.scene import load_scene


@pytest.fixture(scope="module")
def scene():
    return load_scene("table71")


def test_replanning_keeps_clear_of_a_moving_hand(scene):
    stop, s0 = np.array([0.62, 0.16, 0.30]), np.array([0.62, 0.16, 0.75])
    hand = Sphere(s0, 0.06, name="hand")
    st = planner_settings(scene)
    st.max_iter = 10
    move = lambda t: s0 + (stop - s0) * min(1.0, t / 1.5)  # noqa: E731
    res = receding_horizon(scene.robot, scene.obstacles, hand, move, scene.waypoints[0], scene.waypoints[1],
                           N=19, dt=scene.dt, ticks=14, settings=st, vmax=scene.vmax, amax=scene.amax)
    assert res.feasible.all()
    assert res.min_distance.min() >= st.d_min - 1e-9
    # the straight line would hit the hand where it stops: replanning really had to change the path
    X = np.linspace(scene.waypoints[0], scene.waypoints[1], 20)
    assert sphere_distances_batch(scene.robot, X, [hand.moved(stop)], movable_only=True).d.min() < st.d_min
    # every executed configuration is clear of the hand where it was when that step was planned
    planned_with = [s0] + list(res.obstacle_path[:-1])
    for x, c in zip(res.executed[1:], planned_with):
        d = sphere_distances_batch(scene.robot, x[None], [hand.moved(c)] + list(scene.obstacles), movable_only=True)
        assert d.d.min() >= st.d_min - 1e-6
    assert res.hz > 0
    assert res.outcome.success and res.outcome.figures["ticks"] == 14
    assert res.outcome.figures["min_distance_m"] == float(res.min_distance.min())


def test_ompl_rrtconnect_finds_clear_path(scene):
    pytest.importorskip("ompl")
    from robointel.planning.ompl_peer import rrtconnect

    st = planner_settings(scene)
    clearance = st.d_min + st.safety
    r = rrtconnect(scene.robot, scene.obstacles, scene.waypoints[2], scene.waypoints[3], clearance=clearance,
                   timeout=10.0, seed=0)
    assert r.solved and len(r.path) >= 2
    np.testing.assert_allclose(r.path[0], scene.waypoints[2], atol=1e-9)
    np.testing.assert_allclose(r.path[-1], scene.waypoints[3], atol=1e-9)
    d = sphere_distances_batch(scene.robot, r.path, scene.obstacles, movable_only=True)
    assert d.d.min() >= clearance - 1e-9
