"""Obstacle shapes, distances with gradients, rotations."""
