"""Kinematic imitation on the LR Mate (Ch. 3.2, (3.1)).

The TCP follows the operator's hand relative to the hip centre,

    p_d = p_h - p_c                                                        (3.1)

mapped into the robot's workspace by one uniform scale and an offset (the body frame of
:mod:`robointel.teach.skeleton` is already x forward, y left, z up, like the robot's), with a
fixed tool orientation. Every frame is solved with the closed-form IK, choosing the solution
closest to the previous one (continuity); unreachable targets hold the last pose and are counted.
The 30 Hz joint targets become a 1 kHz reference through ``ruckig`` (jerk-limited online
trajectory generation within the joint velocity and acceleration limits), so the limits are
respected by construction; a *limit hit* is a frame whose raw IK motion would have exceeded them.
The reference is then tracked by the simulated robot (``robointel.sim.Workcell``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import CubicSpline

from robointel._validate import as_array
from robointel.control import JerkLimitedFollower
from robointel.errors import IKFailure, InvalidInput
from robointel.outcome import Failure, TrialOutcome
from robointel.sim import TrackingLog, Workcell
from robointel.teach.skeleton import Skeleton, clean
from robointel.trajectory import Trajectory

if TYPE_CHECKING:  # pragma: no cover
    from pathlib import Path

    from robointel.robot import Robot

#: Default workspace box for the TCP (robot root frame, m): every point is reachable with the
#: default tool orientation, and J5 stays away from the wrist singularity there.
WORKSPACE_LO = np.array([0.30, -0.30, 0.15])
WORKSPACE_HI = np.array([0.60, 0.30, 0.60])
#: Default fixed tool orientation: the flange's approach axis (x) pointing down (Ry(pi/2)).
TOOL_DOWN = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


@dataclass(frozen=True)
class WorkspaceMap:
    """p_robot = center_robot + scale * (p_human - center_human)  [m]."""

    scale: float
    center_human: np.ndarray
    center_robot: np.ndarray

    def __call__(self, p: np.ndarray) -> np.ndarray:
        """Map hand positions ``p`` (..., 3), m, into the robot workspace, m."""
        return self.center_robot + self.scale * (np.asarray(p, float) - self.center_human)


def fit_workspace(d: np.ndarray, lo: ArrayLike = WORKSPACE_LO, hi: ArrayLike = WORKSPACE_HI, *,
                  max_scale: float = 1.0) -> WorkspaceMap:
    """Fit the workspace map: one uniform scale and an offset.

    Uniform scale (<= ``max_scale``) and offset putting the hand-minus-hip path ``d`` (N, 3) inside the box [lo, hi]
    (centred), preserving the shape of the motion.
    """
    d = as_array(d, "d", (None, 3))
    lo, hi = as_array(lo, "lo", (3,)), as_array(hi, "hi", (3,))
    if np.any(hi <= lo):
        raise InvalidInput("workspace box needs hi > lo on every axis", value=(lo, hi))
    dmin, dmax = d.min(axis=0), d.max(axis=0)
    ext = np.maximum(dmax - dmin, 1e-6)
    scale = float(min(max_scale, np.min((hi - lo) / ext)))
    return WorkspaceMap(scale, 0.5 * (dmin + dmax), 0.5 * (lo + hi))


@dataclass
class ImitationPlan:
    """The robot motion derived from a skeleton.

    Attributes:
        t: (N,) frame times [s]; p_target: (N, 3) TCP targets [m]; q_ik: (N, 6) IK per frame [rad];
        reachable: (N,) IK found a solution; limit_hits: (6,) frames per joint whose raw IK
        velocity or acceleration exceeded the limit; trajectory: the 1 kHz jerk-limited joint
        reference (s, rad, rad/s, rad/s^2); mapping: the workspace map; source: the recording.
    """

    t: np.ndarray
    p_target: np.ndarray
    R_tool: np.ndarray
    q_ik: np.ndarray
    reachable: np.ndarray
    limit_hits: np.ndarray
    trajectory: Trajectory
    mapping: WorkspaceMap
    source: str = ""


def hand_targets(skel: Skeleton, *, side: str | None = None, mapping: WorkspaceMap | None = None,
                 lo: ArrayLike = WORKSPACE_LO, hi: ArrayLike = WORKSPACE_HI) -> tuple[np.ndarray, WorkspaceMap]:
    """(N, 3) TCP targets p_d = map(p_h - p_c) (3.1) and the map used."""
    side = side or skel.active_side()
    a = skel.arm(side)
    d = a["hand"] - a["hip"]
    mapping = mapping or fit_workspace(d, lo, hi)
    return mapping(d), mapping


def solve_ik_path(robot: Robot, p: np.ndarray, R: np.ndarray,
                  q0: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form IK for each target with a fixed tool rotation, continuous along the path.

    Closed-form IK for each target (N, 3) with fixed rotation R, each solution the one closest to the previous
    (``q0`` for the first). Unreachable targets hold the previous solution.

    Returns: (q (N, n), reachable (N,) bool).
    """
    p = as_array(p, "p", (None, 3))
    R = as_array(R, "R", (3, 3))
    q_prev = None if q0 is None else robot.check_q(q0, "q0")
    out = np.zeros((len(p), robot.nq))
    ok = np.zeros(len(p), dtype=bool)
    T = np.eye(4)
    T[:3, :3] = R
    for k, pk in enumerate(p):
        T[:3, 3] = pk
        try:
            sols = robot.ik(T, q_ref=q_prev)
            q_prev = sols[0] if q_prev is not None else min(sols, key=lambda s: float(np.abs(s).sum()))
            ok[k] = True
        except IKFailure:
            if q_prev is None:
                continue
        out[k] = q_prev
    if not ok.any():
        raise IKFailure("no frame of the imitation path is reachable; adjust the workspace box", value=p)
    first = int(np.argmax(ok))
    out[:first] = out[first]
    return out, ok


def jerk_limited(t: np.ndarray, q: np.ndarray, vmax: ArrayLike, amax: ArrayLike, jmax: ArrayLike, *, dt: float = 0.001,
                 lower: ArrayLike | None = None, upper: ArrayLike | None = None, gain: float = 12.0,
                 joint_names: list[str] | None = None) -> Trajectory:
    """Jerk-limited joint reference through joint targets.

    Follows the C2 spline through the targets within velocity, acceleration and jerk limits with a
    :class:`~robointel.control.JerkLimitedFollower` (ruckig).

    Args:
        t: (N,) target times, s.
        q: (N, n) joint targets, rad.
        vmax: (n,) velocity limits, rad/s.
        amax: (n,) acceleration limits, rad/s^2.
        jmax: (n,) jerk limits, rad/s^3.
        dt: step of the reference, s.
        lower: (n,) lower joint limits the targets are clipped to, rad (optional).
        upper: (n,) upper joint limits, rad (with ``lower``).
        gain: position feedback gain of the follower, 1/s.
        joint_names: n names of the result (default ``joint_1``...).

    Returns:
        The reference at 1/dt Hz from t[0] to t[-1].

    Raises:
        ShapeError, NotFinite: bad ``t`` or ``q``.
    """
    t = as_array(t, "t", (None,))
    q = as_array(q, "q", (len(t), None))
    n = q.shape[1]
    fol = JerkLimitedFollower(np.broadcast_to(as_array(vmax, "vmax"), (n,)), amax, jmax, dt=dt, gain=gain,
                              lower=lower, upper=upper)
    fol.reset(q[0])
    tg = np.arange(t[0], t[-1] + 0.5 * dt, dt)
    sp = CubicSpline(t, q, axis=0)
    S, SD = sp(tg), sp(tg, 1)
    if lower is not None:
        S = np.clip(S, lower, upper)
    Q = np.empty((len(tg), n))
    QD = np.empty_like(Q)
    QDD = np.empty_like(Q)
    for k in range(len(tg)):
        Q[k], QD[k], QDD[k] = fol.step(S[k], SD[k])
    return Trajectory(tg, Q, QD, QDD, list(joint_names or []))


def kinematic_imitation(skel: Skeleton, robot: Robot, *, side: str | None = None, R_tool: ArrayLike | None = None,
                        lo: ArrayLike = WORKSPACE_LO, hi: ArrayLike = WORKSPACE_HI, dt: float = 0.001,
                        cutoff_hz: float = 6.0, jerk_factor: float = 20.0) -> ImitationPlan:
    """Kinematic imitation (3.1): skeleton to a jerk-limited 1 kHz joint reference.

    Skeleton -> cleaned hand path -> TCP targets (3.1) -> closed-form IK -> jerk-limited 1 kHz joint reference
    within the robot's velocity and acceleration limits.

    Args:
        skel: raw skeleton (bridged and filtered here with :func:`clean`).
        robot: the LR Mate (any robot with ``ik``).
        R_tool: fixed 3x3 tool orientation (default ``TOOL_DOWN``; pointing forward, identity,
            puts the wrist at its singularity q5 = 0 in the middle of the workspace).
        side: "left" or "right" arm (default: the one that moves most).
        lo: (3,) lower corner of the TCP workspace box, m.
        hi: (3,) upper corner of the TCP workspace box, m.
        dt: step of the joint reference, s (1 kHz).
        cutoff_hz: low-pass cut-off of the skeleton filter, Hz.
        jerk_factor: jerk limit = jerk_factor * acceleration limit [rad/s^3].

    Returns:
        The plan: targets, per-frame IK and the jerk-limited joint reference (a :class:`Trajectory`).
    """
    side = side or skel.active_side()
    s = "Right" if side == "right" else "Left"
    c = clean(skel, cutoff_hz=cutoff_hz, joints=["SpineBase", f"Shoulder{s}", f"Elbow{s}", f"Hand{s}"])
    p, mapping = hand_targets(c, side=side, lo=lo, hi=hi)
    R = TOOL_DOWN if R_tool is None else as_array(R_tool, "R_tool", (3, 3))
    q_ik, ok = solve_ik_path(robot, p, R)
    v = np.abs(np.gradient(q_ik, c.t, axis=0))
    a = np.abs(np.gradient(np.gradient(q_ik, c.t, axis=0), c.t, axis=0))
    hits = np.sum((v > robot.velocity_limit) | (a > robot.acceleration_limit), axis=0)
    ref = jerk_limited(c.t, q_ik, robot.velocity_limit, robot.acceleration_limit,
                       jerk_factor * robot.acceleration_limit, dt=dt, lower=robot.lower, upper=robot.upper,
                       joint_names=list(robot.joint_names))
    return ImitationPlan(c.t, p, R, q_ik, ok, hits, ref, mapping, skel.source)


@dataclass
class ImitationRun:
    """A plan tracked in MuJoCo.

    ``log`` is the Workcell's TrackingLog; ``rms`` (6,) RMS of the simulated joints against the per-frame IK targets
    (the imitation error, rad); ``tracking_rms`` (6,) against the 1 kHz reference (the controller's error);
    ``tcp_rms`` RMS TCP distance to the hand targets [m]; ``tcp`` (N, 3) TCP at the frame times.
    """

    plan: ImitationPlan
    log: TrackingLog
    rms: np.ndarray
    tracking_rms: np.ndarray
    tcp_rms: float
    tcp: np.ndarray

    @property
    def outcome(self) -> TrialOutcome:
        """The run as a trial: ``Failure.COLLISION`` when the simulated robot touched its environment, else a success.

        Figures: ``tcp_rms_m``, ``max_joint_rms_rad`` (imitation error), ``max_tracking_rms_rad`` (controller
        error), ``unreachable_fraction`` (hand targets outside the arm's reach) and ``duration_s``.
        """
        figures = {"tcp_rms_m": float(self.tcp_rms), "max_joint_rms_rad": float(np.max(self.rms)),
                   "max_tracking_rms_rad": float(np.max(self.tracking_rms)),
                   "unreachable_fraction": float(1.0 - np.mean(self.plan.reachable)), "duration_s": self.log.duration}
        if self.log.collided:
            return TrialOutcome(False, Failure.COLLISION, f"contact in {int(np.count_nonzero(self.log.contacts))} "
                                f"control periods, min distance {1000 * self.log.min_distance:.1f} mm", figures)
        return TrialOutcome(True, Failure.NONE, f"TCP RMS error {1000 * self.tcp_rms:.1f} mm", figures)


def simulate_imitation(plan: ImitationPlan, robot: Robot, workcell: Workcell | None = None) -> ImitationRun:
    """Track the plan's reference in the MuJoCo workcell (1 kHz PID + feed-forward, Fig. 2.3)."""
    if workcell is None:
        workcell = Workcell(robot, ft_sensor=False)
    log = workcell.run_trajectory(plan.trajectory, record_ft=False)
    tq = plan.trajectory.t[: len(log.q)]
    target = np.stack([np.interp(tq, plan.t, plan.q_ik[:, j]) for j in range(robot.nq)], axis=1)
    rms = np.sqrt(np.mean((log.q - target) ** 2, axis=0))
    idx = np.searchsorted(tq, plan.t).clip(0, len(tq) - 1)
    tcp = np.array([robot.fk(log.q[i])[:3, 3] for i in idx])
    d = np.linalg.norm(tcp - plan.p_target, axis=1)
    return ImitationRun(plan, log, rms, log.rms_error, float(np.sqrt(np.mean(d ** 2))), tcp)


def plot_imitation(run: ImitationRun, path: str | Path) -> None:
    """Joint targets vs simulated joints, and the TCP path against the hand targets."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plan, log = run.plan, run.log
    fig = plt.figure(figsize=(12, 6))
    for j in range(6):
        ax = fig.add_subplot(3, 3, j + 1)
        ax.plot(plan.t, plan.q_ik[:, j], "k.", ms=2, label="IK per frame")
        ax.plot(plan.trajectory.t[: len(log.q)], log.q[:, j], "C0-", lw=1, label="LR Mate (MuJoCo)")
        ax.set_title(f"J{j + 1}: RMS {run.rms[j]:.4f} rad, {int(plan.limit_hits[j])} limit hits", fontsize=8)
        ax.tick_params(labelsize=7)
        if j == 0:
            ax.legend(fontsize=6)
    ax = fig.add_subplot(3, 3, (7, 9))
    labels = "xyz"
    for i in range(3):
        ax.plot(plan.t, plan.p_target[:, i], "--", color=f"C{i}", lw=1, label=f"hand target {labels[i]}")
        ax.plot(plan.t, run.tcp[:, i], "-", color=f"C{i}", lw=1, label=f"TCP {labels[i]}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("TCP target [m]")
    ax.legend(fontsize=6, ncol=3)
    fig.suptitle(f"Kinematic imitation (3.1) on the LR Mate: {plan.source}; TCP RMS {run.tcp_rms * 1000:.1f} mm, "
                 f"{int((~plan.reachable).sum())} unreachable frames", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
