"""Robot core in a minute: load the LR Mate, FK, Jacobians, all IK branches, dynamics, spheres,
and a short tracked motion in the MuJoCo workcell.

    python examples/robot_core.py
"""
import numpy as np

from robointel.robot import Robot
from robointel.sim import Workcell

robot = Robot.load("lrmate200id7l")
q = np.array([0.2, 0.3, -0.2, 0.5, -0.8, 1.0])

T = robot.fk(q)
print("TCP position [m]:", np.round(T[:3, 3], 4))
print("all IK branches within limits:", len(robot.ik(T)))
print("joint solution closest to q recovers it:", np.allclose(robot.ik(T, q_ref=q)[0], q))

J_rep = robot.point_jacobian(q, "link_4", [0.2, 0.0, 0.0])[:3]  # a control point on the forearm
print("J_rep shape:", J_rep.shape)

print("gravity torques [N m]:", np.round(robot.gravity(q), 2))
P, Js = robot.spheres.kinematics(q)
print(f"{len(P)} collision spheres, Jacobians {Js.shape}")

# a one-second rest-to-rest move, tracked by PID + feed-forward at 1 kHz in MuJoCo
t = np.linspace(0.0, 1.0, 1001)
s = 10 * t**3 - 15 * t**4 + 6 * t**5
q_goal = q + np.array([0.4, -0.2, 0.3, 0.0, 0.3, -0.5])
traj = q + s[:, None] * (q_goal - q)
cell = Workcell(robot)
log = cell.run_trajectory(t, traj)
print("tracking RMS per joint [rad]:", np.array2string(log.rms_error, precision=6))
