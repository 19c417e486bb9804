"""The hand-held demonstration device (HDD, Sec. 5.2) and the tool it shares with the robot.

The HDD is a handle, a 6-axis F/T sensor and a tool (here a round peg or a grinding stylus), tracked
in 6-D. In MuJoCo it is a free ``handle`` body (where the person's hand pushes) with a rigidly
attached ``hdd_tool`` body carrying the sensor site and the tool geoms; MuJoCo's ``force``/``torque``
sensors at that site measure the wrench between handle and tool exactly like the real sensor. The
same :class:`Tool` is mounted on the robot's flange (see :mod:`robointel.learning.insertion`), so
demonstration and reproduction share one tool frame.

Tool frame: origin at the sensor, z along the tool axis toward the tip. The wrench reported by
:func:`tool_wrench` is the force and torque the environment exerts on the tool (gravity of the tool
removed), in the tool frame, torque about the sensor origin: [f (N), tau (N m)].
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from robointel.errors import InvalidInput

TOOL_SITE = "tool_ft"
GRAVITY = np.array([0.0, 0.0, -9.81])


@dataclass(frozen=True)
class Contact:
    """Stiff contact settings for tight fits (Sec.

    5.5): MuJoCo ``solref`` (time constant, damping ratio), ``solimp`` (dmin, dmax, width (m), midpoint, power),
    friction coefficient, torsional friction (m: torque per unit normal force), zero margin. The impedance width
    must stay below the radial clearance so that the peg cannot sink into the wall by more than a fraction of the
    gap.
    """

    solref: tuple[float, float] = (0.002, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.9999, 0.99999, 5e-6, 0.5, 2.0)
    friction: float = 0.2
    margin: float = 0.0
    torsional: float = 0.005

    def apply(self, geom: Any) -> None:
        """Set these parameters on an ``MjsGeom``."""
        geom.solref = list(self.solref)
        geom.solimp = list(self.solimp)
        geom.friction = [self.friction, self.torsional, 0.0001]
        geom.margin = self.margin
        geom.gap = 0.0
        geom.condim = 4  # sliding + torsional friction (elliptic cone)


@dataclass(frozen=True)
class Tool:
    """A round peg.

    ``radius`` (m), cylindrical ``length`` (m) with a hemispherical tip, mounted ``offset`` (m) after the sensor
    along the tool z axis; ``mass`` (kg) of the tool after the sensor. The tip point is at z = offset + length +
    radius.
    """

    radius: float = 0.0127
    length: float = 0.06
    offset: float = 0.03
    mass: float = 0.3
    name: str = "peg"

    def __post_init__(self) -> None:
        for k in ("radius", "length", "offset", "mass"):
            v = getattr(self, k)
            if not np.isfinite(v) or v <= 0:
                raise InvalidInput(f"tool {k} must be a positive number, got {v!r}", value=v)

    @property
    def tip(self) -> float:
        """Tip distance from the sensor along z (m)."""
        return self.offset + self.length + self.radius

    @property
    def com(self) -> np.ndarray:
        """Centre of mass in the tool frame (m)."""
        return np.array([0.0, 0.0, self.offset + 0.5 * self.length])

    def add_to(self, body: Any, contact: Contact, *, R_body_tool: ArrayLike | None = None,
               p_body_tool: ArrayLike | None = None, contype: int = 1, conaffinity: int = 2) -> Any:
        """Add the tool (a child body ``<name>`` with the sensor site and geoms) to an ``MjsBody``.

        Args:
            body: The parent ``mujoco.MjsBody``.
            contact: Contact parameters of the tool's geoms.
            R_body_tool: (3, 3) tool orientation in the body frame (default identity).
            p_body_tool: (3,) tool origin in the body frame, m (default 0).
            contype: MuJoCo contact type bits of the geoms.
            conaffinity: MuJoCo contact affinity bits of the geoms.

        Returns:
            The new ``MjsBody``.
        """
        R_body_tool = np.eye(3) if R_body_tool is None else R_body_tool
        p_body_tool = np.zeros(3) if p_body_tool is None else np.asarray(p_body_tool, float)
        q = np.empty(4)
        mujoco.mju_mat2Quat(q, np.ascontiguousarray(R_body_tool, dtype=float).ravel())
        tb = body.add_body(name=self.name, pos=list(p_body_tool), quat=q)
        tb.mass = self.mass
        tb.ipos = self.com
        r, L = self.radius, self.length
        ixx = self.mass * (3 * r * r + L * L) / 12
        tb.inertia = [ixx, ixx, 0.5 * self.mass * r * r]
        tb.explicitinertial = True
        tb.add_site(name=TOOL_SITE, size=[0.005, 0, 0], rgba=[1, 0, 0, 1])
        # adapter between sensor and peg (no contact)
        tb.add_geom(name=self.name + "/adapter", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                    size=[0.03, 0.5 * self.offset, 0], pos=[0, 0, 0.5 * self.offset], rgba=[0.3, 0.3, 0.3, 1],
                    contype=0, conaffinity=0, mass=0, density=0)
        g = tb.add_geom(name=self.name + "/peg", type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[r, 0.5 * L, 0],
                        pos=[0, 0, self.offset + 0.5 * L], rgba=[0.75, 0.75, 0.8, 1], mass=0, density=0,
                        contype=contype, conaffinity=conaffinity)
        contact.apply(g)
        return tb


def add_tool_sensors(spec: mujoco.MjSpec) -> None:
    """The F/T sensor at the tool site (``tool_force``, ``tool_torque``)."""
    spec.add_sensor(name="tool_force", type=mujoco.mjtSensor.mjSENS_FORCE, objtype=mujoco.mjtObj.mjOBJ_SITE,
                    objname=TOOL_SITE)
    spec.add_sensor(name="tool_torque", type=mujoco.mjtSensor.mjSENS_TORQUE, objtype=mujoco.mjtObj.mjOBJ_SITE,
                    objname=TOOL_SITE)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """3-vector cross product (np.cross is slow for single vectors in a 1 kHz loop)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


class ToolFT:
    """The simulated F/T sensor of a tool in a compiled model (ids cached for 1 kHz loops)."""

    def __init__(self, model: mujoco.MjModel, tool: Tool) -> None:
        self.tool = tool
        self.site = model.site(TOOL_SITE).id
        self.fadr = int(model.sensor_adr[model.sensor("tool_force").id])
        self.tadr = int(model.sensor_adr[model.sensor("tool_torque").id])

    def pose(self, data: mujoco.MjData) -> np.ndarray:
        """4x4 world pose of the tool frame (the sensor site)."""
        T = np.eye(4)
        T[:3, :3] = data.site_xmat[self.site].reshape(3, 3)
        T[:3, 3] = data.site_xpos[self.site]
        return T

    def wrench(self, data: mujoco.MjData, R: np.ndarray | None = None) -> np.ndarray:
        """Environment wrench on the tool in the tool frame (6,) [f.

        Tau about the sensor], from the simulated F/T sensor with the tool's weight removed (static F/T
        compensation, Sec. 3.3).
        """
        # MuJoCo reports the force the parent exerts on the tool body (site frame): quasi-statically
        # it balances the environment wrench and the tool's weight.
        R = data.site_xmat[self.site].reshape(3, 3) if R is None else R
        g_tool = R.T @ (self.tool.mass * GRAVITY)
        f = -data.sensordata[self.fadr:self.fadr + 3] - g_tool
        t = -data.sensordata[self.tadr:self.tadr + 3] - cross(self.tool.com, g_tool)
        return np.concatenate([f, t])


def tool_pose(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """4x4 world pose of the tool frame (the sensor site)."""
    sid = model.site(TOOL_SITE).id
    T = np.eye(4)
    T[:3, :3] = data.site_xmat[sid].reshape(3, 3)
    T[:3, 3] = data.site_xpos[sid]
    return T


def tool_wrench(model: mujoco.MjModel, data: mujoco.MjData, tool: Tool) -> np.ndarray:
    """Environment wrench on the tool, tool frame (6,); see :meth:`ToolFT.wrench`."""
    return ToolFT(model, tool).wrench(data)
