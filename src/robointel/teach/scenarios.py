"""The guidance scenarios of Table 4.1 with a simulated operator (Ch. 4, Fig. 4.6).

Three cylinder obstacles (diameter 70 mm), given in the FANUC world frame (the ROS ``base`` frame,
0.330 m above the robot's mounting plane ``base_link``) and converted here to the robot's root
frame, in which the controller, the sphere model and the MuJoCo workcell all work:

=====  ============  ==========================  ==========================
 no.   where          end centre A (mm, base)     end centre B (mm, base)
=====  ============  ==========================  ==========================
 I     lower front    (480, -500, 13)             (480, 500, 13)
 II    upper front    (710, -500, 546)            (710, 500, 546)
 III   beside         (230, 430, -330)            (230, 430, 670)
=====  ============  ==========================  ==========================

A simulated operator holds the handle (the tool after the F/T sensor) and pulls it toward a target
moving along an intended path that would hit the obstacle: a spring-damper hand
F_h = K_h (p_target - p) - B_h v, saturated at ``max_force``. In scenario II the intended path
goes straight into the bar: the operator pushes into the obstacle on purpose.

:func:`run_scenario` runs it in the MuJoCo :class:`robointel.sim.Workcell` (the real loop: the
hand's wrench is applied in the physics, read back by the F/T sensor with bias and noise,
compensated with the identified payload, and the controller's joint velocity command is tracked by
the joint controller); ``physics=False`` integrates the command kinematically instead (fast, for
tests). :func:`plot_scenario` draws the four panels of Fig. 4.6b.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from robointel.control import PayloadCompensation, shift_wrench, wrench_to_world
from robointel.errors import InvalidInput, TargetInCollision
from robointel.geometry import Cylinder
from robointel.outcome import Failure, TrialOutcome
from robointel.robot import Robot
from robointel.sim import Workcell
from robointel.sim.mjcf import Payload
from robointel.sim.workcell import FTSensor
from robointel.teach.collision_guard import CollisionGuard
from robointel.teach.ft_identification import calibrate_in_workcell
from robointel.teach.guidance import GuidanceConfig, GuidanceController
from robointel.teach.keypoints import blended_trajectory

__all__ = ["BASE_HEIGHT", "OBSTACLE_RADIUS", "OUTCOME_FIGURES", "SCENARIOS", "Scenario", "ScenarioResult",
           "SimulatedOperator", "plot_scenario", "run_scenario", "scenario", "table_4_1_obstacles"]

BASE_HEIGHT = 0.330  # FANUC world frame ("base") above the mounting plane (base_link), m
OBSTACLE_RADIUS = 0.035  # 70 mm diameter
#: how far ahead (s) each guidance command is checked against the table, the floor and self-collision
GUARD_LOOKAHEAD = 0.02
#: the figures of :attr:`ScenarioResult.outcome` (keys of :meth:`ScenarioResult.metrics`)
OUTCOME_FIGURES = ("min_distance_m", "max_penetration_m", "robot_obstacle_contacts", "mean_velocity_deviation",
                   "held_steps", "duration_s")
_TABLE_4_1_MM = {1: ((480, -500, 13), (480, 500, 13)),
                 2: ((710, -500, 546), (710, 500, 546)),
                 3: ((230, 430, -330), (230, 430, 670))}
_NAMES = {1: "I: lower front", 2: "II: upper front", 3: "III: beside (pillar)"}


def table_4_1_obstacles() -> dict[int, Cylinder]:
    """The three Table 4.1 cylinders in the robot root frame (``base_link``), keyed 1, 2, 3."""
    off = np.array([0.0, 0.0, BASE_HEIGHT])
    return {k: Cylinder(np.array(a, float) / 1000 + off, np.array(b, float) / 1000 + off, OBSTACLE_RADIUS)
            for k, (a, b) in _TABLE_4_1_MM.items()}


@dataclass(frozen=True)
class Scenario:
    """One guidance scenario.

    Attributes:
        number: 1, 2 or 3 (Table 4.1).
        name: short description.
        obstacle: the cylinder, robot root frame.
        waypoints: (3, 3) intended TCP path (root frame, m): start, a point beyond the obstacle
            (the operator pushes toward it), and the point the operator retreats to.
        speed: operator's intended speed along the path, m/s.
        dwell: time the operator keeps pushing toward the second waypoint, s.
        on_purpose: the operator deliberately pushes into the obstacle.
    """

    number: int
    name: str
    obstacle: Cylinder
    waypoints: np.ndarray
    speed: float = 0.12
    dwell: float = 1.0
    on_purpose: bool = False


# intended TCP paths (robot root frame, tool pointing down); each would hit the obstacle
_PATHS = {  # start, beyond the obstacle, retreat
    1: ([0.35, -0.30, 0.65], [0.62, 0.10, 0.20], [0.45, 0.0, 0.50]),   # down and forward over the low bar
    2: ([0.60, -0.15, 0.55], [0.68, 0.15, 0.80], [0.55, 0.05, 0.60]),   # up under the high bar, into it
    3: ([0.45, -0.30, 0.45], [0.05, 0.60, 0.45], [0.40, 0.10, 0.50]),   # swing left into the pillar
}


def scenario(number: int) -> Scenario:
    """Scenario I, II or III (``number`` 1, 2, 3)."""
    if number not in (1, 2, 3):
        raise InvalidInput(f"scenario must be 1, 2 or 3 (Table 4.1), got {number!r}", value=number)
    return Scenario(number, _NAMES[number], table_4_1_obstacles()[number], np.array(_PATHS[number], float),
                    on_purpose=number == 2)


SCENARIOS = (1, 2, 3)


@dataclass
class SimulatedOperator:
    """A human hand as a saturated spring-damper pulling the handle along an intended path.

    The target moves from ``waypoints[0]`` to ``waypoints[1]`` (blended line segments), stays
    there for ``dwell`` seconds (the hand keeps pushing) and, with a third waypoint, then moves
    back to it (the operator retreats).

    Attributes:
        waypoints: (2 or 3, 3) path, m. speed: along it, m/s. dwell: pause at waypoints[1], s.
        stiffness: K_h, N/m. damping: B_h, N s/m. max_force: saturation, N.
        rot_stiffness: how the hand resists tool rotation, N m/rad.
    """

    waypoints: np.ndarray
    speed: float = 0.12
    dwell: float = 1.0
    stiffness: float = 250.0
    damping: float = 5.0
    max_force: float = 30.0
    rot_stiffness: float = 2.0

    def __post_init__(self) -> None:
        P = np.asarray(self.waypoints, float)
        if P.ndim != 2 or P.shape[1] != 3 or not 2 <= len(P) <= 3:
            raise InvalidInput("waypoints must be (2, 3) or (3, 3)", value=self.waypoints)
        self.waypoints = P
        self.legs = [blended_trajectory(P[:2], speed=self.speed, blend_time=0.5, kind="quintic")]
        if len(P) == 3:
            self.legs.append(blended_trajectory(P[1:], speed=self.speed, blend_time=0.5, kind="quintic"))

    @property
    def duration(self) -> float:
        """Time until the target comes to rest at the end of the path, s."""
        return sum(leg.duration for leg in self.legs) + self.dwell

    def target(self, t: float) -> np.ndarray:
        """Target point (3,) at time t, s."""
        return self.targets(np.array([float(t)]))[0]

    def targets(self, t: ArrayLike) -> np.ndarray:
        """Target points (M, 3) at times t (M,), s."""
        t = np.asarray(t, float)
        T1 = self.legs[0].duration
        out = self.legs[0](t)[0]
        if len(self.legs) == 2:
            late = t > T1 + self.dwell
            out[(t > T1) & ~late] = self.waypoints[1]
            if late.any():
                out[late] = self.legs[1](t[late] - T1 - self.dwell)[0]
        return out

    def wrench(self, t: float, T_tcp: np.ndarray, v_tcp: np.ndarray, R_hold: np.ndarray,
               target: np.ndarray | None = None) -> np.ndarray:
        """Hand wrench [f.

        Tau] (6,) on the handle, world axes, about the TCP (``target``: the precomputed :meth:`target` at t).
        """
        p = self.target(t) if target is None else target
        f = self.stiffness * (p - T_tcp[:3, 3]) - self.damping * v_tcp
        nf = np.linalg.norm(f)
        if nf > self.max_force:
            f *= self.max_force / nf
        tau = self.rot_stiffness * pin.log3(R_hold @ T_tcp[:3, :3].T)
        return np.concatenate([f, tau])


@dataclass
class ScenarioResult:
    """Time series of one scenario run (1 kHz) and its figures.

    Attributes:
        t: (T,) s. q: (T, n). tcp: (T, 3) TCP position, m. target: (T, 3) operator target, m.
        distance: (T,) controller's sphere-model distance to the obstacle, m.
        true_distance: (T,) distance between the robot's collision geometry and the obstacle
            (MuJoCo ``mj_geomDistance``; NaN where not evaluated; sphere model without physics).
        v_lead, v_cmd: (T, 6) lead and commanded TCP twists.
        approach_rate: (T,) u_rep^T J_rep qd, the closest point's speed away from the obstacle.
        weight: (T,) blend weight lambda. active: (T,) obstacles inside d0. held: (T,) bool.
        step_us: (T,) controller step wall time, microseconds.
        step_cpu_us: (T,) the same step's CPU (thread) time, microseconds: excludes preemption.
    """

    scenario: int
    method: str
    t: np.ndarray
    q: np.ndarray
    tcp: np.ndarray
    target: np.ndarray
    distance: np.ndarray
    true_distance: np.ndarray
    v_lead: np.ndarray
    v_cmd: np.ndarray
    approach_rate: np.ndarray
    weight: np.ndarray
    active: np.ndarray
    held: np.ndarray
    step_us: np.ndarray
    physics: bool = True
    contacts: int = 0
    extra: dict = field(default_factory=dict)
    step_cpu_us: np.ndarray | None = None

    @property
    def deviation(self) -> np.ndarray:
        """||V_cmd - V_lead|| (translation), m/s, (T,).

        While the controller holds after an F/T fault, V_cmd = 0 and V_lead is the leading twist of the reading (the
        operator's intent; NaN for a NaN reading).
        """
        return np.linalg.norm(self.v_cmd[:, :3] - self.v_lead[:, :3], axis=1)

    def metrics(self) -> dict:
        """The figures of Table 4.2, as plain floats."""
        dev = self.deviation
        cpu = self.step_cpu_us
        act = self.active > 0
        td = self.true_distance[np.isfinite(self.true_distance)]
        dmin = float(np.min(td)) if td.size else float(np.nanmin(self.distance))
        return {
            "min_distance_m": dmin,
            "min_sphere_distance_m": float(np.nanmin(self.distance)),
            "held_steps": int(np.sum(self.held)),
            "max_penetration_m": float(max(0.0, -dmin)),
            "robot_obstacle_contacts": int(self.contacts),
            "mean_velocity_deviation": float(np.nanmean(dev)),
            "max_velocity_deviation": float(np.nanmax(dev)),
            "mean_velocity_deviation_active": float(np.nanmean(dev[act])) if act.any() else 0.0,
            "mean_angular_deviation": float(np.nanmean(np.linalg.norm(self.v_cmd[:, 3:] - self.v_lead[:, 3:], axis=1))),
            "min_approach_rate_active": float(np.min(self.approach_rate[act])) if act.any() else 0.0,
            "active_fraction": float(np.mean(act)),
            "step_us_median": float(np.median(self.step_us)),
            "step_us_p99": float(np.percentile(self.step_us, 99)),
            "step_cpu_us_median": float(np.median(cpu)) if cpu is not None else float("nan"),
            "step_cpu_us_p99": float(np.percentile(cpu, 99)) if cpu is not None else float("nan"),
            "duration_s": float(self.t[-1] - self.t[0]) if len(self.t) else 0.0,
        }

    @property
    def outcome(self) -> TrialOutcome:
        """The scenario as a trial: success when the robot never touched or penetrated the obstacle.

        A failure is ``Failure.COLLISION``. Figures: :data:`OUTCOME_FIGURES` of :meth:`metrics`.
        """
        m = self.metrics()
        ok = m["robot_obstacle_contacts"] == 0 and m["max_penetration_m"] <= 0.0
        detail = f"min distance {1000 * m['min_distance_m']:.1f} mm, {m['robot_obstacle_contacts']} contacts"
        return TrialOutcome(ok, Failure.NONE if ok else Failure.COLLISION, detail,
                            {k: float(m[k]) for k in OUTCOME_FIGURES})


def _start_configuration(robot: Robot, p0: np.ndarray) -> np.ndarray:
    """IK of the start TCP position with the tool pointing down, elbow up, closest to q_home."""
    q_home = np.array([0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0])
    T = robot.fk(q_home)
    T[:3, 3] = p0
    return robot.ik(T, q_ref=q_home)[0]


def run_scenario(number: int, method: str = "qp", *, duration: float | None = None, physics: bool = True,
                 config: GuidanceConfig | None = None, robot: Robot | None = None, ft_noise: float = 0.05,
                 ft_bias: ArrayLike = (1.5, -0.8, 2.0, 0.05, -0.03, 0.02), identify: bool = True,
                 progress: Callable[[float], None] | None = None, seed: int = 0) -> ScenarioResult:
    """Run scenario ``number`` with a guidance ``method`` and a simulated operator.

    Args:
        number: 1, 2, 3 (Table 4.1).
        method: "qp", "equality", "repulsive" or "nullspace".
        duration: simulated seconds (default: the operator's whole path plus 0.5 s).
        physics: True: MuJoCo workcell with the F/T sensor in the loop; False: kinematic
            integration of the command (q += qd dt), hand wrench fed to the controller directly.
        config: controller configuration (its ``method`` is replaced by ``method``).
        ft_noise: F/T noise std (N; torques get a tenth, N m).
        ft_bias: F/T bias [N, N m], identified away before guiding.
        identify: identify payload and bias first (3.14)-(3.19); else use the true values.
        robot: the arm (default: a freshly loaded LR Mate 200iD/7L).
        progress: called with the fraction done.
        seed: seed of the F/T sensor noise.
    """
    sc = scenario(number)
    robot = robot or Robot.load("lrmate200id7l")
    cfg = replace(config or GuidanceConfig(), method=method)
    ctl = GuidanceController(robot, [sc.obstacle], cfg)
    op = SimulatedOperator(sc.waypoints, speed=sc.speed, dwell=sc.dwell)
    q0 = _start_configuration(robot, sc.waypoints[0])
    R_hold = robot.fk(q0)[:3, :3]
    if duration is not None and not (np.isfinite(duration) and duration > 0):
        raise InvalidInput(f"duration must be a positive number of simulated seconds, got {duration}", value=duration)
    guard = CollisionGuard(robot)
    T_end = op.duration + 0.5 if duration is None else float(duration)
    N = int(round(T_end / 0.001))
    n = robot.nq
    log = {k: np.zeros((N, w)) for k, w in (("q", n), ("tcp", 3), ("target", 3), ("v_lead", 6), ("v_cmd", 6))}
    dist, tdist, rate, lam, act, held, us = (np.full(N, np.nan), np.full(N, np.nan), np.zeros(N), np.zeros(N),
                                             np.zeros(N, int), np.zeros(N, bool), np.zeros(N))
    cpu = np.zeros(N)
    contacts = 0
    extra: dict = {}
    wc = comp = None
    if physics:
        payload = Payload(mass=0.6, com=(0.04, 0.0, 0.01), radius=0.03)
        sens = FTSensor(bias=np.asarray(ft_bias, float), noise_std=np.r_[[ft_noise] * 3, [ft_noise / 10] * 3],
                        seed=seed)
        wc = Workcell(robot, obstacles=[sc.obstacle], ft_sensor=sens, payload=payload, q0=q0)
        if identify:
            cal = calibrate_in_workcell(wc, q0)
            extra["identified_mass"] = cal.mass
            extra["identified_com"] = cal.com.tolist()
            comp = cal.payload
        else:
            bias = np.asarray(ft_bias, float)
            comp = PayloadCompensation(payload.mass, np.asarray(payload.com, float), bias[:3], bias[3:])
        wc.reset(q0)
        wc.hold(0.05)
    q = q0.copy()
    qd_prev = np.zeros(n)
    t0 = wc.time if wc is not None else 0.0
    targets = op.targets(np.arange(N) * 0.001)
    log["target"][:] = targets
    for i in range(N):
        t = i * 0.001
        if wc is not None:
            q = wc.q
        T = robot.fk(q)
        v_tcp = ctl.tcp_jacobian(q)[:3] @ (wc.qd if wc is not None else qd_prev)
        hand = op.wrench(t, T, v_tcp, R_hold, targets[i])
        if wc is not None:
            wc.apply_wrench(hand[:3], hand[3:], point=T[:3, 3])
            raw = wc.ft_reading()
            Rs = wc.sensor_pose()[:3, :3]
            assert comp is not None  # identified or given above whenever there is a workcell
            # external wrench in world axes, torque about the TCP (sensor origin: the flange; TCP = flange + tool)
            w_world = shift_wrench(wrench_to_world(comp.compensate(raw, Rs), Rs), T[:3, 3] - wc.sensor_pose()[:3, 3])
        else:
            w_world = hand
        k0, c0 = time.thread_time_ns(), time.perf_counter_ns()
        s = ctl.step(q, w_world)
        c1, k1 = time.perf_counter_ns(), time.thread_time_ns()
        us[i], cpu[i] = (c1 - c0) / 1e3, (k1 - k0) / 1e3
        try:  # the table, the floor and self-collision: checked GUARD_LOOKAHEAD ahead, else hold
            guard.check(q + s.qd * GUARD_LOOKAHEAD, "guidance command")
        except TargetInCollision as exc:
            s = replace(s, qd=np.zeros(n))
            extra["guard_holds"] = extra.get("guard_holds", 0) + 1
            extra.setdefault("guard_reason", str(exc))
        if wc is not None:
            wc.command_velocity(s.qd)
            ncon = _obstacle_contacts(wc)
            contacts += ncon
            if i % 5 == 0 or ncon or s.distance < 0.02:
                tdist[i] = wc.obstacle_distance(distmax=0.3)[0]
        else:
            q = np.clip(q + s.qd * 0.001, robot.lower, robot.upper)
            qd_prev = s.qd
        log["q"][i], log["tcp"][i] = q, T[:3, 3]
        log["v_cmd"][i] = s.v_cmd
        if s.held:  # the operator still pushes: their intent is the leading twist of the reading
            log["v_lead"][i] = ctl.lead_twist(w_world) if np.isfinite(w_world).all() else np.nan
        else:
            log["v_lead"][i] = s.v_lead
        dist[i], rate[i], lam[i], act[i], held[i] = s.distance, s.approach_rate, s.weight, s.active, s.held
        if progress is not None and i % 250 == 0:
            progress(i / N)
    if wc is not None:
        wc.clear_wrench()
    tdist[tdist >= 0.3] = np.nan  # beyond distmax: not evaluated
    return ScenarioResult(number, method, t0 + np.arange(N) * 0.001, log["q"], log["tcp"], log["target"], dist, tdist,
                          log["v_lead"], log["v_cmd"], rate, lam, act, held, us, physics=physics, contacts=contacts,
                          extra=extra, step_cpu_us=cpu)


def _obstacle_contacts(wc: Workcell) -> int:
    d = wc.data
    if d.ncon == 0:
        return 0
    return sum(1 for c in wc.contacts() if c.kind == "obstacle" and c.distance < 0)


def plot_scenario(result: ScenarioResult, path: str | Path, *, d0: float = 0.15) -> Path:
    """Four panels like Fig. 4.6b: distance, lead vs commanded speed, deviation, approach rate.

    Returns the PNG path.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r = result
    t = r.t - r.t[0]
    act = r.active > 0
    fig, ax = plt.subplots(4, 1, figsize=(8, 9), sharex=True)
    ax[0].plot(t, r.distance * 1e3, label="sphere model (controller)")
    if np.isfinite(r.true_distance).any():
        m = np.isfinite(r.true_distance)
        ax[0].plot(t[m], r.true_distance[m] * 1e3, ".", ms=2, label="collision geometry (MuJoCo)")
    ax[0].axhline(d0 * 1e3, ls="--", c="gray", lw=0.8, label="d0")
    ax[0].axhline(0, c="k", lw=0.8)
    ax[0].set_ylabel("distance [mm]")
    ax[0].legend(fontsize=7, loc="upper right")
    ax[1].plot(t, np.linalg.norm(r.v_lead[:, :3], axis=1), label="||V_lead||")
    ax[1].plot(t, np.linalg.norm(r.v_cmd[:, :3], axis=1), label="||V_cmd||")
    ax[1].set_ylabel("speed [m/s]")
    ax[1].legend(fontsize=7, loc="upper right")
    ax[2].plot(t, r.deviation, c="C3")
    ax[2].set_ylabel("||V_cmd - V_lead|| [m/s]")
    ax[3].plot(t, np.where(act, r.approach_rate, np.nan), c="C2")
    ax[3].axhline(0, c="k", lw=0.8)
    ax[3].set_ylabel("V_cmd . u_rep [m/s]\n(avoidance active)")
    ax[3].set_xlabel("time [s]")
    for a in ax:
        if act.any():
            a.fill_between(t, 0, 1, where=act, transform=a.get_xaxis_transform(), color="orange", alpha=0.12, lw=0)
    m = r.metrics()
    fig.suptitle(f"Scenario {_NAMES[r.scenario]} - method {r.method}: min distance {m['min_distance_m'] * 1e3:.1f} mm, "
                 f"mean deviation {m['mean_velocity_deviation']:.3f} m/s", fontsize=9)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
