"""The hand-held demonstration device (HDD) over a task in MuJoCo: a free handle a person pushes (Sec. 5.2)."""

from __future__ import annotations

from typing import Protocol

import mujoco
import numpy as np
import numpy.typing as npt

from robointel.learning.hdd import GRAVITY, Contact, Tool, ToolFT, add_tool_sensors, cross
from robointel.learning.insertion.peg_hole import wall_geom_range, wall_penetration


class Task(Protocol):
    """A task the device works on: its contact settings, its environment and its tool."""

    @property
    def contact(self) -> Contact:
        """The contact settings of the task's geoms and its tool."""

    def build(self, spec: mujoco.MjSpec) -> None:
        """Add the task's environment to ``spec``."""

    def tool(self) -> Tool:
        """The task's default tool."""


class HDDScene:
    """The device on the table: a free handle (mass ``handle_mass``) with the tool and its F/T sensor.

    The person acts on the handle with :meth:`step`; the F/T sensor sits between handle and tool.
    """

    def __init__(self, task: Task, tool: Tool | None = None, *, handle_mass: float = 0.4) -> None:
        """Build the scene.

        Args:
            task: The task (its ``build`` adds the environment).
            tool: The tool on the handle (default: the task's).
            handle_mass: Mass of the handle without the tool (kg).
        """
        self.task = task
        self.tool = tool or task.tool()
        spec = mujoco.MjSpec()
        spec.option.timestep = 0.001
        spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        spec.option.gravity = GRAVITY
        spec.worldbody.add_geom(name="table", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1, 1, 0.1],
                                rgba=[0.55, 0.42, 0.3, 1], contype=2, conaffinity=3)
        spec.worldbody.add_light(name="light", pos=[0.5, -1.0, 2.5], dir=[-0.2, 0.4, -1.0])
        task.build(spec)
        h = spec.worldbody.add_body(name="handle", pos=[0, 0, 0.5])
        h.add_freejoint(name="handle")
        h.mass = handle_mass
        h.inertia = [2e-4, 2e-4, 2e-4]
        h.explicitinertial = True
        h.add_geom(name="handle/grip", type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.015, 0.04, 0],
                   pos=[0, 0, -0.05], rgba=[0.2, 0.2, 0.25, 1], contype=0, conaffinity=0, mass=0, density=0)
        self.tool.add_to(h, task.contact, contype=1, conaffinity=2)
        add_tool_sensors(spec)
        self.spec = spec
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self._hid = self.model.body("handle").id
        self.mass = float(self.model.body_subtreemass[self._hid])
        self._walls = wall_geom_range(self.model)
        self._peg = self.model.geom(self.tool.name + "/peg").id
        self.ft = ToolFT(self.model, self.tool)

    def reset(self, T_tool: npt.NDArray[np.float64]) -> None:
        """Place the tool at the (4, 4) world pose ``T_tool`` at rest."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:3] = T_tool[:3, 3]
        q = np.empty(4)
        mujoco.mju_mat2Quat(q, np.ascontiguousarray(T_tool[:3, :3]).ravel())
        self.data.qpos[3:7] = q
        mujoco.mj_forward(self.model, self.data)

    def pose(self) -> npt.NDArray[np.float64]:
        """The tool's (4, 4) world pose."""
        return self.ft.pose(self.data)

    def wrench(self) -> npt.NDArray[np.float64]:
        """The F/T sensor's wrench (6,) [f (N); tau (N m)] in the tool frame."""
        return self.ft.wrench(self.data)

    def twist(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """World linear velocity (3,) m/s of the tool origin and angular velocity (3,) rad/s."""
        v = self.data.qvel
        return v[:3].copy(), self.data.xmat[self._hid].reshape(3, 3) @ v[3:6]

    def step(self, force: npt.NDArray[np.float64], torque: npt.NDArray[np.float64]) -> None:
        """One 1 ms step with the hand's force (3,) N and torque (3,) N m at the tool origin, world frame."""
        d = self.data
        p = d.xpos[self._hid]
        d.xfrc_applied[self._hid, :3] = force
        d.xfrc_applied[self._hid, 3:] = torque + cross(p - d.xipos[self._hid], force)
        mujoco.mj_step(self.model, d)

    def wall_penetration(self) -> float:
        """Deepest penetration (m) of the peg into the hole wall now."""
        return wall_penetration(self.data, self._walls, self._peg)
