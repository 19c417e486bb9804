"""The environment check every path that moves the robot runs before a target reaches the controller.

A target configuration q is accepted when every movable collision sphere (Fig. 4.2) of the robot is
clear of the environment obstacles (the table and the floor by default, plus any scene obstacles)
by ``clearance`` and no self-collision pair of spheres overlaps by more than ``self_clearance``:

    d(p_i(q), O_k) - r_i >= clearance  for every movable sphere i and obstacle k,     (4.3)
    ||p_i(q) - p_j(q)|| - r_i - r_j >= self_clearance  for every self pair (i, j).

A motion is checked on the straight joint-space segment from the current reference to the target,
sampled every ``step`` rad of the largest joint move.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel.errors import TargetInCollision
from robointel.geometry.table import table_obstacles
from robointel.robot import Robot


class CollisionGuard:
    """Checks configurations and joint-space moves against the environment and the robot itself.

    Args:
        robot: a :class:`robointel.robot.Robot` (its ``spheres`` are the collision model). The guard
            uses its own copy of the robot's kinematic data, so it may run beside a control thread.
        obstacles: environment obstacles (default: the workcell's table and floor).
        clearance: required sphere-obstacle clearance, m (0: no penetration).
        self_clearance: required clearance of self-collision sphere pairs, m (negative tolerates a
            small overlap of the conservative spheres).
        step: largest joint step between samples of a checked move, rad.
    """

    def __init__(self, robot: Any, obstacles: Sequence[Any] | None = None, *, clearance: float = 0.0,
                 self_clearance: float = 0.0, step: float = 0.05) -> None:
        self.robot = Robot(robot.urdf, name=robot.name, urdf_path=robot.urdf_path, flange_frame=robot.flange_frame,
                           tool=robot.tool)
        self.obstacles = list(table_obstacles() if obstacles is None else obstacles)
        self.clearance = float(clearance)
        self.self_clearance = float(self_clearance)
        self.step = float(step)
        sm = self.robot.spheres
        self._movable = np.flatnonzero(np.asarray(sm.movable, bool))
        self._pairs: npt.NDArray[np.int_] = np.asarray(sm.self_pairs, int).reshape(-1, 2)

    def check(self, q: npt.ArrayLike, what: str = "target") -> None:
        """Raise if configuration ``q`` (n,) rad is in collision.

        Raises:
            TargetInCollision: naming the link and the obstacle (or the other link) and the distance.
        """
        self.check_many(np.asarray(q, float)[None], what)

    def check_motion(self, q_from: npt.ArrayLike, q_to: npt.ArrayLike, what: str = "target") -> None:
        """Raise if the straight joint-space move ``q_from`` -> ``q_to`` ((n,) rad each) collides.

        Raises:
            TargetInCollision: at the first colliding sample, naming the link.
        """
        a, b = np.asarray(q_from, float), np.asarray(q_to, float)
        k = max(1, int(np.ceil(float(np.max(np.abs(b - a))) / self.step)))
        s = np.linspace(0.0, 1.0, k + 1)[1:, None]
        self.check_many(a + s * (b - a), what)

    def check_many(self, Q: npt.NDArray[np.float64], what: str = "target") -> None:
        """Raise at the first configuration of ``Q`` (B, n) that is in collision.

        Raises:
            TargetInCollision: naming the link, the obstacle (or other link) and the distance.
        """
        sm = self.robot.spheres
        P = self.robot.points_kinematics_batch(Q, sm.joints, sm._in_joint)[0]  # (B, m, 3)
        r = sm.radii
        B, mv = len(Q), self._movable
        for k, o in enumerate(self.obstacles):
            d = o.distance(P[:, mv].reshape(-1, 3))[0].reshape(B, len(mv)) - r[mv]  # (B, movable)
            hit = np.argwhere(d < self.clearance)
            if len(hit):
                b = int(hit[0, 0])
                w = int(np.argmin(d[b]))
                link = sm.links[int(mv[w])]
                raise TargetInCollision(
                    f"{what} rejected: link {link!r} would be {d[b, w] * 1000:.1f} mm from {o.label(k)!r} "
                    f"(required {self.clearance * 1000:.0f} mm); the robot holds", value={
                        "link": link, "obstacle": o.label(k), "distance": float(d[b, w]), "q": Q[b].tolist()})
        if len(self._pairs):
            pa, pb = self._pairs[:, 0], self._pairs[:, 1]
            ds = np.linalg.norm(P[:, pa] - P[:, pb], axis=2) - r[pa] - r[pb]  # (B, pairs)
            hit = np.argwhere(ds < self.self_clearance)
            if len(hit):
                b = int(hit[0, 0])
                m = int(np.argmin(ds[b]))
                la, lb = sm.links[int(pa[m])], sm.links[int(pb[m])]
                raise TargetInCollision(
                    f"{what} rejected: link {la!r} would hit link {lb!r} (self-collision, spheres "
                    f"{-ds[b, m] * 1000:.1f} mm into each other); the robot holds",
                    value={"link": la, "obstacle": lb, "distance": float(ds[b, m]), "q": Q[b].tolist()})
