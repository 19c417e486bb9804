"""A MuJoCo model generated from the robot's own URDF (one source of truth), plus the workcell.

:func:`build_spec` loads ``robot.urdf`` with :class:`mujoco.MjSpec` and adds, without changing
the robot:

* motor (torque) actuators on every joint, ``ctrlrange`` = the URDF effort limits;
* a tool body ``"tool"`` welded to the flange frame, carrying the optional :class:`Payload`, and a
  6-axis force/torque sensor (MuJoCo ``force`` + ``torque`` sensors on the site ``"ft_sensor"``,
  placed at and aligned with the flange frame);
* the built-in workcell: a table whose top is the plane z = 0 under the robot's ``base_link``
  (so **the MuJoCo world frame is the robot root frame**, identity transform) and a floor
  :data:`TABLE_HEIGHT` below it;
* obstacles (``robointel.geometry`` shapes) as geoms on mocap bodies (movable at no cost with
  :meth:`Workcell.set_obstacle_pose`), and objects as free bodies (:class:`SimObject`).

The robot part is MuJoCo's reading of the URDF as written (:func:`robointel.sim.mujoco_urdf.robot_spec`),
with gravity (0, 0, -9.81).
"""
from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from robointel._validate import as_array
from robointel.errors import DescriptionError, InvalidInput
from robointel.geometry.table import TABLE_EXTENTS, TABLE_HEIGHT, TABLE_THICKNESS  # noqa: F401 (re-exported)
from robointel.sim.mujoco_urdf import robot_spec

if TYPE_CHECKING:  # pragma: no cover
    from robointel.robot import Robot
GRAVITY = (0.0, 0.0, -9.81)

ROBOT_RGBA = (1.0, 0.78, 0.05, 1.0)  # FANUC yellow
ROBOT_CONTYPE = 1
ENV_CONTYPE, ENV_CONAFFINITY = 2, 3
TOOL_BODY = "tool"
FT_SITE = "ft_sensor"
OBSTACLE_PREFIX = "obstacle/"
OBJECT_PREFIX = "object/"


@dataclass(frozen=True)
class Payload:
    """A rigid tool/payload mounted after the F/T sensor.

    Args:
        mass: kg (> 0).
        com: centre of mass in the flange (sensor) frame, (3,) m.
        inertia: 3x3 rotational inertia about the CoM in the flange frame (kg m^2); default: a
            solid sphere of radius ``radius``.
        radius: radius (m) of the sphere geom drawn for the payload (and of the default inertia).
        collide: whether the payload geom takes part in contacts (contact forces on it are felt by
            the F/T sensor, e.g. a peg in a hole).
        shape: optional ``robointel.geometry`` Sphere/Capsule/Cylinder/Box in the flange frame
            used as the payload's geom instead of the sphere (its mass is still ``mass`` at ``com``).
    """

    mass: float
    com: Sequence[float] = (0.0, 0.0, 0.0)
    inertia: Any = None
    radius: float = 0.03
    collide: bool = False
    shape: Any = None

    def checked(self) -> tuple[float, np.ndarray, np.ndarray]:
        """Mass (kg), centre of mass (3,) m and inertia (3, 3) kg m^2 about it, validated."""
        m = float(self.mass)
        if not np.isfinite(m) or m <= 0:
            raise InvalidInput(f"payload mass must be a positive number of kg, got {self.mass!r}", value=self.mass)
        com = as_array(self.com, "payload.com", (3,))
        if self.inertia is None:
            inertia = np.eye(3) * 0.4 * m * float(self.radius) ** 2
        else:
            inertia = as_array(self.inertia, "payload.inertia", (3, 3))
            if not np.allclose(inertia, inertia.T, atol=1e-12) or np.linalg.eigvalsh(inertia).min() <= 0:
                raise InvalidInput("payload.inertia must be symmetric positive definite (kg m^2)", value=self.inertia)
        return m, com, inertia


@dataclass
class SimObject:
    """A free rigid body in the workcell.

    Args:
        name: unique name (the MuJoCo body is ``"object/<name>"``).
        shape: a ``robointel.geometry`` shape (Sphere, Capsule, Cylinder, Box; its placement gives
            the initial pose), a ``trimesh.Trimesh`` or a mesh file path (vertices in the body
            frame; collisions use its convex hull).
        mass: kg (> 0).
        pose: initial 4x4 pose of the body (meshes; for shapes, composed after the shape's own
            placement). Default identity.
        friction: sliding friction coefficient.
        rgba: colour.
    """

    name: str
    shape: Any
    mass: float
    pose: Any = None
    friction: float = 1.0
    rgba: Sequence[float] = (0.9, 0.6, 0.2, 1.0)


# ---------------------------------------------------------------------------------------- helpers
def _quat_from_matrix(R: np.ndarray) -> np.ndarray:
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).reshape(9))
    return q


def _frame_z_to(axis: np.ndarray) -> np.ndarray:
    """Quaternion of a frame whose z axis is ``axis`` (unit)."""
    q = np.empty(4)
    mujoco.mju_quatZ2Vec(q, np.asarray(axis, dtype=float))
    return q


def _kind(shape: Any) -> str:
    t = getattr(type(shape), "type", None)
    return t if isinstance(t, str) else type(shape).__name__.lower()


def shape_geoms(shape: Any, *, max_points: int = 2000) -> tuple[np.ndarray, list[dict]]:
    """MuJoCo geoms for a ``robointel.geometry`` shape.

    Returns the body position (3,) (the shape's reference point in the world) and a list of geom
    dicts (``type``, ``size``, ``pos``, ``quat`` relative to the body). Point clouds become small
    spheres (radius ``max(cloud.radius, 5 mm)``), uniformly subsampled to ``max_points`` with a
    warning.

    Raises:
        InvalidInput: not a supported shape.
    """
    kind = _kind(shape)
    G = mujoco.mjtGeom
    ident = np.array([1.0, 0, 0, 0])
    if kind == "sphere":
        c = as_array(shape.center, "sphere.center", (3,))
        return c, [dict(type=G.mjGEOM_SPHERE, size=[float(shape.radius), 0, 0], pos=np.zeros(3), quat=ident)]
    if kind in ("capsule", "cylinder"):
        a = as_array(shape.a, f"{kind}.a", (3,))
        b = as_array(shape.b, f"{kind}.b", (3,))
        r = float(shape.radius)
        c = 0.5 * (a + b)
        L = float(np.linalg.norm(b - a))
        if L < 1e-12:
            if kind == "cylinder":
                raise InvalidInput("cylinder with a == b has no axis; give distinct end points", value=shape)
            return c, [dict(type=G.mjGEOM_SPHERE, size=[r, 0, 0], pos=np.zeros(3), quat=ident)]
        t = G.mjGEOM_CAPSULE if kind == "capsule" else G.mjGEOM_CYLINDER
        return c, [dict(type=t, size=[r, 0.5 * L, 0], pos=np.zeros(3), quat=_frame_z_to((b - a) / L))]
    if kind == "box":
        c = as_array(shape.center, "box.center", (3,))
        size = as_array(shape.size, "box.size", (3,))
        R = as_array(getattr(shape, "rotation", np.eye(3)), "box.rotation", (3, 3))
        return c, [dict(type=G.mjGEOM_BOX, size=0.5 * size, pos=np.zeros(3), quat=_quat_from_matrix(R))]
    if kind == "pointcloud":
        P = as_array(shape.points, "pointcloud.points", (None, 3))
        if len(P) == 0:
            raise InvalidInput("point cloud obstacle has no points", value=shape)
        if len(P) > max_points:
            warnings.warn(f"point cloud with {len(P)} points subsampled to {max_points} spheres in MuJoCo",
                          stacklevel=3)
            P = P[np.linspace(0, len(P) - 1, max_points).astype(int)]
        r = max(float(getattr(shape, "radius", 0.0) or 0.0), 0.005)
        c = P.mean(axis=0)
        return c, [dict(type=G.mjGEOM_SPHERE, size=[r, 0, 0], pos=p - c, quat=ident) for p in P]
    raise InvalidInput(
        f"unsupported obstacle type {type(shape).__name__}; use robointel.geometry Sphere, Capsule, Cylinder, "
        "Box or PointCloud", value=shape)


def shape_name(shape: Any, default: str) -> str:
    """The name of an obstacle shape, or ``default`` if it has none."""
    n = getattr(shape, "name", None)
    return str(n) if n else default


# ---------------------------------------------------------------------------------------- builder
def build_spec(robot: Robot, *, table: bool = True, obstacles: Sequence[Any] = (), objects: Sequence[SimObject] = (),
               ft_sensor: bool = True, payload: Payload | None = None, timestep: float = 0.001,
               armature: ArrayLike | None = None, self_collision: bool = False) -> tuple[mujoco.MjSpec, dict]:
    """Build the MuJoCo spec of the workcell from ``robot.urdf``.

    Args:
        robot: a :class:`robointel.robot.Robot`.
        table: add the table (top at z = 0, the robot's mounting plane) and the floor.
        obstacles: ``robointel.geometry`` shapes, world frame; each becomes a mocap body
            ``"obstacle/<name>"`` with geom(s) ``"obstacle/<name>"`` (``/<i>`` for point clouds).
        objects: :class:`SimObject` free bodies.
        ft_sensor: add the F/T sensor (``force`` and ``torque`` sensors on site ``"ft_sensor"``).
        payload: optional :class:`Payload` on the tool body, after the sensor.
        timestep: physics step (s).
        armature: optional (n,) rotor inertia reflected to each joint (kg m^2); default 0, which
            keeps M(q) identical to the robot core's.
        self_collision: let robot geoms collide with each other (MuJoCo always skips
            parent-child pairs). Off by default: the built-in LR Mate's primitive collision
            geometry overlaps between link_2 and link_4 in most configurations.

    Contact filtering: robot geoms have ``contype=1`` and ``conaffinity=2`` (``3`` with
    ``self_collision``); environment geoms (table, floor, obstacles, objects) ``contype=2``,
    ``conaffinity=3``; so the robot touches the environment, objects touch everything.

    Returns:
        (spec, info): ``info`` maps ``"obstacles"`` -> list of names, ``"objects"`` -> names,
        ``"flange_body"`` -> the link carrying the flange.
    """
    if not (np.isfinite(timestep) and 1e-5 <= timestep <= 0.01):
        raise InvalidInput(f"timestep must be within [1e-5, 0.01] s, got {timestep!r}", value=timestep)
    spec = robot_spec(robot)
    spec.modelname = f"robointel_{robot.name}"
    spec.compiler.discardvisual = False  # URDF visuals are already dropped by the parser; keep our textures
    spec.option.gravity = np.array(GRAVITY)
    spec.option.timestep = float(timestep)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.visual.global_.offwidth = 1280
    spec.visual.global_.offheight = 960

    for g in spec.geoms:  # only the robot's geoms exist at this point
        g.contype, g.conaffinity = ROBOT_CONTYPE, (3 if self_collision else 2)
        g.rgba = list(ROBOT_RGBA)
    joints = [spec.joint(n) for n in robot.joint_names]
    if any(j is None for j in joints):
        raise DescriptionError("MuJoCo's model lacks some of the robot core's joints", value=robot.joint_names)
    if armature is not None:
        arm = as_array(armature, "armature", (robot.nq,))
        if np.any(arm < 0):
            raise InvalidInput("armature must be >= 0 (kg m^2)", value=armature)
        for j, a in zip(joints, arm):
            j.armature = float(a)
    for j in joints:
        # Coulomb friction (frictionloss) as a nearly hard constraint: MuJoCo's default soft
        # friction lets a light joint (the LR Mate's J6: 2e-5 kg m^2) creep at (1 - d) tau / (J d b)
        # rad/s under any torque below the friction level; d = 0.9999 and a 2-step time constant
        # make it behave like the URDF's dry friction.
        j.solref_friction = [2.0 * float(timestep), 1.0]
        j.solimp_friction = [0.9999, 0.9999, 0.001, 0.5, 2.0]
    for _j, name, eff in zip(joints, robot.joint_names, robot.effort_limit):
        act = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_motor()
        if np.isfinite(eff) and eff > 0:
            act.ctrlrange = [-float(eff), float(eff)]
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        else:
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE

    # ---- tool body + F/T sensor at the flange frame
    flange_body, T_body_flange = _flange_body(robot)
    fb = spec.body(flange_body)
    if fb is None:
        raise DescriptionError(f"the flange frame {flange_body!r} is not a URDF link; MuJoCo needs a body there",
                               value=flange_body)
    tool = fb.add_body(name=TOOL_BODY, pos=T_body_flange[:3, 3], quat=_quat_from_matrix(T_body_flange[:3, :3]))
    if payload is not None:
        m, com, inertia = payload.checked()
        tool.mass = m
        tool.ipos = com
        tool.fullinertia = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
        tool.explicitinertial = True
        if payload.shape is None:
            geoms = [dict(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[float(payload.radius), 0, 0], pos=com,
                          quat=np.array([1.0, 0, 0, 0]))]
        else:
            if _kind(payload.shape) not in ("sphere", "capsule", "cylinder", "box"):
                raise InvalidInput("payload.shape must be a Sphere, Capsule, Cylinder or Box", value=payload.shape)
            pos, geoms = shape_geoms(payload.shape)
            for g in geoms:
                g["pos"] = g["pos"] + pos
        for g in geoms:
            geom = tool.add_geom(name="payload", type=g["type"], size=g["size"], pos=g["pos"], quat=g["quat"],
                                 rgba=[0.3, 0.3, 0.8, 1.0], mass=0.0)
            geom.contype, geom.conaffinity = ((ROBOT_CONTYPE, 3 if self_collision else 2) if payload.collide
                                              else (0, 0))
    if ft_sensor:
        tool.add_site(name=FT_SITE, size=[0.01, 0, 0], rgba=[1, 0, 0, 1])
        spec.add_sensor(name="ft_force", type=mujoco.mjtSensor.mjSENS_FORCE, objtype=mujoco.mjtObj.mjOBJ_SITE,
                        objname=FT_SITE)
        spec.add_sensor(name="ft_torque", type=mujoco.mjtSensor.mjSENS_TORQUE, objtype=mujoco.mjtObj.mjOBJ_SITE,
                        objname=FT_SITE)

    # ---- table and floor (static world geoms)
    wb = spec.worldbody
    if table:
        x0, x1, y0, y1 = TABLE_EXTENTS
        wb.add_geom(name="table", type=mujoco.mjtGeom.mjGEOM_BOX,
                    size=[(x1 - x0) / 2, (y1 - y0) / 2, TABLE_THICKNESS / 2],
                    pos=[(x1 + x0) / 2, (y1 + y0) / 2, -TABLE_THICKNESS / 2], rgba=[0.55, 0.42, 0.3, 1],
                    contype=ENV_CONTYPE, conaffinity=ENV_CONAFFINITY)
        tex = spec.add_texture(name="grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                               builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, rgb1=[0.82, 0.82, 0.82],
                               rgb2=[0.7, 0.7, 0.7], width=256, height=256)
        mat = spec.add_material(name="grid", texrepeat=[8, 8], reflectance=0.05)
        mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = tex.name
        wb.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[3, 3, 0.1],
                    pos=[0, 0, -TABLE_HEIGHT], material="grid",
                    contype=ENV_CONTYPE, conaffinity=ENV_CONAFFINITY)
    wb.add_light(name="light", pos=[0.5, -1.0, 2.5], dir=[-0.2, 0.4, -1.0], diffuse=[0.7, 0.7, 0.7])
    spec.add_texture(name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
                     rgb1=[0.75, 0.85, 0.95], rgb2=[0.2, 0.25, 0.3], width=256, height=256)
    spec.visual.headlight.ambient = [0.35, 0.35, 0.35]

    # ---- obstacles on mocap bodies
    names: list[str] = []
    for i, shape in enumerate(obstacles):
        name = shape_name(shape, f"obstacle_{i}")
        if name in names:
            raise InvalidInput(f"duplicate obstacle name {name!r}; give each obstacle a unique name", value=name)
        names.append(name)
        pos, geoms = shape_geoms(shape)
        body = wb.add_body(name=OBSTACLE_PREFIX + name, pos=pos, mocap=True)
        for k, g in enumerate(geoms):
            gname = OBSTACLE_PREFIX + name + ("" if len(geoms) == 1 else f"/{k}")
            body.add_geom(name=gname, type=g["type"], size=g["size"], pos=g["pos"], quat=g["quat"],
                          rgba=[0.8, 0.2, 0.2, 0.6], contype=ENV_CONTYPE, conaffinity=ENV_CONAFFINITY)

    # ---- free objects
    onames: list[str] = []
    for obj in objects:
        if not isinstance(obj, SimObject):
            raise InvalidInput(f"objects must be robointel.sim.SimObject, got {type(obj).__name__}", value=obj)
        if obj.name in onames or obj.name in names:
            raise InvalidInput(f"duplicate object name {obj.name!r}", value=obj.name)
        onames.append(obj.name)
        _add_object(spec, obj)
        # an inactive weld tool -> object, switched on by Workcell.grasp (relative pose set then)
        spec.add_equality(name=OBJECT_PREFIX + obj.name, type=mujoco.mjtEq.mjEQ_WELD, objtype=mujoco.mjtObj.mjOBJ_BODY,
                          name1=TOOL_BODY, name2=OBJECT_PREFIX + obj.name, active=False,
                          solref=[4.0 * float(timestep), 1.0], solimp=[0.99, 0.999, 0.001, 0.5, 2.0])
    return spec, {"obstacles": names, "objects": onames, "flange_body": flange_body}


def _flange_body(robot: Robot) -> tuple[str, np.ndarray]:
    """The MuJoCo body of the flange frame (every URDF link is a body.

    No static fusing) and the flange pose in it (identity).
    """
    return robot.flange_frame, np.eye(4)


def _add_object(spec: mujoco.MjSpec, obj: SimObject) -> None:
    m = float(obj.mass)
    if not np.isfinite(m) or m <= 0:
        raise InvalidInput(f"object {obj.name!r}: mass must be positive (kg), got {obj.mass!r}", value=obj.mass)
    pose = np.eye(4) if obj.pose is None else as_array(obj.pose, f"object {obj.name!r} pose", (4, 4))
    kind = _kind(obj.shape)
    if kind in ("sphere", "capsule", "cylinder", "box"):
        pos, geoms = shape_geoms(obj.shape)
        T = pose.copy()
        T[:3, 3] = pose[:3, :3] @ pos + pose[:3, 3]
        body = spec.worldbody.add_body(name=OBJECT_PREFIX + obj.name, pos=T[:3, 3], quat=_quat_from_matrix(T[:3, :3]))
        body.add_freejoint(name=OBJECT_PREFIX + obj.name)
        g = geoms[0]
        body.add_geom(name=OBJECT_PREFIX + obj.name, type=g["type"], size=g["size"], pos=g["pos"], quat=g["quat"],
                      mass=m, rgba=list(obj.rgba), friction=[float(obj.friction), 0.005, 0.0001],
                      contype=ENV_CONTYPE, conaffinity=ENV_CONAFFINITY)
        return
    import trimesh

    mesh = obj.shape
    if isinstance(mesh, (str, Path)):
        try:
            mesh = trimesh.load(str(mesh), force="mesh")
        except Exception as exc:
            raise InvalidInput(f"object {obj.name!r}: cannot load mesh {obj.shape!r}: {exc}", value=obj.shape) from None
    if not isinstance(mesh, trimesh.Trimesh):
        raise InvalidInput(f"object {obj.name!r}: shape must be a geometry shape, a trimesh.Trimesh or a mesh path",
                           value=obj.shape)
    solid = mesh if mesh.is_watertight and mesh.volume > 0 else mesh.convex_hull
    com = np.asarray(solid.center_mass, dtype=float)
    inertia = np.asarray(solid.moment_inertia, dtype=float) * (m / solid.mass)  # about the CoM, body frame
    mname = OBJECT_PREFIX + obj.name
    spec.add_mesh(name=mname, uservert=np.asarray(mesh.vertices, dtype=np.float32).ravel(),
                  userface=np.asarray(mesh.faces, dtype=np.int32).ravel())
    body = spec.worldbody.add_body(name=mname, pos=pose[:3, 3], quat=_quat_from_matrix(pose[:3, :3]))
    body.add_freejoint(name=mname)
    body.mass = m
    body.ipos = com
    body.fullinertia = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    body.explicitinertial = True
    body.add_geom(name=mname, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=mname, rgba=list(obj.rgba),
                  friction=[float(obj.friction), 0.005, 0.0001], mass=0.0, density=0.0,
                  contype=ENV_CONTYPE, conaffinity=ENV_CONAFFINITY)


def build_model(robot: Robot, **kwargs: Any) -> tuple[mujoco.MjModel, dict]:
    """Compile :func:`build_spec` into an ``MjModel`` (same arguments)."""
    spec, info = build_spec(robot, **kwargs)
    try:
        model = spec.compile()
    except Exception as exc:
        raise DescriptionError(f"MuJoCo could not compile the workcell: {exc}") from None
    return model, info
