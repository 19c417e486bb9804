"""Robot core (Ch. 2): model loading, kinematics, IK, dynamics, collision spheres."""
from robointel.robot.catalogue import builtin_names, example_robot_urdf
from robointel.robot.collision import SphereModel
from robointel.robot.model import Robot

__all__ = ["Robot", "SphereModel", "builtin_names", "example_robot_urdf"]
