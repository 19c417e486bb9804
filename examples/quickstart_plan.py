import numpy as np

from robointel.geometry import Box
from robointel.planning import Environment, MotionSettings, plan_motion
from robointel.robot import Robot, example_robot_urdf

urdf = example_robot_urdf("ur5")                  # or the path of your own arm's URDF file
robot = Robot.load(urdf)                          # kinematics, limits, spheres fitted to its collision meshes
box = Box(center=[0.5, 0.0, 0.25], size=[0.2, 0.2, 0.5], name="box")   # metres, robot base frame
env = Environment(robot, [box], srdf=urdf.parent.parent / "srdf" / "ur5.srdf")

start = np.array([-0.8, -1.2, 1.4, -1.8, -1.57, 0.0])  # rad: the tool on one side of the box ...
goal = np.array([0.8, -1.2, 1.4, -1.8, -1.57, 0.0])    # ... and on the other
plan = plan_motion(robot, env, start, goal, settings=MotionSettings(d_min=0.02, time_budget_s=5.0))
assert plan.success, plan.reason

traj = plan.trajectory                            # t, q, qd, qdd: checked every 1 ms for clearance and limits
print(f"planned in {plan.plan_ms:.0f} ms: {traj.duration:.2f} s of motion, "
      f"clearance >= {plan.min_clearance_m * 1e3:.0f} mm")
