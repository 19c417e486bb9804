"""Where a skill running on the robot interface reads its wrench: the robot's F/T sensor or a stand-in.

A skill needs the external wrench on its tool every controller period. On ``sim`` it is the flange
F/T sensor in the robot state; a FANUC controller streaming Stream Motion v3 reports none (the
cell's own F/T sensor is read over its own link), so a :class:`WrenchSource` is passed in:
:class:`StateWrench` (the state's sensor, payload-compensated (3.20)) or :class:`VirtualWall`, a
simulated contact (a spring-damper plane computed from the measured joints) that stands for the
sensor when the robot is the controller emulator.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from robointel.control.payload import PayloadCompensation
from robointel.errors import InvalidInput
from robointel.interface.state import RobotState

Vector = npt.NDArray[np.float64]


class WrenchSource(Protocol):
    """The external wrench on the tool in the flange (sensor) frame, once per controller period."""

    def wrench(self, state: RobotState) -> Vector | None:
        """(6,) [f (N); m (N m)] on the tool, flange frame, torque about the flange origin; None: no reading."""
        ...


@dataclass
class StateWrench:
    """The robot state's F/T reading with the tool's weight and the sensor's biases removed (3.20).

    Attributes:
        robot: the :class:`robointel.robot.Robot` of the arm (flange orientation for the compensation).
        payload: the tool's weight and the sensor biases (None: the reading as it is).
    """

    robot: Any
    payload: PayloadCompensation | None = None

    def wrench(self, state: RobotState) -> Vector | None:
        """The compensated reading (6,) in the flange frame, or None when the state carries none."""
        if state.wrench is None:
            return None
        w = np.asarray(state.wrench, dtype=float)
        if self.payload is None:
            return w
        R = self.robot.frame_pose(state.q, self.robot.flange_frame)[:3, :3]
        return np.asarray(self.payload.compensate(w, R))


@dataclass
class VirtualWall:
    """A simulated contact: a spring-damper half-space that pushes back on a point of the tool.

    The wall is the plane through ``point`` with outward normal ``normal`` (world); when the tool point
    (the robot's TCP at the measured joints) is ``d`` metres inside it, the wall pushes with
    ``f = (stiffness d + damping max(-v_n, 0)) n`` plus Coulomb friction against the tangential
    velocity, and the reading adds white noise. It stands for an F/T sensor on a robot that reports no
    wrench (the controller emulator); its forces act on nothing, the motion is the controller's.

    Attributes:
        robot: the :class:`robointel.robot.Robot` whose TCP is the contact point.
        point: (3,) a point of the wall plane, world, m.
        normal: (3,) outward unit normal (the direction the wall pushes), world.
        stiffness: N/m.
        damping: N s/m.
        friction: Coulomb coefficient.
        noise: force noise std, N.
        seed: seed of the noise.
    """

    robot: Any
    point: npt.ArrayLike
    normal: npt.ArrayLike = (0.0, 0.0, 1.0)
    stiffness: float = 5000.0
    damping: float = 50.0
    friction: float = 0.1
    noise: float = 0.0
    seed: int = 0
    _rng: np.random.Generator = field(init=False, repr=False)

    def __post_init__(self) -> None:
        p = np.asarray(self.point, dtype=float)
        n = np.asarray(self.normal, dtype=float)
        if p.shape != (3,) or n.shape != (3,) or not (np.all(np.isfinite(p)) and np.all(np.isfinite(n))):
            raise InvalidInput("VirtualWall point and normal must be 3 finite numbers", value=(p, n))
        if not np.linalg.norm(n) > 0:
            raise InvalidInput("VirtualWall normal must not be zero", value=n)
        for name in ("stiffness", "damping", "friction", "noise"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v >= 0):
                raise InvalidInput(f"VirtualWall.{name} must be finite and >= 0, got {v}", value=v)
        self.point, self.normal = p, n / np.linalg.norm(n)
        self._rng = np.random.default_rng(self.seed)

    def world_force(self, q: npt.ArrayLike, qd: npt.ArrayLike) -> Vector:
        """The wall's force (3,) N on the TCP at joints ``q`` (n,) rad moving at ``qd`` (n,) rad/s, world axes."""
        q = np.asarray(q, dtype=float)
        p = self.robot.fk(q)[:3, 3]
        n = np.asarray(self.normal)
        d = float(n @ (np.asarray(self.point) - p))
        if d <= 0:
            return np.zeros(3)
        v = (self.robot.jacobian(q) @ np.asarray(qd, dtype=float))[:3]
        fn = self.stiffness * d + self.damping * max(-float(n @ v), 0.0)
        vt = v - (n @ v) * n
        s = float(np.linalg.norm(vt))
        ft = -self.friction * fn * vt / s if s > 1e-6 else np.zeros(3)
        return np.asarray(fn * n + ft)

    def wrench(self, state: RobotState) -> Vector | None:
        """The wall's wrench on the tool (6,) in the flange frame about the flange origin, with noise."""
        f = self.world_force(state.q, state.qd)
        Tf = self.robot.frame_pose(state.q, self.robot.flange_frame)
        r = self.robot.fk(state.q)[:3, 3] - Tf[:3, 3]
        w = np.concatenate([Tf[:3, :3].T @ f, Tf[:3, :3].T @ np.cross(r, f)])
        if self.noise > 0:
            w[:3] += self.noise * self._rng.standard_normal(3)
        return w
