"""Dynamic imitation on a 2-link SCARA (Ch. 3.2, (3.2)-(3.9)).

The human arm seen by the Kinect is projected onto the plane it moves in; the shoulder->elbow and
elbow->hand directions in that plane give the desired SCARA angles q1d, q2d (shoulder angle from
the hanging-down direction, elbow angle relative to the upper arm).

The robot (``Robot.load("scara2")``) is driven by computed torque (3.9)

    tau = M(q) u + C(q, qd) qd + G(q) + F_v qd

which turns it into two decoupled double integrators qdd = u. Sampled at T = 1 ms these are
x_{k+1} = A x_k + B u_k with x = [q; qd] (3.2)-(3.5). The discrete LQ tracking law minimises
sum (x_k - r_k)' Q (x_k - r_k) + u_k' R u_k (3.6); its gain comes from the discrete algebraic
Riccati equation (3.7)-(3.8) (``scipy.linalg.solve_discrete_are``):

    P = A'PA - A'PB (R + B'PB)^-1 B'PA + Q,     K = (R + B'PB)^-1 B'PA,
    u_k = qdd_r,k - K (x_k - r_k).

The Kinect delivers frames at ~30 Hz with ~0.1 s latency; a live system sees them cleaned
causally (dropouts held, causal low-pass). A Kalman filter on the received angles (white-noise-
acceleration model) estimates angle and rate. Without compensation the reference is that estimate
at t - latency (the human motion, delayed); with delay compensation it is extrapolated to t (across
the latency plus the age of the frame). Causal throughout: only frames that have arrived are used.
A jerk-limited follower (``ruckig``) turns the estimate into a reference (q_r, qd_r, qdd_r) within
velocity/acceleration limits the torque limits can deliver. Errors are measured against the true
human angles (the zero-phase cleaned recording, not delayed).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.linalg import solve_discrete_are

from robointel._validate import as_array
from robointel.errors import InvalidInput
from robointel.programming.skeleton import Skeleton, clean

#: The dissertation's RMS joint errors (q1, q2) [rad] on the SCARA, without / with compensation.
PAPER_RMS = (0.153, 0.185)
PAPER_RMS_COMPENSATED = (0.0103, 0.0305)


# ----------------------------------------------------------------------------- human -> SCARA angles
def arm_plane(skel: Skeleton, side: str) -> np.ndarray:
    """Unit normal (3,) of the plane the arm moves in: the least-variance direction of the upper-
    arm and forearm vectors (PCA), oriented to point forward/left/up (positive largest component)."""
    a = skel.arm(side)
    V = np.vstack([a["elbow"] - a["shoulder"], a["hand"] - a["elbow"]])
    _, _, vt = np.linalg.svd(V, full_matrices=False)
    n = vt[2]
    return n if n[np.argmax(np.abs(n))] > 0 else -n


def arm_angles(skel: Skeleton, side: str | None = None, *, normal=None) -> np.ndarray:
    """(N, 2) SCARA joint targets [rad] from a skeleton: the upper arm and forearm projected to
    the arm's plane; q1 = shoulder angle measured from the in-plane 'down' direction, q2 = forearm
    angle relative to the upper arm, wrapped to (-pi, pi], both unwrapped over time."""
    side = side or skel.active_side()
    n = arm_plane(skel, side) if normal is None else as_array(normal, "normal", (3,)) / np.linalg.norm(normal)
    down = np.array([0.0, 0.0, -1.0])
    d = down - n * (n @ down)
    if np.linalg.norm(d) < 0.3:  # arm plane nearly horizontal: measure from 'forward'
        d = np.array([1.0, 0.0, 0.0]) - n * n[0]
    d /= np.linalg.norm(d)
    u = np.cross(n, d)
    a = skel.arm(side)
    e, h = a["elbow"] - a["shoulder"], a["hand"] - a["elbow"]
    q1 = np.unwrap(np.arctan2(e @ u, e @ d))
    q2 = np.arctan2(h @ u, h @ d) - np.arctan2(e @ u, e @ d)
    q2 = np.unwrap((q2 + np.pi) % (2 * np.pi) - np.pi)
    return np.stack([q1, q2], axis=1)


# ----------------------------------------------------------------------------- LQ tracking (3.7)-(3.8)
def double_integrator(n: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation of n double integrators, x = [q; qd] (2n), u = qdd (n)."""
    I = np.eye(n)
    A = np.block([[I, dt * I], [np.zeros((n, n)), I]])
    B = np.vstack([0.5 * dt * dt * I, dt * I])
    return A, B


def lq_gain(A, B, Q, R) -> tuple[np.ndarray, np.ndarray]:
    """Solve the DARE (3.7) and return (K, P) with K = (R + B'PB)^-1 B'PA (3.8)."""
    A, B = np.asarray(A, float), np.asarray(B, float)
    Q, R = np.atleast_2d(Q).astype(float), np.atleast_2d(R).astype(float)
    P = solve_discrete_are(A, B, Q, R)
    K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
    return K, P


@dataclass
class ComputedTorqueLQ:
    """Computed torque (3.9) around discrete LQ tracking (3.7)-(3.8) for any robot.

    Args:
        robot: a :class:`robointel.robot.Robot` (dynamics from Pinocchio).
        dt: control period [s].
        q_weight, qd_weight, r_weight: LQ weights on position error [1/rad^2], velocity error and
            commanded acceleration.
    """

    robot: object
    dt: float = 0.001
    q_weight: float = 1.0
    qd_weight: float = 1e-3
    r_weight: float = 1e-8
    K: np.ndarray = field(init=False)
    P: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        n = self.robot.nq
        A, B = double_integrator(n, self.dt)
        Q = np.diag([self.q_weight] * n + [self.qd_weight] * n)
        self.K, self.P = lq_gain(A, B, Q, self.r_weight * np.eye(n))

    def torque(self, q, qd, q_r, qd_r, qdd_r) -> np.ndarray:
        """Joint torques (n,) [N m], clipped to the effort limits."""
        x = np.concatenate([q, qd])
        r = np.concatenate([q_r, qd_r])
        u = qdd_r - self.K @ (x - r)
        rb = self.robot
        tau = rb.mass_matrix(q) @ u + rb.nonlinear_effects(q, qd) + rb.viscous * qd
        return np.clip(tau, -rb.effort_limit, rb.effort_limit)


# ----------------------------------------------------------------------------- latency and prediction
class KalmanPredictor:
    """Per-joint Kalman filter with a white-noise-acceleration model on frames that arrive late,
    predicting the angles at any later time (the delay compensation).

    Args:
        n: number of joints.
        accel_psd: process noise (acceleration) spectral density [rad^2/s^3].
        meas_std: measurement noise [rad].
    """

    def __init__(self, n: int, *, accel_psd: float = 1e3, meas_std: float = 0.02) -> None:
        self.n, self.q, self.r = n, float(accel_psd), float(meas_std) ** 2
        self.x = None  # (n, 2): angle, rate at time self.t
        self.P = None
        self.t = None

    def update(self, t: float, z: np.ndarray) -> None:
        """Fuse the frame taken at time ``t`` (its capture time, not its arrival)."""
        z = np.asarray(z, float)
        if self.x is None:
            self.x = np.stack([z, np.zeros(self.n)], 1)
            self.P = np.tile(np.diag([self.r, 10.0]), (self.n, 1, 1))
            self.t = t
            return
        h = t - self.t
        F = np.array([[1.0, h], [0.0, 1.0]])
        Qn = self.q * np.array([[h ** 3 / 3, h ** 2 / 2], [h ** 2 / 2, h]])
        self.x = self.x @ F.T
        self.P = F @ self.P @ F.T + Qn
        S = self.P[:, 0, 0] + self.r
        K = self.P[:, :, 0] / S[:, None]
        self.x = self.x + K * (z - self.x[:, 0])[:, None]
        self.P = self.P - K[:, :, None] * self.P[:, 0, None, :]
        self.t = t

    def predict(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(angle, rate) at time ``t`` by constant-rate extrapolation from the last fused frame."""
        h = t - self.t
        return self.x[:, 0] + h * self.x[:, 1], self.x[:, 1].copy()


@dataclass
class ScaraResult:
    """One SCARA imitation run.

    Attributes:
        t: (M,) control times [s] (1 kHz).
        q: (M, 2) simulated joint angles [rad].
        q_human: (M, 2) true human angles [rad] (zero-phase cleaned, not delayed).
        q_ref: (M, 2) reference the controller tracked (delayed or predicted).
        tau: (M, 2) commanded torques [N m].
        rms: (2,) RMS of q - q_human [rad] (the imitation error).
        tracking_rms: (2,) RMS of q - q_ref [rad] (the controller's own error).
        saturated: fraction of steps with a torque at its limit.
    """

    t: np.ndarray
    q: np.ndarray
    q_human: np.ndarray
    q_ref: np.ndarray
    tau: np.ndarray
    rms: np.ndarray
    tracking_rms: np.ndarray
    saturated: float
    latency: float
    compensated: bool
    source: str = ""
    offline: bool = False


def human_reference(skel: Skeleton, side: str | None = None, *,
                    live_cutoff_hz: float = 12.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t (N,), true angles (N, 2) from the zero-phase cleaned skeleton, measured angles (N, 2) from
    the raw frames as a live system sees them: dropouts held, causal filter)."""
    side = side or skel.active_side()
    joints = ["SpineBase", *[f"{j}{'Right' if side == 'right' else 'Left'}" for j in ("Shoulder", "Elbow", "Hand")]]
    truth = clean(skel, joints=joints)
    live = clean(skel, joints=joints, causal=True, cutoff_hz=min(live_cutoff_hz, 0.45 * skel.rate))
    normal = arm_plane(truth, side)
    q_true, q_live = arm_angles(truth, side, normal=normal), arm_angles(live, side, normal=normal)
    # the SCARA base has no 'down': put the recording's mean shoulder angle at the middle of J1's
    # range (a calibration constant of the mapping, like the LR Mate's workspace scaling)
    off = np.array([np.mean(q_true[:, 0]), 0.0])
    return truth.t, q_true - off, q_live - off


def simulate_scara(skel: Skeleton, *, robot=None, latency: float = 0.1, compensate: bool = False,
                   side: str | None = None, dt: float = 0.001, controller: ComputedTorqueLQ | None = None,
                   workcell=None, predictor_psd: float = 10.0, max_accel=(60.0, 120.0),
                   jerk_factor: float = 20.0, follow_gain: float = 12.0, offline: bool = False) -> ScaraResult:
    """Simulate dynamic imitation of a recording on the SCARA in MuJoCo at 1/dt Hz.

    Frames captured at t_k reach the controller at t_k + ``latency``. The reference at time t is the
    Kalman estimate extrapolated to t - latency (no compensation: the human motion, delayed) or to
    t (compensation: predicted forward by the latency); the feed-forward acceleration is the
    reference's numerical derivative. Torques from :class:`ComputedTorqueLQ` drive MuJoCo.

    Args:
        skel: raw skeleton (Kinect or BVH).
        robot: default ``Robot.load("scara2")``.
        latency: sensor latency [s] (>= 0).
        compensate: predict across the latency.
        workcell: a ``robointel.sim.Workcell`` of ``robot`` (default: built here, no table).
        predictor_psd: Kalman process noise of the prediction [rad^2/s^3].
        max_accel: (2,) acceleration limit of the reference [rad/s^2] (what the torque limits can
            deliver); jerk limit = ``jerk_factor`` * max_accel; the reference follows the estimate
            with :class:`~robointel.programming.imitation.LimitedFollower` (``follow_gain`` [1/s]).
        offline: replay of a stored recording, known in advance: the reference is the cleaned
            recording itself at time t (no sensor in the loop, so no latency to compensate); what
            remains is the robot's own limits and tracking. ``latency``/``compensate`` are ignored.

    Returns:
        :class:`ScaraResult`.
    """
    from robointel.robot import Robot

    if not (0.0 <= latency < 2.0):
        raise InvalidInput(f"latency must be in [0, 2) s, got {latency}", value=latency)
    robot = robot or Robot.load("scara2")
    if robot.nq != 2:
        raise InvalidInput(f"simulate_scara needs a 2-joint robot, got {robot.nq}", value=robot.name)
    t_h, q_true, q_meas = human_reference(skel, side)
    q_true = np.clip(q_true, robot.lower, robot.upper)
    q_meas = np.clip(q_meas, robot.lower, robot.upper)
    ctrl = controller or ComputedTorqueLQ(robot, dt=dt)
    if workcell is None:
        from robointel.sim import Workcell

        workcell = Workcell(robot, table=False, ft_sensor=False, timestep=dt)
    M = int(np.floor(t_h[-1] / dt)) + 1
    t = np.arange(M) * dt
    spline = CubicSpline(t_h, q_true, axis=0)
    truth = spline(t)
    truth_d = spline(t, 1)
    kf = KalmanPredictor(2, accel_psd=predictor_psd)
    from robointel.programming.imitation import LimitedFollower

    acc = np.broadcast_to(np.asarray(max_accel, float), (2,))
    follow = LimitedFollower(2, robot.velocity_limit, acc, jerk_factor * acc, dt=dt, gain=follow_gain,
                             lower=robot.lower, upper=robot.upper)
    arrival = t_h + latency
    nxt = 0
    # the robot starts at rest at the first frame's pose (the operator is in view before start)
    kf.update(t_h[0], q_meas[0])
    follow.reset(q_meas[0])
    workcell.reset(q_meas[0], np.zeros(2))
    q_log = np.zeros((M, 2))
    ref_log = np.zeros((M, 2))
    tau_log = np.zeros((M, 2))
    for k in range(M):
        while nxt < len(t_h) and arrival[nxt] <= t[k] + 1e-12:
            if nxt > 0:
                kf.update(t_h[nxt], q_meas[nxt])
            nxt += 1
        if offline:
            raw, rate = truth[k], truth_d[k]
        else:
            tq = t[k] if compensate else max(t[k] - latency, t_h[0])
            raw, rate = kf.predict(min(tq, kf.t + 0.5))  # never extrapolate more than 0.5 s
        q_r, qd_r, qdd_r = follow.step(np.clip(raw, robot.lower, robot.upper), rate)
        q, qd = workcell.q, workcell.qd
        tau = ctrl.torque(q, qd, q_r, qd_r, qdd_r)
        workcell.step(tau)
        q_log[k], ref_log[k], tau_log[k] = q, q_r, tau
    err = q_log - truth
    rms = np.sqrt(np.mean(err ** 2, axis=0))
    trk = np.sqrt(np.mean((q_log - ref_log) ** 2, axis=0))
    sat = float(np.mean(np.any(np.abs(tau_log) >= robot.effort_limit - 1e-9, axis=1)))
    return ScaraResult(t, q_log, truth, ref_log, tau_log, rms, trk, sat, 0.0 if offline else latency,
                       compensate and not offline, skel.source, offline)


def plot_scara(results: list[ScaraResult], path) -> None:
    """Fig. 3.8-style plot: human vs robot angles, without and with compensation."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(results), figsize=(6 * len(results), 5.5), squeeze=False, sharex=True)
    for c, r in enumerate(results):
        for j in range(2):
            ax = axes[j, c]
            ax.plot(r.t, r.q_human[:, j], "k-", lw=1.2, label="human (true)")
            ax.plot(r.t, r.q_ref[:, j], "C1--", lw=0.8, label="reference (received)")
            ax.plot(r.t, r.q[:, j], "C0-", lw=1.0, label="SCARA (MuJoCo)")
            ax.set_ylabel(f"q{j + 1} [rad]")
            mode = ("offline replay (no latency)" if r.offline else
                    "with delay compensation" if r.compensated else "without delay compensation")
            ax.set_title(f"{mode}: q{j + 1} RMS {r.rms[j]:.3f} rad", fontsize=9)
            if j == 1:
                ax.set_xlabel("t [s]")
        axes[0, c].legend(fontsize=7, loc="best")
    fig.suptitle(f"Dynamic imitation on the 2-link SCARA (computed torque + LQ), live latency "
                 f"{max(r.latency for r in results):.2f} s: {results[0].source}",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
