"""The fast robot motion planner (FRMP, Sec.

7.4): scene -> CFS path -> temporal optimization -> time-stamped trajectory -> checks on a dense resample ->
execution in the MuJoCo workcell.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from robointel.errors import InvalidInput
from robointel.geometry.table import ENVIRONMENT_NAMES
from robointel.outcome import Failure, TrialOutcome
from robointel.planning.scene import Scene
from robointel.planning.segment import self_clearances
from robointel.planning.temporal import TemporalResult, concatenate_segments, fixed_dt_segment, temporal_optimize
from robointel.planning.waypoints import PlannerSettings, SegmentPlan, TrajectoryPlanner, sphere_clearances
from robointel.trajectory import Trajectory

if TYPE_CHECKING:  # pragma: no cover
    from robointel.robot import Robot
    from robointel.sim import Workcell


@dataclass
class TrajectoryCheck:
    """Dense (1 ms) checks of a trajectory.

    Attributes:
        min_clearance: smallest robot-sphere/obstacle distance (m; inf without obstacles).
        limit_violations: number of samples where a joint exceeds its position, velocity or
            acceleration limit (relative tolerance 1e-6).
        max_velocity_ratio, max_acceleration_ratio: largest |qd|/vmax and |qdd|/amax.
        samples: number of samples checked.
        worst_link, worst_obstacle: where the clearance is smallest.
        min_self_clearance: smallest distance between the spheres of a self-collision pair (m; inf
            without self pairs); negative: the arm hits itself.
        self_links: the two links of that pair.
    """

    min_clearance: float
    limit_violations: int
    max_velocity_ratio: float
    max_acceleration_ratio: float
    samples: int
    worst_link: str = ""
    worst_obstacle: str = ""
    min_self_clearance: float = float("inf")
    self_links: tuple[str, str] = ("", "")


def check_trajectory(traj: Trajectory, robot: Robot, obstacles: Any, vmax: ArrayLike, amax: ArrayLike, *,
                     dt: float = 0.001, rtol: float = 1e-6) -> TrajectoryCheck:
    """Resample ``traj`` every ``dt`` and check clearance (obstacles and self-collision pairs) and joint limits."""
    dense = traj.resample(dt)
    q, qd, qdd = dense.q, dense.qd, dense.qdd
    vmax = np.asarray(vmax, float)
    amax = np.asarray(amax, float)
    bad = ((q < robot.lower - 1e-9) | (q > robot.upper + 1e-9) |
           (np.abs(qd) > vmax * (1 + rtol)) | (np.abs(qdd) > amax * (1 + rtol)))
    viol = int(np.count_nonzero(np.any(bad, axis=1)))
    dmin, link, obs = np.inf, "", ""
    if len(obstacles):
        best: tuple[float, int, int, int] = (np.inf, 0, 0, 0)
        for s in range(0, len(q), 4000):
            D = sphere_clearances(robot, q[s:s + 4000], obstacles)
            i, j, k = (int(x) for x in np.unravel_index(int(np.argmin(D.d)), D.d.shape))
            if D.d[i, j, k] < best[0]:
                best = (float(D.d[i, j, k]), int(D.spheres[j]), k, s + i)
        dmin = best[0]
        link = robot.spheres.links[best[1]]
        obs = obstacles[best[2]].label(best[2])
    smin, pair = np.inf, ("", "")
    sm = robot.spheres
    if len(sm.self_pairs):
        for s in range(0, len(q), 4000):
            ds, _ = self_clearances(robot, q[s:s + 4000])
            i, p = (int(x) for x in np.unravel_index(int(np.argmin(ds)), ds.shape))
            if ds[i, p] < smin:
                smin, pair = float(ds[i, p]), (sm.links[int(sm.self_pairs[p][0])], sm.links[int(sm.self_pairs[p][1])])
    return TrajectoryCheck(min_clearance=float(dmin), limit_violations=viol,
                           max_velocity_ratio=float(np.max(np.abs(qd) / vmax)),
                           max_acceleration_ratio=float(np.max(np.abs(qdd) / amax)), samples=len(q),
                           worst_link=link, worst_obstacle=obs, min_self_clearance=float(smin), self_links=pair)


@dataclass
class FRMPResult:
    """Everything the FRMP produced for one scene.

    Attributes:
        scene: the scene.
        segments: CFS plan of each segment.
        temporal: temporal optimization of each segment.
        path: (sum(steps)+1, n) CFS knots (rad) over the whole cycle.
        trajectory: the FRMP trajectory (temporally optimised).
        fixed: the fixed-dt trajectory through the same knots.
        cfs_ms, cfs_iterations, temporal_ms: per segment.
        plan_ms: total CFS time over all segments.
        check: dense checks of ``trajectory``.
    """

    scene: Scene
    segments: list[SegmentPlan]
    temporal: list[TemporalResult]
    path: np.ndarray
    trajectory: Trajectory
    fixed: Trajectory
    cfs_ms: list[float]
    cfs_iterations: list[int]
    temporal_ms: list[float]
    check: TrajectoryCheck
    extra: dict = field(default_factory=dict)

    @property
    def blocked(self) -> list[bool]:
        """Per segment: whether the straight path was in collision."""
        return [s.blocked for s in self.segments]

    @property
    def plan_ms(self) -> float:
        """Total CFS time over all segments, ms."""
        return float(sum(self.cfs_ms))

    @property
    def operational_time_fixed(self) -> float:
        """Cycle time of the fixed-dt schedule, s."""
        return self.fixed.duration

    @property
    def operational_time_frmp(self) -> float:
        """Cycle time of the FRMP trajectory, s."""
        return self.trajectory.duration

    def summary(self) -> dict:
        """The headline figures as a JSON-ready dict."""
        return {"scene": self.scene.name, "blocked": self.blocked, "cfs_ms": self.cfs_ms,
                "cfs_iterations": self.cfs_iterations, "temporal_ms": self.temporal_ms,
                "plan_ms": self.plan_ms, "operational_time_fixed_s": self.operational_time_fixed,
                "operational_time_frmp_s": self.operational_time_frmp,
                "min_clearance_m": self.check.min_clearance, "limit_violations": self.check.limit_violations,
                "status": [s.status for s in self.segments]}

    @property
    def outcome(self) -> TrialOutcome:
        """The plan as a trial: success when the dense check finds clearance, no self-collision, no limit violation.

        Failures: ``Failure.COLLISION`` (clearance <= 0), else ``Failure.LIMIT``. Figures: ``min_clearance_m``,
        ``limit_violations``, ``duration_s`` (cycle time) and ``plan_ms``.
        """
        c = self.check
        figures = {"min_clearance_m": float(c.min_clearance), "limit_violations": float(c.limit_violations),
                   "duration_s": float(self.trajectory.t[-1] - self.trajectory.t[0]), "plan_ms": self.plan_ms}
        if c.min_clearance <= 0.0:
            return TrialOutcome(False, Failure.COLLISION, f"clearance {c.min_clearance:.4f} m", figures)
        if c.min_self_clearance < 0.0:
            return TrialOutcome(False, Failure.COLLISION, f"self-collision: {c.self_links[0]} and {c.self_links[1]} "
                                f"{-c.min_self_clearance * 1e3:.1f} mm into each other", figures)
        if c.limit_violations:
            return TrialOutcome(False, Failure.LIMIT, f"{c.limit_violations} limit violations", figures)
        return TrialOutcome(True, Failure.NONE, f"clearance {1000 * c.min_clearance:.1f} mm", figures)


def planner_settings(scene: Scene) -> PlannerSettings:
    """:class:`PlannerSettings` of a scene (its d_min, weights and planner block)."""
    kw = dict(scene.planner)
    kw.setdefault("d_min", scene.d_min)
    kw["w1"] = scene.weights.get("w1", 1.0)
    kw["w2"] = scene.weights.get("w2", 0.02)
    return PlannerSettings(**kw)


def make_planners(scene: Scene) -> dict[int, TrajectoryPlanner]:
    """One :class:`TrajectoryPlanner` per distinct segment length (its OSQP workspace is reused)."""
    st = planner_settings(scene)
    return {N: TrajectoryPlanner(scene.robot, scene.obstacles, N=N, dt=scene.dt, vmax=scene.vmax,
                                 amax=scene.amax, settings=st) for N in sorted(set(scene.steps))}


def plan_scene(scene: Scene, *, planners: dict[int, TrajectoryPlanner] | None = None,
               progress: Callable[[float, str], None] | None = None) -> FRMPResult:
    """Run the FRMP on a scene.

    Check the waypoints, plan each segment by CFS, re-time each segment by temporal optimization, join the segments
    and check the result on a 1 ms grid.

    Raises:
        CollisionAtStart: a waypoint is in collision (names link and obstacle).
        LimitViolation: a waypoint is outside the joint limits.
        InfeasibleProblem: a segment's first QP is infeasible (limits too tight for its steps).
    """
    if not isinstance(scene, Scene):
        raise InvalidInput("plan_scene needs a Scene (robointel.planning.scene.load_scene), got "
                           f"{type(scene).__name__}",
                           value=scene)
    planners = planners or make_planners(scene)
    first = planners[scene.steps[0]]
    first.check_waypoints(scene.waypoints, scene.waypoint_names)
    segs, temps, cfs_ms, temporal_ms, fixed_parts, frmp_parts = [], [], [], [], [], []
    nseg = len(scene.steps)
    for i, N in enumerate(scene.steps):
        if progress:
            progress(i / nseg, f"segment {i + 1}/{nseg}: CFS")
        pl = planners[N]
        t0 = time.perf_counter()
        seg = pl.plan_segment(scene.waypoints[i], scene.waypoints[i + 1])
        cfs_ms.append((time.perf_counter() - t0) * 1e3)
        segs.append(seg)
        t0 = time.perf_counter()
        tr = temporal_optimize(seg.path, scene.vmax, scene.amax, dt=scene.dt, w3=scene.weights.get("w3", 1.0),
                               w4=scene.weights.get("w4", 1.0))
        temporal_ms.append((time.perf_counter() - t0) * 1e3)
        temps.append(tr)
        fixed_parts.append(fixed_dt_segment(seg.path, scene.dt))
        frmp_parts.append(tr.trajectory)
    names = list(scene.robot.joint_names)
    path = np.concatenate([segs[0].path] + [s.path[1:] for s in segs[1:]])
    traj = concatenate_segments(frmp_parts, names, {"scene": scene.name, "planner": "FRMP (CFS + temporal CFS)"})
    fixed = concatenate_segments(fixed_parts, names, {"scene": scene.name, "planner": "CFS, fixed dt"})
    if progress:
        progress(0.95, "dense checks")
    check = check_trajectory(traj, scene.robot, scene.obstacles, scene.vmax, scene.amax)
    traj.meta.update({"min_clearance_m": check.min_clearance, "limit_violations": check.limit_violations})
    return FRMPResult(scene=scene, segments=segs, temporal=temps, path=path, trajectory=traj, fixed=fixed,
                      cfs_ms=cfs_ms, cfs_iterations=[s.iterations for s in segs], temporal_ms=temporal_ms,
                      check=check)


@dataclass
class Execution:
    """The FRMP trajectory tracked in the MuJoCo workcell.

    Attributes:
        rms_error_rad, max_error_rad: tracking error over all joints (rad).
        max_tcp_error_m: largest TCP position error (m).
        obstacle_contacts: control periods with a robot-obstacle contact.
        min_distance_m: smallest robot-obstacle distance MuJoCo measured (m).
        collided: any contact with an obstacle.
        log: the :class:`robointel.sim.workcell.TrackingLog`.
    """

    rms_error_rad: float
    max_error_rad: float
    max_tcp_error_m: float
    obstacle_contacts: int
    min_distance_m: float
    collided: bool
    log: object

    @property
    def outcome(self) -> TrialOutcome:
        """The execution as a trial: ``Failure.COLLISION`` when the robot touched an obstacle, else a success.

        Figures: ``rms_error_rad``, ``max_error_rad``, ``max_tcp_error_m``, ``obstacle_contacts``, ``min_distance_m``.
        """
        figures = {"rms_error_rad": self.rms_error_rad, "max_error_rad": self.max_error_rad,
                   "max_tcp_error_m": self.max_tcp_error_m, "obstacle_contacts": float(self.obstacle_contacts),
                   "min_distance_m": self.min_distance_m}
        if self.collided:
            return TrialOutcome(False, Failure.COLLISION, f"{self.obstacle_contacts} control periods in contact, "
                                f"min distance {1000 * self.min_distance_m:.1f} mm", figures)
        return TrialOutcome(True, Failure.NONE, f"max TCP error {1000 * self.max_tcp_error_m:.1f} mm", figures)


def execute(result: FRMPResult, *, workcell: Workcell | None = None) -> Execution:
    """Track the FRMP trajectory with the workcell's 1 kHz controller (Fig. 2.3) and report."""
    scene = result.scene
    # the workcell builds its own table and floor: pass only the scene's other obstacles
    obstacles = [o for o in scene.obstacles if not (getattr(scene, "table", False)
                                                    and getattr(o, "name", None) in ENVIRONMENT_NAMES)]
    from robointel.sim import Workcell  # MuJoCo loads here, not with the planner

    wc = workcell or Workcell(scene.robot, obstacles=obstacles, ft_sensor=False)
    tr = result.trajectory
    log = wc.run_trajectory(tr, record_ft=False)
    err = log.error
    contacts = 0
    try:
        # periods where the robot touched an obstacle (not the table it stands on)
        contacts = int(np.count_nonzero(np.asarray(log.distance)[np.isfinite(log.distance)] < 0))
    except Exception:  # pragma: no cover - defensive
        contacts = int(np.count_nonzero(log.contacts))
    step = max(1, len(log.q) // 400)
    tcp = log.tcp_error(scene.robot)[::1] if len(log.q) <= 2000 else np.array(
        [np.linalg.norm(scene.robot.fk(a)[:3, 3] - scene.robot.fk(b)[:3, 3])
         for a, b in zip(log.q_ref[::step], log.q[::step])])
    return Execution(rms_error_rad=float(np.sqrt(np.mean(err ** 2))), max_error_rad=float(np.max(np.abs(err))),
                     max_tcp_error_m=float(np.max(tcp)), obstacle_contacts=contacts,
                     min_distance_m=float(log.min_distance),
                     collided=bool(contacts > 0 or log.min_distance < 0 or np.any(log.contacts > 0)),
                     log=log)
