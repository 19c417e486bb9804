"""MuJoCo scenes for grasping: a table, placed objects and (optionally) a parallel-jaw gripper.

The table top is the plane ``z = 0`` (world), centred at ``TABLE_CENTRE``. Each placed object has
its scan mesh as a visual geom in group 1 (what the depth cameras see; no contacts) and its convex
pieces as collision geoms in group 3. With ``dynamic=True`` the objects are free bodies; the gripper
(without the arm) follows a mocap target (its pose is commanded each step, e.g. from the LR Mate's
forward kinematics; a free body welded to the mocap target, so that the motion has velocity and
friction acts) with two slide-jointed fingers driven by force-limited position actuators.
:func:`arm_scene` puts the whole LR Mate (from its URDF) in the scene instead, the gripper on its flange.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import mujoco
import numpy as np
import numpy.typing as npt

from robointel.learning.grasp.objects import ObjectModel
from robointel.learning.grasp.quality import ParallelGripper
from robointel.sim.mjcf import build_spec, shape_geoms, shape_name

if TYPE_CHECKING:
    from robointel.geometry.obstacles import Obstacle
    from robointel.robot import Robot

__all__ = ["FINGER_KP", "FINGER_SOLREF", "Placement", "scene_xml", "TABLE_CENTRE", "TABLE_HALF", "close_command",
           "random_placements"]

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
        """4x4 world pose of the object frame (resting on the table plane)."""
        T = np.eye(4)
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
        T[:3, 3] = [self.x, self.y, 0.0]
        return T


def random_placements(objects: Sequence[ObjectModel], rng: np.random.Generator | int | None, *,
                      region: tuple[tuple[float, float], tuple[float, float]] = ((0.4, 0.6), (-0.15, 0.15)),
                      min_gap: float = 0.03,
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


#: Position gain of each finger's drive (N/m); its force is limited to the gripper's ``grip_force``.
FINGER_KP = 3000.0

#: Contact time constant and damping ratio of the finger pads (MuJoCo ``solref``; the pads' geoms have
#: priority, so their contacts with a part use it). MuJoCo's default (0.02 s, 1) scales the contact's
#: stiffness with the part's mass: a 0.1 kg toy arm squeezed with 20 N let the pad corners sink 1.3-5.9 mm
#: into it, and the part pivoted about the sunk edges in the lift and the shake. 0.004 s (twice the 2 ms step,
#: the stiffest MuJoCo advises) leaves ~0.25 mm: rigid pads on a rigid part.
FINGER_SOLREF = (0.004, 1.0)


def close_command(gripper: ParallelGripper, grip_force: float | None = None) -> float:
    """The finger travel command (m) that closes the jaws with the full grip force on any part.

    A real electric gripper closes until its set force is reached and holds it, whatever the part's
    width. A position drive commanded to the closed end (``max_width / 2``) pushes with
    ``FINGER_KP`` x the travel left, which falls below ``grip_force`` on thin parts (15 N instead of 20 N
    on a 10 mm spoon handle in the 48 mm gripper); the command lies ``grip_force / FINGER_KP`` past the
    closed end, so the drive saturates at ``grip_force`` until the fingers meet.

    Args:
        gripper: The gripper.
        grip_force: The drive's force limit (N per finger; default ``gripper.grip_force``).

    Returns:
        The command (m of travel per finger; the joints stop at ``max_width / 2``).
    """
    force = gripper.grip_force if grip_force is None else grip_force
    return gripper.max_width / 2 + force / FINGER_KP


def _fmt(a: npt.ArrayLike) -> str:
    return " ".join(f"{v:.6g}" for v in np.asarray(a, float).ravel())


def _quat_yaw(yaw: float) -> str:
    return _fmt([np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)])


def scene_xml(placements: list[Placement], *, dynamic: bool = False, gripper: ParallelGripper | None = None,
              timestep: float = 0.002, friction: float = 1.0, grip_force: float | None = None) -> str:
    """MJCF text of the scene (see module docstring); ``grip_force`` (N per finger): the gripper's."""
    assets, bodies = [], []
    for i, p in enumerate(placements):
        o = p.obj
        faces = " ".join(map(str, o.mesh.faces.ravel()))
        assets.append(f'<mesh name="scan{i}" vertex="{_fmt(o.mesh.vertices)}" face="{faces}"/>')
        geoms = [f'<geom type="mesh" mesh="scan{i}" group="1" contype="0" conaffinity="0" rgba=".8 .5 .3 1" mass="0"/>']
        for j, piece in enumerate(o.pieces):
            assets.append(f'<mesh name="p{i}_{j}" vertex="{_fmt(piece.vertices)}"/>')
            geoms.append(f'<geom type="mesh" mesh="p{i}_{j}" group="3" friction="{friction} 0.02 0.001" '
                         f'condim="6" rgba=".3 .6 .9 .3" density="0"/>')
        mass = max(o.mass, 0.01)
        com = o.mesh.bounds.mean(axis=0) if not o.mesh.is_watertight else o.mesh.center_mass
        ext = np.maximum(o.mesh.extents, 0.01)
        inertia = mass / 12 * np.array([ext[1] ** 2 + ext[2] ** 2, ext[0] ** 2 + ext[2] ** 2,
                                        ext[0] ** 2 + ext[1] ** 2])
        joint = f'<freejoint name="obj{i}"/>' if dynamic else ""
        inert = f'<inertial pos="{_fmt(com)}" mass="{mass:.4g}" diaginertia="{_fmt(inertia)}"/>' if dynamic else ""
        bodies.append(f'<body name="obj{i}" pos="{p.x:.6g} {p.y:.6g} 0.0005" quat="{_quat_yaw(p.yaw)}">{joint}{inert}'
                      + "".join(geoms) + "</body>")
    grip = ""
    act = ""
    if gripper is not None:
        g = gripper
        grip_force = g.grip_force if grip_force is None else grip_force
        fb = np.array([g.finger_breadth, g.finger_thickness, g.finger_length]) / 2
        zc = g.tip_depth - g.finger_length / 2
        y0 = g.max_width / 2 + g.finger_thickness / 2
        palm_z = g.tip_depth - g.finger_length - g.palm_height / 2
        palm = np.array([g.palm_breadth, g.max_width + 2 * g.finger_thickness, g.palm_height]) / 2
        fingers = ""
        for name, s in (("fp", 1.0), ("fn", -1.0)):
            fingers += (f'<body name="{name}" pos="0 {s * y0:.6g} {zc:.6g}">'
                        f'<joint name="{name}" type="slide" axis="0 {-s:.0f} 0" '
                        f'range="0 {g.max_width / 2:.6g}" damping="200" armature="0.01"/>'
                        f'<geom type="box" size="{_fmt(fb)}" mass="0.05" friction="{friction} 0.02 0.001" condim="6" '
                        f'solref="{_fmt(FINGER_SOLREF)}" priority="1" rgba=".2 .2 .2 1"/></body>')
        grip = (f'<body name="target" mocap="true" pos="0.5 0 1.6"/>'
                f'<body name="gripper" pos="0.5 0 1.6"><freejoint name="gripper"/>'
                f'<geom type="box" pos="0 0 {palm_z:.6g}" mass="{g.mass:.4g}" '
                f'size="{_fmt(palm)}" rgba=".4 .4 .4 1" contype="0" conaffinity="0"/>{fingers}</body>')
        act = ("<actuator>" + "".join(
            f'<position name="a{n}" joint="{n}" kp="{FINGER_KP:g}" ctrlrange="0 {close_command(g, grip_force):.6g}" '
            f'forcerange="{-grip_force} {grip_force}"/>' for n in ("fp", "fn")) + "</actuator>")
        act += ('<equality><joint joint1="fp" joint2="fn" polycoef="0 1 0 0 0" solref="0.005 1"/>'
                '<weld body1="target" body2="gripper" solref="0.004 1"/></equality>')
    return f"""<mujoco model="grasp">
  <option timestep="{timestep}" gravity="0 0 -9.81" cone="elliptic" impratio="5" integrator="implicitfast"/>
  <asset>{"".join(assets)}</asset>
  <worldbody>
    <geom name="table" type="box" pos="{TABLE_CENTRE[0]} {TABLE_CENTRE[1]} -0.02"
          size="{TABLE_HALF[0]} {TABLE_HALF[1]} 0.02"
          rgba=".7 .7 .7 1" friction="{friction} 0.02 0.001"/>
    {"".join(bodies)}
    {grip}
  </worldbody>
  {act}
</mujoco>"""


#: Joint servo gains of the LR Mate in :func:`arm_scene` (N m/rad, N m s/rad), J1..J6.
ARM_KP = (3000.0, 3000.0, 2000.0, 300.0, 300.0, 150.0)
ARM_KV = (120.0, 120.0, 60.0, 6.0, 6.0, 3.0)
#: Reflected rotor inertia added to each joint (kg m^2): an assumption (the LR Mate's motor and gear data
#: are not public); it keeps the stiff wrist servos stable at the 2 ms physics step.
ARM_ARMATURE = (0.2, 0.2, 0.1, 0.02, 0.02, 0.01)


def arm_scene(placements: list[Placement], robot: Robot, gripper: ParallelGripper, *, timestep: float = 0.002,
              friction: float = 1.0, grip_force: float | None = None, kp: Sequence[float] = ARM_KP,
              kv: Sequence[float] = ARM_KV, armature: Sequence[float] = ARM_ARMATURE,
              obstacles: Sequence[Obstacle] = ()) -> mujoco.MjModel:
    """The grasp scene with the whole LR Mate and the gripper on its flange (compiled MjModel).

    The grasp scene with the whole robot: the table and free objects of :func:`scene_xml`, and the
    arm built from its URDF by :func:`robointel.sim.mjcf.build_spec` (root at the world origin, its
    links' collision geometry touching the table and the objects) carrying the parallel-jaw gripper
    on its flange at ``gripper.tool_transform()``. Each arm joint is driven by a position servo
    (``kp``, ``kv``; torque limited to the URDF effort limits) with the arm's gravity compensated
    (MuJoCo ``gravcomp``, the controller's gravity feed-forward); the held object is a real payload.
    Actuators: ``arm/joint_1..6`` (joint angle, rad) then ``arm/afp``, ``arm/afn`` (finger travel, m;
    0 = open, :func:`close_command` = closed with the full grip force); each finger's drive force is
    limited to ``grip_force`` (N, default the gripper's
    ``grip_force``). Any :class:`ParallelGripper` fits (the 48 mm or the 85 mm one). ``obstacles``:
    ``robointel.geometry`` shapes added as static bodies ``obstacle/<name>`` (fixtures the arm and the
    objects collide with). Returns the compiled ``MjModel``.
    """
    spec = mujoco.MjSpec.from_string(scene_xml(placements, dynamic=True, timestep=timestep, friction=friction))
    for i, shape in enumerate(obstacles):
        name = shape_name(shape, f"obstacle_{i}")
        pos, geoms = shape_geoms(shape)
        body = spec.worldbody.add_body(name="obstacle/" + name, pos=pos)
        for k, geom in enumerate(geoms):
            body.add_geom(name="obstacle/" + name + ("" if len(geoms) == 1 else f"/{k}"), type=geom["type"],
                          size=geom["size"], pos=geom["pos"], quat=geom["quat"], rgba=[0.8, 0.2, 0.2, 0.6])
    rs, _ = build_spec(robot, table=False, ft_sensor=False, timestep=timestep, armature=np.asarray(armature, float))
    for b in rs.bodies:
        if b.name != "world":
            b.gravcomp = 1.0
    for a, p, v, eff in zip(rs.actuators, kp, kv, robot.effort_limit):
        a.set_to_position(kp=float(p), kv=float(v))
        a.forcerange = [-float(eff), float(eff)]
        a.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    g = gripper
    grip_force = g.grip_force if grip_force is None else grip_force
    T = g.tool_transform()
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, T[:3, :3].ravel())
    gb = rs.body("tool").add_body(name="gripper", pos=T[:3, 3], quat=q)
    gb.gravcomp = 1.0
    palm = np.array([g.palm_breadth, g.max_width + 2 * g.finger_thickness, g.palm_height]) / 2
    gb.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=palm,
                pos=[0, 0, g.tip_depth - g.finger_length - g.palm_height / 2],
                mass=g.mass, rgba=[0.4, 0.4, 0.4, 1])
    fb = np.array([g.finger_breadth, g.finger_thickness, g.finger_length]) / 2
    zc = g.tip_depth - g.finger_length / 2
    y0 = g.max_width / 2 + g.finger_thickness / 2
    for name, s in (("fp", 1.0), ("fn", -1.0)):
        f = gb.add_body(name=name, pos=[0, s * y0, zc])
        f.gravcomp = 1.0
        f.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, -s, 0], range=[0, g.max_width / 2],
                    damping=200, armature=0.01)
        f.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=fb, mass=0.05, friction=[friction, 0.02, 0.001], condim=6,
                   solref=list(FINGER_SOLREF), priority=1, rgba=[0.2, 0.2, 0.2, 1])
        a = rs.add_actuator(name="a" + name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        a.set_to_position(kp=FINGER_KP)
        a.ctrlrange = [0, close_command(g, grip_force)]
        a.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        a.forcerange = [-grip_force, grip_force]
        a.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    rs.add_equality(type=mujoco.mjtEq.mjEQ_JOINT, name1="fp", name2="fn", data=[0, 1, 0, 0, 0] + [0] * 7,
                    solref=[0.005, 1])
    # the gripper touches the objects and the table; the robot's own links never touch the gripper
    for gname in ("gripper", "fp", "fn"):
        for link in ("link_5", "link_6", "flange", "tool0", "tool"):
            if rs.body(link) is not None:
                rs.add_exclude(bodyname1=link, bodyname2=gname)
    spec.worldbody.add_frame().attach_body(rs.worldbody.first_body(), "arm/", "")
    return spec.compile()
