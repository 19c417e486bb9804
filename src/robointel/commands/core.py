"""Core demo stage: the robot core and the MuJoCo workcell.

Cartesian waypoints -> closed-form IK (the branch continuous with the last) -> quintic joint
trajectory -> tracked by the Fig. 2.3 joint controller (PID at 1 kHz + model feed-forward) in MuJoCo.
"""
from __future__ import annotations

import time

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import numpy.typing as npt

from robointel.report.demo import Figure, StageContext, StageResult
from robointel.robot import Robot
from robointel.robot._kernels import points_jacobians  # noqa: F401  (compiled before the timing below)
from robointel.sim import Workcell

#: Cartesian TCP waypoints (position m in the base_link frame), tool pointing down.
WAYPOINTS = np.array([[0.45, -0.25, 0.45], [0.55, 0.0, 0.30], [0.45, 0.30, 0.45], [0.35, 0.0, 0.65],
                      [0.45, -0.25, 0.45]])


def quintic_path(waypoints: npt.NDArray[np.float64], durations: npt.NDArray[np.float64], dt: float = 0.001
                 ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64],
                            npt.NDArray[np.float64]]:
    """Sample rest-to-rest quintic segments through joint waypoints.

    Each segment follows ``a + (10 s^3 - 15 s^4 + 6 s^5) (b - a)`` with ``s = t / T``.

    Args:
        waypoints: Joint waypoints, shape (m, n), rad.
        durations: Segment durations, shape (m - 1,), s.
        dt: Sample interval, s.

    Returns:
        ``(t, q, qd, qdd)``: times (k,) s and joint positions, velocities and accelerations (k, n)
        in rad, rad/s, rad/s^2, ending at rest on the last waypoint.
    """
    ts: list[npt.NDArray[np.floating]] = []
    qs: list[npt.NDArray[np.floating]] = []
    qds: list[npt.NDArray[np.floating]] = []
    qdds: list[npt.NDArray[np.floating]] = []
    t0 = 0.0
    for a, b, T in zip(waypoints[:-1], waypoints[1:], durations):
        n = int(round(T / dt))
        s = np.arange(n) * dt / T
        p = 10 * s**3 - 15 * s**4 + 6 * s**5
        pd = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
        pdd = (60 * s - 180 * s**2 + 120 * s**3) / T**2
        d = b - a
        ts.append(t0 + np.arange(n) * dt)
        qs.append(a + p[:, None] * d)
        qds.append(pd[:, None] * d)
        qdds.append(pdd[:, None] * d)
        t0 += T
    ts.append(np.array([t0]))
    qs.append(waypoints[-1][None])
    qds.append(np.zeros((1, waypoints.shape[1])))
    qdds.append(np.zeros((1, waypoints.shape[1])))
    return np.concatenate(ts), np.concatenate(qs), np.concatenate(qds), np.concatenate(qdds)


def demo_stage(ctx: StageContext) -> StageResult:
    """Run the demo's core stage: IK through Cartesian waypoints, quintic joint path, MuJoCo tracking.

    Also times the collision-sphere kinematics and the closed-form IK.

    Args:
        ctx: The demo stage context (output folder, quick flag, progress).

    Returns:
        The stage's figures, images and text.
    """
    matplotlib.use("Agg")
    robot = Robot.load("lrmate200id7l")
    ctx.advance(0.05, "IK through waypoints")
    down = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0.0]])  # flange x axis (approach) pointing down
    q_prev = np.array([0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0])
    joint_list = []
    for p in WAYPOINTS:
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = down, p
        q_prev = robot.ik(T, q_ref=q_prev)[0]
        joint_list.append(q_prev)
    joints = np.array(joint_list)
    # segment durations from the joint speed limits (at most 40% of the limit at the quintic peak)
    dur = np.array([max(0.6, float(np.max(1.875 * np.abs(b - a) / (0.4 * robot.velocity_limit))))
                    for a, b in zip(joints[:-1], joints[1:])])
    if ctx.quick:
        joints, dur = joints[:3], dur[:2]
    t, q, qd, qdd = quintic_path(joints, dur)

    ctx.advance(0.15, "simulating in MuJoCo")
    cell = Workcell(robot)
    cell.reset(q[0])
    w0 = time.perf_counter()
    log = cell.run_trajectory(t, q, qd, qdd)
    wall = time.perf_counter() - w0
    ctx.advance(0.85, "plots")
    err = log.q - log.q_ref
    rms = np.sqrt(np.mean(err**2, axis=0))
    tcp_err = np.array([np.linalg.norm(robot.fk(a)[:3, 3] - robot.fk(b)[:3, 3])
                        for a, b in zip(log.q[::20], log.q_ref[::20])])

    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for j in range(robot.nq):
        c = f"C{j}"
        axes[0].plot(log.t, np.degrees(log.q_ref[:, j]), "--", color=c, lw=2, alpha=0.4)
        axes[0].plot(log.t, np.degrees(log.q[:, j]), color=c, lw=1, label=robot.joint_names[j])
        axes[1].plot(log.t, np.degrees(err[:, j]) * 1e3, color=c, lw=1)
    axes[0].set_ylabel("joint angle [deg]\n(dashed: reference)")
    axes[0].legend(ncol=6, fontsize=7)
    axes[1].set_ylabel("tracking error [mdeg]")
    axes[1].set_xlabel("time [s]")
    axes[0].set_title("LR Mate 200iD/7L in MuJoCo: PID (1 kHz) + model feed-forward (Fig. 2.3)")
    fig.tight_layout()
    png = ctx.out / "tracking.png"
    fig.savefig(png, dpi=110)
    plt.close(fig)

    reps = 2000
    qs = robot.random_configuration(0, 16)
    t0 = time.perf_counter()
    for i in range(reps):
        robot.spheres.kinematics(qs[i % 16])
    sph_us = (time.perf_counter() - t0) / reps * 1e6
    Ts = [robot.fk(x) for x in qs]
    t0 = time.perf_counter()
    for i in range(reps):
        robot.ik(Ts[i % 16])
    ik_us = (time.perf_counter() - t0) / reps * 1e6
    ctx.advance(1.0, "done")
    figs = [
        Figure("trajectory", f"{len(WAYPOINTS) if not ctx.quick else 3} Cartesian waypoints, {t[-1]:.2f} s", None,
               "closed-form IK, quintic joint segments"),
        Figure("joint tracking RMS [mdeg]", ", ".join(f"{np.degrees(v) * 1e3:.2f}" for v in rms), None,
               "J1..J6, PID + feed-forward in MuJoCo at 1 kHz"),
        Figure("max TCP deviation [mm]", f"{tcp_err.max() * 1e3:.3f}", None, "FK of simulated vs reference joints"),
        Figure("simulation speed", f"{t[-1] / wall:.1f}x real time", None, "controller + physics at 1 kHz"),
        Figure("FK + Jacobians of all collision spheres", f"{sph_us:.1f} µs ({len(robot.spheres)} spheres)", None,
               "Pinocchio + compiled point Jacobians"),
        Figure("closed-form IK (all branches)", f"{ik_us:.1f} µs", None, "up to 8 solutions within limits"),
    ]
    return StageResult("Robot core and simulated workcell (Ch. 2)", figs, [png],
                       "Masses and inertias of the LR Mate are estimates (27 kg spread by link volume).")
