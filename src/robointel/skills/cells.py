"""Simulated workcells for the skills on the ``sim`` backend: a peg over a hole, a stylus over a plate.

Both are the ordinary :class:`~robointel.sim.Workcell` (the LR Mate under its 1 kHz joint servo, the
flange F/T sensor): the tool is a colliding payload after the sensor (a capsule: a round peg with a
hemispherical tip), the hole is a square pocket of box obstacles whose side is the peg's diameter plus
the clearance, the plate a box. The skill sees the sensor through the robot interface only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput
from robointel.geometry.obstacles import Box, Capsule
from robointel.geometry.rotations import rotation_about
from robointel.robot import Robot
from robointel.sim import Workcell
from robointel.sim.mjcf import OBSTACLE_PREFIX, Payload

R_FLANGE_TOOL = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
"""Tool axes in the flange frame: the tool's z (insertion axis) is the flange's x (the J6 axis)."""
R_DOWN = np.diag([1.0, -1.0, -1.0])
"""Tool orientation pointing straight down (tool z = world -z)."""
Q_REF = np.array([0.0, 0.5, -0.4, 0.0, -0.7, 0.0])
"""IK reference posture over the table (elbow up, wrist down), rad."""


@dataclass(frozen=True)
class PegTool:
    """A round peg with a hemispherical tip after the F/T sensor.

    Attributes:
        radius: m. length: cylindrical length, m. offset: from the sensor to the cylinder's start, m.
        mass: kg.
    """

    radius: float = 0.0127
    length: float = 0.06
    offset: float = 0.03
    mass: float = 0.3

    def __post_init__(self) -> None:
        for k in ("radius", "length", "offset", "mass"):
            v = getattr(self, k)
            if not (np.isfinite(v) and v > 0):
                raise InvalidInput(f"PegTool.{k} must be > 0, got {v!r}", value=v)

    @property
    def centre(self) -> float:
        """Distance (m) from the sensor to the tip sphere's centre (the compliance centre, the TCP)."""
        return self.offset + self.length

    @property
    def tool_transform(self) -> npt.NDArray[np.float64]:
        """(4, 4) TCP in the flange frame: tool axes, origin at the tip sphere's centre."""
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R_FLANGE_TOOL, [self.centre, 0.0, 0.0]
        return T

    def payload(self) -> Payload:
        """The peg as a colliding :class:`~robointel.sim.mjcf.Payload` (a capsule along the flange x)."""
        a, b = np.array([self.offset, 0.0, 0.0]), np.array([self.centre, 0.0, 0.0])
        m, r, L = self.mass, self.radius, self.length
        inertia = np.diag([0.5 * m * r ** 2] + [m * (3 * r ** 2 + L ** 2) / 12] * 2)
        return Payload(m, 0.5 * (a + b), inertia=inertia, collide=True, shape=Capsule(a, b, r))

    def robot(self) -> Robot:
        """The LR Mate with this peg's TCP as its tool."""
        return Robot.load("lrmate200id7l", tool=self.tool_transform)


@dataclass(frozen=True)
class HoleTask:
    """A square pocket for the peg: side = peg diameter + ``clearance``, open at ``top`` (x, y, z) m.

    Attributes:
        clearance: diametral clearance, m. depth: m. top: the pocket's top centre, world, m.
        wall: wall thickness, m.
    """

    clearance: float = 0.5e-3
    depth: float = 0.03
    top: tuple[float, float, float] = (0.6, 0.0, 0.2)
    wall: float = 0.02

    def obstacles(self, peg: PegTool) -> list[Box]:
        """The bottom block and the four walls, world frame."""
        x, y, z = self.top
        a = peg.radius + 0.5 * self.clearance
        w, zb = self.wall, z - self.depth
        return [Box(np.array([x, y, zb / 2]), np.array([2 * a, 2 * a, zb]), name="hole_bottom"),
                Box(np.array([x + a + w / 2, y, z / 2]), np.array([w, 2 * a + 2 * w, z]), name="hole_px"),
                Box(np.array([x - a - w / 2, y, z / 2]), np.array([w, 2 * a + 2 * w, z]), name="hole_nx"),
                Box(np.array([x, y + a + w / 2, z / 2]), np.array([2 * a, w, z]), name="hole_py"),
                Box(np.array([x, y - a - w / 2, z / 2]), np.array([2 * a, w, z]), name="hole_ny")]

    def start_tcp(self, peg: PegTool, *, gap: float = 0.003, lateral: npt.ArrayLike = (0.0, 0.0),
                  tilt: tuple[float, float] = (0.0, 0.0)) -> npt.NDArray[np.float64]:
        """TCP pose (4, 4) with the tip ``gap`` m above the pocket, a lateral error (2,) m and a tilt.

        ``tilt`` = (phi, angle): ``angle`` rad about the horizontal axis at angle ``phi``, about the tip.
        """
        lat = np.asarray(lateral, dtype=float)
        tip = np.array([self.top[0] + lat[0], self.top[1] + lat[1], self.top[2] + gap])
        phi, ang = tilt
        R = rotation_about(np.array([np.cos(phi), np.sin(phi), 0.0]), ang) @ R_DOWN
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, tip - R[:, 2] * peg.radius
        return T

    def advance(self, gap: float = 0.003) -> float:
        """How far (m) the TCP travels along the axis from the start to the bottom."""
        return gap + self.depth


def peg_hole_workcell(peg: PegTool | None = None, hole: HoleTask | None = None) -> tuple[Workcell, Robot]:
    """The workcell with the peg on the flange and the pocket on the table, and the robot with the peg TCP.

    Returns:
        (workcell, robot): ``robot.tool`` is :attr:`PegTool.tool_transform`.
    """
    peg = peg or PegTool()
    hole = hole or HoleTask()
    robot = peg.robot()
    return Workcell(Robot.load("lrmate200id7l"), obstacles=hole.obstacles(peg), payload=peg.payload()), robot


@dataclass(frozen=True)
class PlateTask:
    """A flat plate (top surface at ``top`` m) centred at ``center`` (x, y) m, ``size`` (x, y) m."""

    center: tuple[float, float] = (0.6, 0.0)
    top: float = 0.12
    size: tuple[float, float] = (0.18, 0.18)

    def obstacles(self) -> list[Box]:
        """The plate on a pedestal, world frame."""
        cx, cy = self.center
        return [Box(np.array([cx, cy, self.top / 2]), np.array([self.size[0], self.size[1], self.top]), name="plate")]


def stylus() -> PegTool:
    """The grinding stylus: a 6 mm radius capsule tip, 40 mm long, 30 mm after the sensor, 0.2 kg."""
    return PegTool(radius=0.006, length=0.04, offset=0.03, mass=0.2)


PAD_SOLREF = (0.01, 1.0)
PAD_SOLIMP = (0.5, 0.99, 0.0002, 0.5, 2.0)
"""The grinding pad's contact (MuJoCo solref, solimp): 10 ms time constant, impedance rising from 0.5 at first
touch to 0.99 at 0.2 mm compression, as the plate of the grinding demonstrations."""


def plate_workcell(plate: PlateTask | None = None, tool: PegTool | None = None) -> tuple[Workcell, Robot]:
    """The workcell with the stylus on the flange over the plate (a compliant pad); the robot with the stylus TCP."""
    plate = plate or PlateTask()
    tool = tool or stylus()
    wc = Workcell(Robot.load("lrmate200id7l"), obstacles=plate.obstacles(), payload=tool.payload())
    g = wc.model.geom(OBSTACLE_PREFIX + "plate").id
    wc.model.geom_solref[g] = PAD_SOLREF
    wc.model.geom_solimp[g] = PAD_SOLIMP
    return wc, tool.robot()


def ik_near(robot: Robot, T: npt.NDArray[np.float64], q_ref: npt.ArrayLike = Q_REF) -> npt.NDArray[np.float64]:
    """The IK solution (6,) rad of TCP pose ``T`` (4, 4) closest to ``q_ref``."""
    return np.asarray(robot.ik(T, q_ref=np.asarray(q_ref, dtype=float))[0])
