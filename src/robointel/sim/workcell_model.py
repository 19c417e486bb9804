"""The workcell's MuJoCo model: built from the robot description; names, ids, state, body poses, obstacles.

The base class of the :class:`~robointel.sim.workcell.Workcell` parts.
"""
from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from robointel._validate import as_array
from robointel.errors import DescriptionError, InvalidInput
from robointel.sim.mjcf import FT_SITE, OBJECT_PREFIX, OBSTACLE_PREFIX, TOOL_BODY, build_spec

CONTROL_DT = 0.001  # 1 kHz joint controller


class WorkcellModel:
    """The compiled MuJoCo model and data of a workcell and what is read straight from them."""

    # attributes set by the concrete Workcell (declared for the type checker)
    robot: Any
    n: int
    timestep: float
    control_dt: float
    substeps: int
    controller: Any
    ft_config: Any
    payload: Any
    spec: Any
    info: dict[str, Any]
    model: Any
    data: Any
    _has_ft: bool
    _armature: Any
    _table: bool
    _self_collision: bool
    _obstacles: list[Any]
    _objects: list[Any]
    _wrench: Any
    _hold: Any
    _q0: Any
    _q_safe: np.ndarray
    _qadr: Any
    _vadr: Any
    _aid: Any
    _t_safe: float

    def _build(self) -> None:
        self.spec, self.info = build_spec(self.robot, table=self._table, obstacles=self._obstacles,
                                          objects=self._objects, ft_sensor=self._has_ft, payload=self.payload,
                                          timestep=self.timestep, armature=self._armature,
                                          self_collision=self._self_collision)
        try:
            self.model = self.spec.compile()
        except Exception as exc:
            raise DescriptionError(f"MuJoCo could not compile the workcell: {exc}") from None
        self.data = mujoco.MjData(self.model)
        m = self.model
        jids = [m.joint(nm).id for nm in self.robot.joint_names]
        self._qadr = np.array([m.jnt_qposadr[j] for j in jids])
        self._vadr = np.array([m.jnt_dofadr[j] for j in jids])
        self._aid = np.array([m.actuator(nm).id for nm in self.robot.joint_names])
        if np.array_equal(self._qadr, np.arange(self.n)) and np.array_equal(self._vadr, np.arange(self.n)):
            self._qadr = self._vadr = slice(0, self.n)
        if np.array_equal(self._aid, np.arange(self.n)):
            self._aid = slice(0, self.n)
        # which geoms belong to the robot (bodies in the subtree of the robot's root link)
        root = m.body(self._root_link()).id
        robot_bodies = {b for b in range(m.nbody) if self._in_subtree(b, root)}
        self._robot_body = np.array([b in robot_bodies for b in range(m.nbody)])
        self._geom_robot = self._robot_body[m.geom_bodyid]
        self._geom_names = [m.geom(g).name or f"geom{g}" for g in range(m.ngeom)]
        self._body_names = [m.body(b).name for b in range(m.nbody)]
        self._obstacle_geoms = np.array([g for g in range(m.ngeom) if self._geom_names[g].startswith(OBSTACLE_PREFIX)],
                                        dtype=int)
        self._robot_geoms = np.flatnonzero(self._geom_robot & ((m.geom_contype | m.geom_conaffinity) > 0))
        self._mocap = {nm: int(m.body_mocapid[m.body(OBSTACLE_PREFIX + nm).id]) for nm in self.info["obstacles"]}
        self._tool_id = m.body(TOOL_BODY).id
        if self._has_ft:
            self._ft_adr = int(m.sensor_adr[m.sensor("ft_force").id])
            self._site_id = m.site(FT_SITE).id
        self._warn0 = 0
        self._zero = np.zeros(self.n)
        self._zero.flags.writeable = False

    def _root_link(self) -> str:
        """The robot's root body: the ancestor of the first joint's body that hangs on the world."""
        m = self.model
        b = int(m.jnt_bodyid[m.joint(self.robot.joint_names[0]).id])
        while m.body_parentid[b] != 0:
            b = int(m.body_parentid[b])
        return m.body(b).name

    def _in_subtree(self, b: int, root: int) -> bool:
        m = self.model
        while b > 0:
            if b == root:
                return True
            b = m.body_parentid[b]
        return b == root


    @property
    def q(self) -> np.ndarray:
        """Joint positions (n,) rad."""
        return self.data.qpos[self._qadr].copy()

    @property
    def qd(self) -> np.ndarray:
        """Joint velocities (n,) rad/s."""
        return self.data.qvel[self._vadr].copy()

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return float(self.data.time)

    @property
    def qpos_index(self) -> slice | np.ndarray:
        """Where the robot's joints sit in MuJoCo's ``qpos`` (a slice or an index array)."""
        return self._qadr


    def _bad_count(self) -> int:
        w = self.data.warning
        return int(w[mujoco.mjtWarning.mjWARN_BADQACC].number)


    def _body_id(self, name: str) -> int:
        m = self.model
        for cand in (name, OBSTACLE_PREFIX + name, OBJECT_PREFIX + name):
            i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, cand)
            if i >= 0:
                return i
        raise InvalidInput(f"no body {name!r}; bodies: {self._body_names}", value=name)

    def body_pose(self, name: str) -> np.ndarray:
        """4x4 world pose of a MuJoCo body (robot links, ``"tool"``, obstacles and objects by name)."""
        i = self._body_id(name)
        T = np.eye(4)
        T[:3, :3] = self.data.xmat[i].reshape(3, 3)
        T[:3, 3] = self.data.xpos[i]
        return T


    @property
    def obstacle_names(self) -> list[str]:
        """Names of the obstacles in the scene."""
        return list(self.info["obstacles"])


    def set_obstacle_pose(self, name: str, position: npt.ArrayLike, rotation: npt.ArrayLike | None = None) -> None:
        """Move an obstacle's reference point (centre / axis midpoint) to ``position`` (3,), world frame.

        ``rotation`` is an optional 3x3 rotation. Takes effect immediately (moving obstacles).
        """
        if name not in self._mocap:
            raise InvalidInput(f"no obstacle {name!r}; obstacles: {self.obstacle_names}", value=name)
        i = self._mocap[name]
        self.data.mocap_pos[i] = as_array(position, "position", (3,))
        if rotation is not None:
            R = as_array(rotation, "rotation", (3, 3))
            if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
                raise InvalidInput("rotation must be a proper rotation matrix", value=rotation)
            mujoco.mju_mat2Quat(self.data.mocap_quat[i], R.reshape(9))
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_collision(self.model, self.data)


    def _apply_wrench_now(self) -> None:
        """Re-apply the external wrench (implemented by the F/T sensing part)."""
        raise NotImplementedError

