"""Contacts of the robot with the environment and robot-obstacle distances in the workcell."""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from robointel.sim.mjcf import OBJECT_PREFIX, OBSTACLE_PREFIX
from robointel.sim.workcell_model import WorkcellModel


@dataclass(frozen=True)
class Contact:
    """One MuJoCo contact involving the robot (or its tool).

    ``distance`` is MuJoCo's signed contact distance (m, negative = penetration); ``position``
    (3,) the contact point and ``normal`` (3,) the unit normal pointing from ``robot_geom`` toward
    ``other_geom``, both in the world frame. ``force`` (3,) N is the contact force the other geom
    exerts on the robot geom (world frame; normal + friction). ``kind`` is "obstacle", "table",
    "floor", "object", "self" (robot-robot) or "world".
    """

    robot_geom: str
    other_geom: str
    robot_body: str
    other_body: str
    kind: str
    distance: float
    position: np.ndarray
    normal: np.ndarray
    force: np.ndarray



class ContactSensing(WorkcellModel):
    """Contacts and distances measured by MuJoCo."""

    def _contact_kind(self, g: int) -> str:
        n = self._geom_names[g]
        if self._geom_robot[g]:
            return "self"
        if n.startswith(OBSTACLE_PREFIX):
            return "obstacle"
        if n.startswith(OBJECT_PREFIX):
            return "object"
        if n in ("table", "floor"):
            return n
        return "world"

    def contacts(self) -> list[Contact]:
        """Current contacts with at least one robot geom (the robot geom first)."""
        out = []
        d = self.data
        f6 = np.zeros(6)
        for i in range(d.ncon):
            c = d.contact[i]
            g1, g2 = int(c.geom1), int(c.geom2)
            r1, r2 = self._geom_robot[g1], self._geom_robot[g2]
            if not (r1 or r2):
                continue
            normal = np.array(c.frame[:3])
            # mj_contactForce: force of geom1 on geom2 in the contact frame (rows of c.frame)
            mujoco.mj_contactForce(self.model, d, i, f6)
            f_on_2 = np.asarray(c.frame).reshape(3, 3).T @ f6[:3]
            force = -f_on_2
            if not r1:
                g1, g2, normal, force = g2, g1, -normal, f_on_2
            out.append(Contact(self._geom_names[g1], self._geom_names[g2],
                               self._body_names[self.model.geom_bodyid[g1]],
                               self._body_names[self.model.geom_bodyid[g2]], self._contact_kind(g2),
                               float(c.dist), np.array(c.pos), normal, force))
        return out

    def _environment_contact_count(self) -> int:
        d = self.data
        if d.ncon == 0:
            return 0
        g1 = d.contact.geom1[: d.ncon]
        g2 = d.contact.geom2[: d.ncon]
        r1, r2 = self._geom_robot[g1], self._geom_robot[g2]
        objs = np.array([self._geom_names[g].startswith(OBJECT_PREFIX) for g in np.concatenate([g1, g2])])
        obj = objs[: d.ncon] | objs[d.ncon:]
        return int(np.count_nonzero((r1 | r2) & ~obj))

    def obstacle_distance(self, distmax: float = 1.0) -> tuple[float, str | None, str | None]:
        """Minimum signed distance (m) between robot and obstacle geoms, with the two geom names.

        (``inf``, None, None) without obstacles or beyond ``distmax`` (m).
        """
        if len(self._obstacle_geoms) == 0:
            return float("inf"), None, None
        m, d = self.model, self.data
        rg, og = self._robot_geoms, self._obstacle_geoms
        centre = np.linalg.norm(d.geom_xpos[rg][:, None] - d.geom_xpos[og][None], axis=2)
        gap = centre - m.geom_rbound[rg][:, None] - m.geom_rbound[og][None]
        best, pair = float("inf"), (None, None)
        for i, j in zip(*np.nonzero(gap < distmax)):
            dd = mujoco.mj_geomDistance(m, d, int(rg[i]), int(og[j]), distmax, None)
            if dd < best:
                best, pair = dd, (self._geom_names[rg[i]], self._geom_names[og[j]])
        return best, pair[0], pair[1]
