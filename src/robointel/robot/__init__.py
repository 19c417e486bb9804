"""Robot core (Ch. 2): model loading, kinematics, IK, dynamics, collision spheres."""
from robointel.robot.collision import SphereModel
from robointel.robot.model import Robot, builtin_names, example_robot_urdf

__all__ = ["Robot", "SphereModel", "builtin_names", "example_robot_urdf"]
