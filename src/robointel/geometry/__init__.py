"""Obstacle shapes, distances with gradients, rotations.

Shapes: :class:`Sphere`, :class:`Capsule`, :class:`Cylinder`, :class:`Box`, :class:`PointCloud`,
each with ``distance(points) -> (d, closest, normal)`` (signed, negative inside).
Robot distances: :func:`sphere_distances`, :func:`sphere_distances_batch`, :func:`min_distance`, :func:`closest_pairs`,
:func:`self_collision_distance`, :func:`in_collision`, :func:`check_collision_free`.
"""
from robointel.geometry import rotations
from robointel.geometry.distance import (
    ClosestPairs,
    Collision,
    MinDistance,
    ObstacleSet,
    SelfDistance,
    SphereDistances,
    check_collision_free,
    closest_pairs,
    in_collision,
    min_distance,
    self_collision_distance,
    sphere_distances,
    sphere_distances_batch,
    warmup,
)
from robointel.geometry.obstacles import (
    OBSTACLE_TYPES,
    Box,
    Capsule,
    Cylinder,
    Obstacle,
    PointCloud,
    Sphere,
    obstacle_from_dict,
)

__all__ = [
    "Obstacle", "Sphere", "Capsule", "Cylinder", "Box", "PointCloud", "OBSTACLE_TYPES", "obstacle_from_dict",
    "ObstacleSet", "SphereDistances", "MinDistance", "ClosestPairs", "closest_pairs", "SelfDistance", "Collision",
    "sphere_distances", "sphere_distances_batch", "min_distance", "self_collision_distance",
    "in_collision", "check_collision_free", "warmup", "rotations",
]
