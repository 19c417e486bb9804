"""MuJoCo worlds built from the robot description: scenes, sensors, controllers."""
