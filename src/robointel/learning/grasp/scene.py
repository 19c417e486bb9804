"""MuJoCo scenes for grasping: a table, placed objects and (optionally) a parallel-jaw gripper.

The table top is the plane ``z = 0`` (world), centred at ``TABLE_CENTRE``. Each placed object has
its scan mesh as a visual geom in group 1 (what the depth cameras see; no contacts) and its convex
pieces as collision geoms in group 3. With ``dynamic=True`` the objects are free bodies; the gripper
follows a mocap target (its pose is commanded each step, e.g. from the LR Mate's forward kinematics) with
(a free body welded to a mocap target, so that the motion has velocity and friction acts) with
two slide-jointed fingers driven by force-limited position actuators.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robointel.learning.grasp.objects import ObjectModel
from robointel.learning.grasp.quality import ParallelGripper

__all__ = ["Placement", "scene_xml", "TABLE_CENTRE", "TABLE_HALF", "random_placements"]

TABLE_CENTRE = np.array([0.5, 0.0])
TABLE_HALF = np.array([0.35, 0.45])


@dataclass
class Placement:
    """An object placed on the table: position (x, y) of its frame origin and heading ``yaw`` (rad)."""

    obj: ObjectModel
    x: float
    y: float
    yaw: float

    @property
    def pose(self) -> np.ndarray:
        T = np.eye(4)
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
        T[:3, 3] = [self.x, self.y, 0.0]
        return T


def random_placements(objects, rng, *, region=((0.4, 0.6), (-0.15, 0.15)), min_gap: float = 0.03,
                      tries: int = 200) -> list[Placement]:
    """Place ``objects`` at random positions and headings in ``region`` without overlapping footprints."""
    rng = np.random.default_rng(rng)
    out: list[Placement] = []
    for o in objects:
        r = 0.5 * float(np.linalg.norm(o.mesh.extents[:2]))
        for _ in range(tries):
            x, y = rng.uniform(*region[0]), rng.uniform(*region[1])
            ok = all(np.hypot(x - p.x, y - p.y) > r + 0.5 * float(np.linalg.norm(p.obj.mesh.extents[:2])) + min_gap
                     for p in out)
            if ok:
                break
        out.append(Placement(o, float(x), float(y), float(rng.uniform(-np.pi, np.pi))))
    return out


def _fmt(a) -> str:
    return " ".join(f"{v:.6g}" for v in np.asarray(a, float).ravel())


def _quat_yaw(yaw: float) -> str:
    return _fmt([np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)])


def scene_xml(placements: list[Placement], *, dynamic: bool = False, gripper: ParallelGripper | None = None,
              timestep: float = 0.002, friction: float = 1.0, grip_force: float = 20.0) -> str:
    """MJCF text of the scene (see module docstring)."""
    assets, bodies = [], []
    for i, p in enumerate(placements):
        o = p.obj
        assets.append(f'<mesh name="scan{i}" vertex="{_fmt(o.mesh.vertices)}" face="{" ".join(map(str, o.mesh.faces.ravel()))}"/>')
        geoms = [f'<geom type="mesh" mesh="scan{i}" group="1" contype="0" conaffinity="0" rgba=".8 .5 .3 1" mass="0"/>']
        for j, piece in enumerate(o.pieces):
            assets.append(f'<mesh name="p{i}_{j}" vertex="{_fmt(piece.vertices)}"/>')
            geoms.append(f'<geom type="mesh" mesh="p{i}_{j}" group="3" friction="{friction} 0.02 0.001" '
                         f'condim="6" rgba=".3 .6 .9 .3" density="0"/>')
        mass = max(o.mass, 0.01)
        com = o.mesh.bounds.mean(axis=0) if not o.mesh.is_watertight else o.mesh.center_mass
        ext = np.maximum(o.mesh.extents, 0.01)
        inertia = mass / 12 * np.array([ext[1] ** 2 + ext[2] ** 2, ext[0] ** 2 + ext[2] ** 2, ext[0] ** 2 + ext[1] ** 2])
        joint = f'<freejoint name="obj{i}"/>' if dynamic else ""
        inert = f'<inertial pos="{_fmt(com)}" mass="{mass:.4g}" diaginertia="{_fmt(inertia)}"/>' if dynamic else ""
        bodies.append(f'<body name="obj{i}" pos="{p.x:.6g} {p.y:.6g} 0.0005" quat="{_quat_yaw(p.yaw)}">{joint}{inert}'
                      + "".join(geoms) + "</body>")
    grip = ""
    act = ""
    if gripper is not None:
        g = gripper
        fb = np.array([g.finger_breadth, g.finger_thickness, g.finger_length]) / 2
        zc = g.tip_depth - g.finger_length / 2
        y0 = g.max_width / 2 + g.finger_thickness / 2
        palm_z = g.tip_depth - g.finger_length - g.palm_height / 2
        palm = np.array([g.palm_breadth, g.max_width + 2 * g.finger_thickness, g.palm_height]) / 2
        fingers = ""
        for name, s in (("fp", 1.0), ("fn", -1.0)):
            fingers += (f'<body name="{name}" pos="0 {s * y0:.6g} {zc:.6g}"><joint name="{name}" type="slide" axis="0 {-s:.0f} 0" '
                        f'range="0 {g.max_width / 2:.6g}" damping="200" armature="0.01"/>'
                        f'<geom type="box" size="{_fmt(fb)}" mass="0.05" friction="{friction} 0.02 0.001" condim="6" '
                        f'rgba=".2 .2 .2 1"/></body>')
        grip = (f'<body name="target" mocap="true" pos="0.5 0 1.6"/>'
                f'<body name="gripper" pos="0.5 0 1.6"><freejoint name="gripper"/>'
                f'<geom type="box" pos="0 0 {palm_z:.6g}" mass="{g.mass:.4g}" '
                f'size="{_fmt(palm)}" rgba=".4 .4 .4 1" contype="0" conaffinity="0"/>{fingers}</body>')
        act = ("<actuator>" + "".join(
            f'<position name="a{n}" joint="{n}" kp="3000" ctrlrange="0 {g.max_width / 2:.6g}" '
            f'forcerange="{-grip_force} {grip_force}"/>' for n in ("fp", "fn")) + "</actuator>")
        act += ('<equality><joint joint1="fp" joint2="fn" polycoef="0 1 0 0 0" solref="0.005 1"/>'
                '<weld body1="target" body2="gripper" solref="0.004 1"/></equality>')
    return f"""<mujoco model="grasp">
  <option timestep="{timestep}" gravity="0 0 -9.81" cone="elliptic" impratio="5" integrator="implicitfast"/>
  <asset>{"".join(assets)}</asset>
  <worldbody>
    <geom name="table" type="box" pos="{TABLE_CENTRE[0]} {TABLE_CENTRE[1]} -0.02" size="{TABLE_HALF[0]} {TABLE_HALF[1]} 0.02"
          rgba=".7 .7 .7 1" friction="{friction} 0.02 0.001"/>
    {"".join(bodies)}
    {grip}
  </worldbody>
  {act}
</mujoco>"""
