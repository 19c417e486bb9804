"""The workcell's fixed environment as collision obstacles: the table the robot stands on and the floor.

The table top is the plane z = 0 of the robot's root frame (the robot's mounting plane); the floor
is ``TABLE_HEIGHT`` below it. The same numbers build the MuJoCo table (``robointel.sim.mjcf``), so
the planner, the streaming interface and the guidance controller check the table the simulated
robot would hit.
"""
from __future__ import annotations

import numpy as np

from robointel.geometry.obstacles import Box

#: Height of the table top above the floor (m). The table top is z = 0 of the world frame.
TABLE_HEIGHT = 0.75
#: Table top extents (x_min, x_max, y_min, y_max) in the world frame (m) and thickness (m).
TABLE_EXTENTS = (-0.4, 1.0, -0.7, 0.7)
TABLE_THICKNESS = 0.05
#: Names of the environment obstacles (scene files leave them out: they are implied by ``table: true``).
ENVIRONMENT_NAMES = ("table", "floor")


def table_obstacles(extents: tuple[float, float, float, float] = TABLE_EXTENTS,
                    height: float = TABLE_HEIGHT) -> list[Box]:
    """The table and the floor as boxes for the sphere collision model.

    The table is modelled as a solid block from its top (z = 0) down to the floor (nothing the arm
    may reach lives under the top), the floor as a 0.1 m slab under z = -``height`` reaching 3 m
    in x and y.

    Args:
        extents: (x_min, x_max, y_min, y_max) of the table top in the robot root frame, m.
        height: table top above the floor, m.

    Returns:
        ``[table, floor]`` :class:`~robointel.geometry.obstacles.Box` obstacles named
        ``"table"`` and ``"floor"``.
    """
    x0, x1, y0, y1 = extents
    table = Box(center=np.array([(x0 + x1) / 2, (y0 + y1) / 2, -height / 2]),
                size=np.array([x1 - x0, y1 - y0, height]), name="table")
    floor = Box(center=np.array([0.0, 0.0, -height - 0.05]), size=np.array([6.0, 6.0, 0.1]), name="floor")
    return [table, floor]
