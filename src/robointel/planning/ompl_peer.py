"""The sampling-based peer: OMPL RRTConnect + path simplification on the same scene.

Same robot spheres, same obstacles and the same clearance (``d_min + safety``) as the CFS planner:
a configuration is valid when every movable sphere is at least that far from every obstacle
(:func:`robointel.geometry.min_distance`, the compiled minimum over all pairs). Motions are checked by OMPL's
discrete motion
validator at ``resolution`` (fraction of the joint-space extent). ``ompl`` comes with the ``peers`` extra.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from robointel._extras import needs_extra
from robointel.geometry import min_distance

if TYPE_CHECKING:  # pragma: no cover
    from robointel.robot import Robot


@dataclass
class OMPLResult:
    """RRTConnect + simplification outcome: path (K, n) rad, solved flag, times (ms), checks."""

    path: np.ndarray
    solved: bool
    plan_ms: float
    simplify_ms: float
    checks: int

    @property
    def total_ms(self) -> float:
        """Planning plus simplification time, ms."""
        return self.plan_ms + self.simplify_ms


def rrtconnect(robot: Robot, obstacles: Any, start: np.ndarray, goal: np.ndarray, *, clearance: float,
               timeout: float = 10.0, resolution: float = 0.005, simplify: bool = True,
               seed: int | None = 0) -> OMPLResult:
    """Plan from ``start`` to ``goal`` (n,) with OMPL's RRTConnect, then simplify the path."""
    with needs_extra("peers", "the OMPL peer"):
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou

    ou.setLogLevel(ou.LogLevel.LOG_NONE)
    if seed is not None:
        ou.RNG.setSeed(int(seed) + 1)
    n = robot.nq
    space = ob.RealVectorStateSpace(n)
    b = ob.RealVectorBounds(n)
    for i in range(n):
        b.setLow(i, float(robot.lower[i]))
        b.setHigh(i, float(robot.upper[i]))
    space.setBounds(b)
    ss = og.SimpleSetup(space)
    obstacles = tuple(obstacles)
    count = [0]
    q = np.empty(n)

    # ``s`` stays unannotated: OMPL's bindings read the callback's annotations, and with one it is never called
    def valid(s) -> bool:  # type: ignore[no-untyped-def]
        """The fastest single-configuration check robointel has (compiled minimum)."""
        count[0] += 1
        for i in range(n):
            q[i] = s[i]
        if not obstacles:
            return True
        return bool(min_distance(robot, q, obstacles, movable_only=True).distance >= clearance)

    ss.setStateValidityChecker(valid)
    si = ss.getSpaceInformation()
    si.setStateValidityCheckingResolution(resolution)
    s0, s1 = space.allocState(), space.allocState()
    for i in range(n):
        s0[i] = float(start[i])
        s1[i] = float(goal[i])
    ss.setStartAndGoalStates(s0, s1)
    ss.setPlanner(og.RRTConnect(si))
    if obstacles:  # the compiled check built (or loaded) before the clock starts: OMPL's timeout is for planning
        min_distance(robot, np.asarray(start, float), obstacles, movable_only=True)
    t0 = time.perf_counter()
    status = ss.solve(float(timeout))
    t1 = time.perf_counter()
    solved = bool(ss.haveExactSolutionPath())
    if solved and simplify:
        ss.simplifySolution()
    t2 = time.perf_counter()
    path = np.zeros((0, n))
    if solved:
        states = ss.getSolutionPath().getStates()
        path = np.array([[st[i] for i in range(n)] for st in states])
    del status
    return OMPLResult(path=path, solved=solved, plan_ms=(t1 - t0) * 1e3,
                      simplify_ms=((t2 - t1) * 1e3) if simplify else 0.0, checks=count[0])
