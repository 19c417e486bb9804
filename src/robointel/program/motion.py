"""Start-to-goal moves of a program cell that carries a tool and, at times, an object.

The cell's moves are planned by :func:`robointel.planning.plan_motion` (RRT-Connect on the robot's
mesh-covering spheres, the exact collision meshes at the start and goal edges, temporal optimization
(7.7)-(7.9), and the dense 1 ms check) in an :class:`robointel.planning.environment.Environment` whose
attached objects are the tool (the gripper's palm and open fingers) and the held object, both given in
the flange frame, so the planned clearance ``d_min`` holds for the arm, the tool and the held part.
"""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robointel.errors import InfeasibleProblem, InvalidInput
from robointel.geometry.obstacles import Box, Obstacle
from robointel.learning.grasp import ParallelGripper
from robointel.planning.environment import Environment
from robointel.planning.motion import plan_motion
from robointel.planning.motion_settings import MotionSettings
from robointel.planning.scene import Scene
from robointel.trajectory import Trajectory

#: wall-time budget of one move's global search, s (the planner repeats with another seed once)
TIME_BUDGET_S = 2.0
#: smallest clearance between two links of the arm a move may start or end with, m
SELF_MIN_M = 0.005


def gripper_geometry(gripper: ParallelGripper) -> list[Obstacle]:
    """The parallel gripper (palm and open fingers as one box) in the flange frame.

    Args:
        gripper: The gripper mounted at ``gripper.tool_transform()`` on the flange.

    Returns:
        One :class:`robointel.geometry.Box` in the flange frame (m).
    """
    g = gripper
    T = g.tool_transform()
    z0 = g.tip_depth - g.finger_length - g.palm_height  # palm back, grasp frame
    size = np.array([max(g.palm_breadth, g.finger_breadth), g.max_width + 2 * g.finger_thickness,
                     g.finger_length + g.palm_height])
    centre = np.array([0.0, 0.0, z0 + size[2] / 2])
    return [Box(center=T[:3, :3] @ centre + T[:3, 3], size=size, rotation=T[:3, :3], name="gripper")]


def held_box(T_flange: npt.ArrayLike, T_object: npt.ArrayLike, bounds: npt.ArrayLike) -> Box:
    """The held object's bounding box in the flange frame.

    Args:
        T_flange: (4, 4) world pose of the flange, m.
        T_object: (4, 4) world pose of the object's frame, m.
        bounds: (2, 3) lower and upper corners of the object's box in its own frame, m.

    Returns:
        The :class:`robointel.geometry.Box` in the flange frame.
    """
    T = np.linalg.inv(np.asarray(T_flange, float)) @ np.asarray(T_object, float)
    b = np.asarray(bounds, float)
    return Box(center=T[:3, :3] @ b.mean(axis=0) + T[:3, 3], size=np.maximum(b[1] - b[0], 1e-3),
               rotation=T[:3, :3], name="held")


class CellPlanner:
    """Plan the moves of a cell with attached objects around the scene's obstacles.

    Args:
        scene: The program's scene (robot, obstacles, d_min, velocity and acceleration limits).
        seed: Seed of the sampler.
    """

    def __init__(self, scene: Scene, *, seed: int = 0) -> None:
        self.scene = scene
        self.seed = int(seed)
        self._envs: dict[str, Environment] = {}
        self._srdf: Path | None = None
        self._tmp: tempfile.TemporaryDirectory[str] | None = None

    def environment(self, attached: Sequence[Obstacle], *, self_collision: bool = True) -> Environment:
        """The planning environment with ``attached`` (flange frame) on the tool (cached per attachment).

        Args:
            attached: Objects on the tool, in the flange frame.
            self_collision: False: an environment that checks the obstacles only (every link pair disabled).
        """
        key = (repr([o.to_dict() for o in attached]) + repr([o.to_dict() for o in self.scene.obstacles])
               + str(self_collision))
        if key not in self._envs:
            if len(self._envs) > 6:
                self._envs.clear()
            srdf = None if self_collision else self._no_self_srdf()
            self._envs[key] = Environment(self.scene.robot, self.scene.obstacles, attached=list(attached), srdf=srdf)
        return self._envs[key]

    def _no_self_srdf(self) -> Path:
        """An SRDF disabling every link pair (obstacle-only clearance), written once per planner."""
        if self._srdf is None:
            links = list(self.scene.robot.link_names)
            pairs = "".join(f'<disable_collisions link1="{a}" link2="{b}" reason="obstacles only"/>'
                            for i, a in enumerate(links) for b in links[i + 1:])
            self._tmp = tempfile.TemporaryDirectory(prefix="robointel-cell-")
            self._srdf = Path(self._tmp.name) / "no_self.srdf"
            self._srdf.write_text(f'<robot name="{self.scene.robot.name}">{pairs}</robot>')
        return self._srdf

    def clearance(self, q: npt.ArrayLike, attached: Sequence[Obstacle] = (), *, self_collision: bool = True) -> float:
        """Smallest clearance (m) of the arm and its attachments to the obstacles (and between links) at ``q``.

        Args:
            q: (n,) configuration, rad.
            attached: Objects on the tool, in the flange frame.
            self_collision: False: the obstacles only.
        """
        env = self.environment(attached, self_collision=self_collision)
        env.use("cover")
        return float(env.clearance(np.asarray(q, float), cap=1.0))

    def d_min_between(self, a: np.ndarray, b: np.ndarray, attached: Sequence[Obstacle] = ()) -> float:
        """The clearance a move from ``a`` to ``b`` is planned with: the scene's ``d_min``, or less for link pairs.

        The planner holds one ``d_min`` for obstacles and between the robot's own links. When the start
        or the goal (a grasp the grasp search chose) brings two links of the arm closer than ``d_min``
        (but at least ``SELF_MIN_M`` apart) while the obstacles keep ``d_min``, the move is planned with
        that smaller clearance (minus 2 mm).
        """
        d_min = float(self.scene.d_min)
        out = d_min
        for q in (a, b):
            full = self.clearance(q, attached)
            if full < d_min and self.clearance(q, attached, self_collision=False) >= d_min and full >= SELF_MIN_M:
                out = min(out, max(SELF_MIN_M, full - 0.002))
        return out

    def plan(self, q0: npt.ArrayLike, q1: npt.ArrayLike, attached: Sequence[Obstacle] = (), *,
             speed: float = 1.0) -> Trajectory | None:
        """Plan a rest-to-rest move keeping ``d_min`` from the obstacles for the arm and ``attached``.

        Args:
            q0: (n,) start, rad.
            q1: (n,) goal, rad.
            attached: Objects on the tool, in the flange frame.
            speed: Fraction of the scene's velocity limits (its square of the acceleration limits), in (0, 1].

        Returns:
            The checked trajectory, or None when ``q0`` and ``q1`` coincide.

        Raises:
            InvalidInput: ``speed`` outside (0, 1].
            CollisionAtStart: The start or the goal is closer than ``d_min`` (names the pair).
            InfeasibleProblem: No motion that passes the dense check was found.
        """
        if not 0 < speed <= 1:
            raise InvalidInput(f"speed must be in (0, 1], got {speed}", value=speed)
        a, b = np.asarray(q0, float), np.asarray(q1, float)
        if float(np.max(np.abs(b - a))) < 1e-9:
            return None
        sc = self.scene
        robot = sc.robot
        vscale = float(np.min(np.asarray(sc.vmax) / robot.velocity_limit)) * speed
        amax = tuple(float(x) for x in np.asarray(sc.amax) * speed ** 2)
        env = self.environment(attached)
        d_min = self.d_min_between(a, b, attached)
        last = None
        for attempt in range(2):
            st = MotionSettings(d_min=d_min, velocity_scale=min(1.0, vscale), acceleration_limit=amax,
                                time_budget_s=TIME_BUDGET_S, seed=self.seed + attempt)
            res = plan_motion(robot, env, a, b, settings=st)
            if res.success and res.trajectory is not None:
                return res.trajectory
            last = res
        assert last is not None
        raise InfeasibleProblem(f"no motion keeps {sc.d_min * 1000:.0f} mm from the obstacles: {last.reason}",
                                value=last)
