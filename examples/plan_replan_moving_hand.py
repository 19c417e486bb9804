"""Receding-horizon replanning while a hand reaches into the robot's path.

    python examples/plan_replan_moving_hand.py
"""
import numpy as np

from robointel.geometry import Sphere
from robointel.planning import planner_settings, receding_horizon
from robointel.planning.scene import load_scene

scene = load_scene("table71")
start, stop = np.array([0.62, 0.16, 0.75]), np.array([0.62, 0.16, 0.30])  # the hand comes down and stays
hand = Sphere(start, 0.06, name="hand")
settings = planner_settings(scene)
settings.max_iter = 10  # bound the time per re-plan
res = receding_horizon(scene.robot, scene.obstacles, hand, lambda t: start + (stop - start) * min(1.0, t / 1.5),
                       scene.waypoints[0], scene.waypoints[1], N=19, dt=scene.dt, ticks=30, settings=settings,
                       vmax=scene.vmax, amax=scene.amax)
print(f"{res.hz:.0f} Hz (median {np.median(res.times_ms):.1f} ms per re-plan), "
      f"all plans clear: {bool(res.feasible.all())}, closest {res.min_distance.min() * 1000:.1f} mm")
