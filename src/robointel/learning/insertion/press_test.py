"""The honesty check of the contact physics: press the device's peg into the hole along its axis."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robointel.geometry.rotations import rotation_about
from robointel.learning.insertion.hdd_scene import HDDScene
from robointel.learning.insertion.peg_hole import PegHole, tip_point


@dataclass(frozen=True)
class PressResult:
    """What :func:`press_test` measured.

    Attributes:
        inserted: Tip within 1 mm of the bottom.
        height: Final tip height above the bottom (m).
        max_penetration: Deepest wall penetration (m).
        axial_force: Axial contact force at the end (N).
    """

    inserted: bool
    height: float
    max_penetration: float
    axial_force: float


def press_test(task: PegHole, *, interference: float = 0.0, force: float = 100.0, duration: float = 4.0,
               lateral: float = 0.0, tilt: float = 0.0) -> PressResult:
    """Press the device's peg into the hole with up to ``force`` N along the hole axis.

    The hand is a stiff spring whose reference sinks at 10 mm/s to 20 mm below the bottom, laterally
    compliant. With ``interference`` > 0 the peg is larger than the hole: an honest simulation must not let
    it in.

    Args:
        task: The peg-hole.
        interference: Diametral oversize of the peg (m).
        force: Largest axial push (N).
        duration: Pressing time (s).
        lateral: Lateral start offset along x (m).
        tilt: Start tilt about y (rad).

    Returns:
        The result.
    """
    tool = task.tool(interference=interference)
    scene = HDDScene(task, tool)
    T = task.pre_insert_pose(tool, height=0.001)
    T[:3, :3] = rotation_about(np.array([0.0, 1.0, 0.0]), tilt) @ T[:3, :3]
    T[:3, 3] = np.array(task.top) + np.array([lateral, 0.0, 0.001]) - T[:3, 2] * tool.tip
    scene.reset(T)
    dt = float(scene.model.opt.timestep)
    z0 = T[:3, 3].copy()
    max_pen = 0.0
    mg = np.array([0, 0, scene.mass * 9.81])
    for k in range(int(duration / dt)):
        P = scene.pose()
        v, w = scene.twist()
        ref = z0 - np.array([0, 0, min(0.01 * k * dt, task.depth + 0.02)])
        e = ref - P[:3, 3]
        fz = float(np.clip(20000 * e[2] - 150 * v[2], -force, force))
        f = np.array([300 * e[0] - 20 * v[0], 300 * e[1] - 20 * v[1], fz]) + mg
        scene.step(f, -0.05 * w)
        max_pen = max(max_pen, scene.wall_penetration())
    h = float(tip_point(scene.pose(), tool)[2] - task.bottom_z)
    return PressResult(h <= 1e-3, h, max_pen, float(-scene.wrench()[2]))
