"""Receding-horizon replanning with a moving obstacle (the human-robot interaction case of Ch. 7).

At every tick the robot advances one step along its current plan, the obstacle moves, and CFS
re-plans the N-step horizon from the robot's new configuration to the goal, warm-started from the
previous plan shifted by one step (and from OSQP's previous primal/dual pair: the QP pattern does
not change between ticks). The replanning rate is 1 / (time per re-plan).
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from robointel._validate import as_array
from robointel.errors import InvalidInput
from robointel.outcome import Failure, TrialOutcome
from robointel.planning.waypoints import PlannerSettings, TrajectoryPlanner

if TYPE_CHECKING:  # pragma: no cover
    from robointel.geometry.obstacles import Obstacle
    from robointel.robot import Robot


@dataclass
class ReplanResult:
    """Per tick.

    Re-plan wall time (ms), CFS iterations, whether the plan is clear, the plan's smallest sphere/obstacle distance
    (m); the executed configurations (ticks+1, n) and the obstacle positions (ticks, 3).
    """

    times_ms: np.ndarray
    iterations: np.ndarray
    feasible: np.ndarray
    min_distance: np.ndarray
    executed: np.ndarray
    obstacle_path: np.ndarray

    @property
    def hz(self) -> float:
        """Replanning rate from the median re-plan time."""
        return float(1000.0 / np.median(self.times_ms))

    @property
    def outcome(self) -> TrialOutcome:
        """The run as a trial: success when every re-plan was clear (feasible).

        Failures: ``Failure.COLLISION`` when a re-plan ran into the obstacle (negative distance), else
        ``Failure.INFEASIBLE``. Figures: ``ticks``, ``infeasible_ticks``, ``min_distance_m``,
        ``max_iterations``; timing: ``replan_median_s``.
        """
        bad = int(np.count_nonzero(~np.asarray(self.feasible, bool)))
        dmin = float(np.min(self.min_distance)) if len(self.min_distance) else float("nan")
        figures = {"ticks": float(len(self.times_ms)), "infeasible_ticks": float(bad), "min_distance_m": dmin,
                   "max_iterations": float(np.max(self.iterations)) if len(self.iterations) else 0.0}
        timings = {"replan_median_s": float(np.median(self.times_ms)) / 1e3} if len(self.times_ms) else {}
        if bad == 0:
            return TrialOutcome(True, Failure.NONE, f"{len(self.times_ms)} clear re-plans", figures, timings)
        reason = Failure.COLLISION if dmin < 0 else Failure.INFEASIBLE
        return TrialOutcome(False, reason, f"{bad} of {len(self.times_ms)} re-plans not clear, min distance "
                            f"{1000 * dmin:.1f} mm", figures, timings)


def shifted(plan: np.ndarray) -> np.ndarray:
    """Warm start for the next tick: drop the executed first step, repeat the goal."""
    return np.vstack([plan[1:], plan[-1:]])


def receding_horizon(robot: Robot, static_obstacles: Sequence[Obstacle], moving: Obstacle,
                     trajectory: Callable[[float], np.ndarray], start: ArrayLike, goal: ArrayLike, *, N: int, dt: float,
                     ticks: int, settings: PlannerSettings | None = None, vmax: ArrayLike | None = None,
                     amax: ArrayLike | None = None) -> ReplanResult:
    """Run ``ticks`` receding-horizon re-plans while ``moving`` (an obstacle) follows ``trajectory``.

    Args:
        robot: the robot.
        static_obstacles: obstacles that stay put.
        moving: a :mod:`robointel.geometry` obstacle; at tick k it is moved to ``trajectory(k * dt)``.
        trajectory: time (s) -> centre (3,) of the moving obstacle.
        start: (n,) start configuration, rad.
        goal: (n,) goal configuration, rad.
        N: horizon steps.
        dt: time step, s.
        ticks: number of re-plans.
        settings: planner settings (default :class:`PlannerSettings`).
        vmax: (n,) velocity limits, rad/s (default the robot's).
        amax: (n,) acceleration limits, rad/s^2 (default the robot's).

    Returns:
        The executed path and the per-tick planning figures.

    Raises:
        InvalidInput: ``ticks`` < 1 or bad shapes.
    """
    start = as_array(start, "start", (robot.nq,))
    goal = as_array(goal, "goal", (robot.nq,))
    if int(ticks) < 1:
        raise InvalidInput(f"ticks must be >= 1, got {ticks}", value=ticks)
    static = list(static_obstacles)
    planner = TrajectoryPlanner(robot, static + [moving], N=N, dt=dt, vmax=vmax, amax=amax, settings=settings)
    x = start.copy()
    plan = planner.plan_segment(x, goal).path
    times, iters, feas, dmin, executed, obs = [], [], [], [], [x.copy()], []
    for k in range(int(ticks)):
        x = plan[1].copy()  # the robot executes one step of the current plan
        executed.append(x.copy())
        c = as_array(trajectory((k + 1) * dt), "obstacle centre", (3,))
        obs.append(c)
        planner.set_obstacles(static + [moving.moved(c)])
        t0 = time.perf_counter()
        seg = planner.plan_segment(x, goal, init=shifted(plan))
        times.append((time.perf_counter() - t0) * 1e3)
        iters.append(seg.iterations)
        feas.append(seg.feasible)
        dmin.append(seg.min_distance)
        plan = seg.path
    return ReplanResult(times_ms=np.array(times), iterations=np.array(iters), feasible=np.array(feas),
                        min_distance=np.array(dmin), executed=np.array(executed), obstacle_path=np.array(obs))
