"""Idealised grasps in the workcell: objects welded to the tool (MuJoCo equality constraints)."""
from __future__ import annotations

import mujoco
import numpy as np

from robointel.errors import InvalidInput
from robointel.sim.mjcf import OBJECT_PREFIX, TOOL_BODY
from robointel.sim.workcell_model import WorkcellModel


class GraspWelds(WorkcellModel):
    """Attach and release objects."""

    def grasp(self, name: str) -> None:
        """Rigidly attach object ``name`` to the tool where it is now (a MuJoCo weld; an idealised grasp).

        Its mass is then carried by the arm and felt by the F/T sensor; the controller's feed-forward does
        not know it (the integral takes it up).
        """
        eq = self._object_eq(name)
        m, d = self.model, self.data
        Tt, To = self.body_pose(TOOL_BODY), self.body_pose(name)
        Tr = np.linalg.inv(Tt) @ To  # object pose in the tool frame
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(Tr[:3, :3]).reshape(9))
        m.eq_data[eq, 0:3] = 0.0
        m.eq_data[eq, 3:6] = Tr[:3, 3]
        m.eq_data[eq, 6:10] = quat
        d.eq_active[eq] = 1

    def release(self, name: str) -> None:
        """Detach an object attached by :meth:`grasp`."""
        self.data.eq_active[self._object_eq(name)] = 0

    def grasped(self) -> list[str]:
        """Names of the objects currently attached to the tool."""
        return [n for n in self.info["objects"] if self.data.eq_active[self._object_eq(n)]]

    def _object_eq(self, name: str) -> int:
        if name not in self.info["objects"]:
            raise InvalidInput(f"no object {name!r}; objects: {self.info['objects']}", value=name)
        return int(mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_EQUALITY, OBJECT_PREFIX + name))
