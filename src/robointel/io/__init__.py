"""Files: reference data, demonstrations, grasp databases, scenes, trajectories."""
