"""Dynamic imitation on a 2-link SCARA (Ch. 3.2, (3.2)-(3.9)).

The human arm seen by the Kinect gives the desired SCARA angles q1d, q2d: q1d = the upper arm's
angle in the plane the arm moves in (from the hanging-down direction), q2d = the elbow's flexion
angle (by default the true 3-D angle between upper arm and forearm; the projected in-plane angle,
``elbow="planar"``, wraps past +-pi when the arm leaves the plane).

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
at t - latency (the human motion, delayed); with delay compensation it is predicted to t (across
the latency plus the age of the frame), by the Kalman filter (constant rate) or by a linear
autoregressive predictor (:class:`ARPredictor`) fitted on other recordings. Causal throughout:
only frames that have arrived are used. A jerk-limited follower (``ruckig``) or a second-order
reference model turns the estimate into a reference (q_r, qd_r, qdd_r). Errors are measured
against the true human angles (the zero-phase cleaned recording, not delayed) at the same instant.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.linalg import solve_discrete_are

from robointel._validate import as_array
from robointel.errors import InvalidInput
from robointel.programming.skeleton import Skeleton, clean

#: The dissertation's RMS joint errors (q1, q2) [rad] on the SCARA, without / with compensation.
PAPER_RMS = (0.153, 0.185)
PAPER_RMS_COMPENSATED = (0.0103, 0.0305)
#: Natural frequency [Hz] of the reference model used with the learned predictor, chosen on the
#: seven Kinect recordings (a tuned hyper-parameter; the predictor itself is fitted leave-one-out):
#: 3 / 4 / 5 / 6 Hz gave mean RMS q1/q2 0.319/0.276, 0.294/0.274, 0.283/0.291, 0.277/0.321 rad.
SMOOTH_HZ = 4.0


# ----------------------------------------------------------------------------- human -> SCARA angles
def arm_plane(skel: Skeleton, side: str) -> np.ndarray:
    """Unit normal (3,) of the plane the arm moves in: the least-variance direction of the upper-
    arm and forearm vectors (PCA), oriented to point forward/left/up (positive largest component)."""
    a = skel.arm(side)
    V = np.vstack([a["elbow"] - a["shoulder"], a["hand"] - a["elbow"]])
    _, _, vt = np.linalg.svd(V, full_matrices=False)
    n = vt[2]
    return n if n[np.argmax(np.abs(n))] > 0 else -n


def arm_angles(skel: Skeleton, side: str | None = None, *, normal=None, elbow: str = "flexion") -> np.ndarray:
    """(N, 2) SCARA joint targets [rad] from a skeleton: q1 = the upper arm's angle in the arm's
    plane, measured from the in-plane 'down' direction, unwrapped over time.

    ``elbow="planar"``: q2 = the projected forearm's angle relative to the projected upper arm,
    unwrapped over time. When the arm leaves the plane the projections can swing through the
    folded direction and q2 drifts past -pi/pi (Ges05_demopoint reaches -6.2 rad while the elbow
    is bent 9 degrees). ``elbow="flexion"``: q2 = the elbow's true 3-D flexion angle (0 = straight,
    in [0, pi)), signed by the recording's dominant in-plane bending direction; it never wraps.
    """
    if elbow not in ("planar", "flexion"):
        raise InvalidInput(f"elbow must be 'planar' or 'flexion', got {elbow!r}", value=elbow)
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
    q2 = (q2 + np.pi) % (2 * np.pi) - np.pi
    if elbow == "flexion":
        c = np.einsum("ij,ij->i", e, h) / (np.linalg.norm(e, axis=1) * np.linalg.norm(h, axis=1))
        sign = 1.0 if np.median(q2) >= 0 else -1.0
        return np.stack([q1, sign * np.arccos(np.clip(c, -1.0, 1.0))], axis=1)
    return np.stack([q1, np.unwrap(q2)], axis=1)


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
            commanded acceleration (scalars or one per joint).
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
        w = [np.broadcast_to(np.asarray(x, float), (n,)) for x in (self.q_weight, self.qd_weight, self.r_weight)]
        if any(np.any(x <= 0) for x in w):
            raise InvalidInput("LQ weights must be positive")
        self.K, self.P = lq_gain(A, B, np.diag(np.concatenate(w[:2])), np.diag(w[2]))

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

    def reset(self) -> None:
        """Forget all frames."""
        self.x = self.P = self.t = None

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


class ARPredictor:
    """Linear autoregressive predictor across the latency, fitted by ridge regression on recordings.

    From the newest received frame q_k (captured at t_k) and the P frame-to-frame differences
    before it, the angle at t_k + h is predicted per joint (weights shared by the joints) as

        q(t_k + h) = q_k + w' (phi_k kron [1, h, h^2]),   phi_k = [q_k - q_{k-1}, ..., q_{k-P+1} - q_{k-P}, 1],

    so the horizon h (latency plus the frame's age) enters polynomially. Fit it with
    :meth:`fit` on recordings other than the one it is evaluated on (leave-one-recording-out).

    Args:
        weights: ((P + 1) * (poly + 1),) regression weights.
        order: P, number of past differences.
        poly: degree of the horizon polynomial.
    """

    def __init__(self, weights, order: int = 6, poly: int = 2) -> None:
        self.order, self.poly = int(order), int(poly)
        self.w = as_array(weights, "weights", ((self.order + 1) * (self.poly + 1),))
        self.hist: list[np.ndarray] = []
        self.t = None

    @staticmethod
    def _features(hist: np.ndarray, order: int) -> np.ndarray:
        """(n, P + 1) features per joint from the last frames ``hist`` (m, n), oldest first."""
        h = hist[-(order + 1):]
        if len(h) < order + 1:  # too few frames yet: repeat the first (zero differences)
            h = np.vstack([np.repeat(h[:1], order + 1 - len(h), 0), h])
        d = np.diff(h, axis=0)[::-1]  # newest difference first
        return np.hstack([d.T, np.ones((h.shape[1], 1))])

    def reset(self) -> None:
        """Forget all frames."""
        self.hist, self.t = [], None

    def update(self, t: float, z: np.ndarray) -> None:
        """Add the frame captured at time ``t``."""
        self.hist.append(np.asarray(z, float).copy())
        if len(self.hist) > self.order + 1:
            self.hist.pop(0)
        self.t = t

    def predict(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(angle (n,), rate (n,)) predicted at time ``t`` from the frames received so far."""
        h = t - self.t
        f = self._features(np.asarray(self.hist), self.order)
        hv = h ** np.arange(self.poly + 1)
        dv = np.concatenate([[0.0], np.arange(1, self.poly + 1) * h ** np.arange(self.poly)])
        W = self.w.reshape(self.order + 1, self.poly + 1)
        return self.hist[-1] + f @ W @ hv, f @ W @ dv

    @classmethod
    def fit(cls, runs, *, latency: float = 0.1, order: int = 6, poly: int = 2, ridge: float = 1e-9,
            dt: float = 0.003, span: float | None = None) -> "ARPredictor":
        """Fit on recordings.

        Args:
            runs: iterable of (t (N,), q_true (N, n), q_meas (N, n)) as returned by
                :func:`human_reference` (frame times, true angles, angles as received live).
            latency: sensor latency [s]; horizons from ``latency`` to ``latency`` + ``span``.
            dt: spacing of the training horizons [s].
            span: range of horizons beyond the latency [s] (default three frame periods).
        """
        X, Y = [], []
        for t_h, q_true, q_meas in runs:
            t_h, q_true, q_meas = np.asarray(t_h, float), np.asarray(q_true, float), np.asarray(q_meas, float)
            spline = CubicSpline(t_h, q_true, axis=0)
            T = float(np.median(np.diff(t_h)))
            span_ = 3 * T if span is None else float(span)
            hs = np.arange(latency, latency + span_, dt)
            for j in range(len(t_h)):
                h = hs[t_h[j] + hs <= t_h[-1]]
                if len(h) == 0:
                    break
                f = cls._features(q_meas[max(0, j - order):j + 1], order)  # (n, P + 1)
                X.append(np.einsum("ca,hb->hcab", f, h[:, None] ** np.arange(poly + 1)).reshape(len(h) * len(f), -1))
                Y.append((spline(t_h[j] + h) - q_meas[j]).reshape(-1))
        if not X:
            raise InvalidInput("ARPredictor.fit needs at least one recording longer than the latency")
        X, Y = np.vstack(X), np.concatenate(Y)
        w = np.linalg.solve(X.T @ X + ridge * len(Y) * np.eye(X.shape[1]), X.T @ Y)
        return cls(w, order, poly)


def fit_predictor(skeletons, *, latency: float = 0.1, robot=None, elbow: str = "flexion", **kw) -> ARPredictor:
    """An :class:`ARPredictor` fitted on recordings as :func:`simulate_scara` sees them (angles from
    :func:`human_reference`, clipped to the SCARA's joint range). Pass recordings other than the one
    you evaluate on. ``kw`` go to :meth:`ARPredictor.fit`."""
    from robointel.robot import Robot

    robot = robot or Robot.load("scara2")
    runs = []
    for sk in skeletons:
        t_h, q_true, q_meas = human_reference(sk, elbow=elbow)
        runs.append((t_h, np.clip(q_true, robot.lower, robot.upper), np.clip(q_meas, robot.lower, robot.upper)))
    if not runs:
        raise InvalidInput("fit_predictor needs at least one recording")
    return ARPredictor.fit(runs, latency=latency, **kw)


def training_predictor(exclude: str = "", *, latency: float = 0.1, robot=None,
                       elbow: str = "flexion") -> tuple[ARPredictor, str]:
    """An :class:`ARPredictor` for a live run: fitted on the reference Kinect recordings except the
    one named ``exclude`` (a file name such as ``Ges01_wavehand.csv``), or, without the reference
    data, on three synthetic arm waves (seeds 1-3). Returns (predictor, what it was fitted on)."""
    from robointel.errors import DataMissing
    from robointel.io.reference import data_path
    from robointel.programming.skeleton import read_kinect_csv, synthetic_wave

    try:
        files = sorted(p for p in data_path("kinect").glob("*.csv") if p.name != Path(exclude).name)
    except DataMissing:
        files = []
    if files:
        skels, what = [read_kinect_csv(f) for f in files], f"{len(files)} other Kinect recordings"
    else:
        skels, what = [synthetic_wave(6.0, seed=s, dropout_at=None) for s in (1, 2, 3)], "3 synthetic arm waves"
    return fit_predictor(skels, latency=latency, robot=robot, elbow=elbow), what


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


def human_reference(skel: Skeleton, side: str | None = None, *, live_cutoff_hz: float = 12.0,
                    elbow: str = "flexion") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t (N,), true angles (N, 2) from the zero-phase cleaned skeleton, measured angles (N, 2) from
    the raw frames as a live system sees them: dropouts held, causal filter)."""
    side = side or skel.active_side()
    joints = ["SpineBase", *[f"{j}{'Right' if side == 'right' else 'Left'}" for j in ("Shoulder", "Elbow", "Hand")]]
    truth = clean(skel, joints=joints)
    live = clean(skel, joints=joints, causal=True, cutoff_hz=min(live_cutoff_hz, 0.45 * skel.rate))
    normal = arm_plane(truth, side)
    q_true = arm_angles(truth, side, normal=normal, elbow=elbow)
    q_live = arm_angles(live, side, normal=normal, elbow=elbow)
    if np.median(q_true[:, 1]) * np.median(q_live[:, 1]) < 0:  # same bending sign for both (flexion)
        q_live[:, 1] *= -1.0
    # the SCARA base has no 'down': put the recording's mean shoulder angle at the middle of J1's
    # range (a calibration constant of the mapping, like the LR Mate's workspace scaling)
    off = np.array([np.mean(q_true[:, 0]), 0.0])
    return truth.t, q_true - off, q_live - off


def simulate_scara(skel: Skeleton, *, robot=None, latency: float = 0.1, compensate: bool = False,
                   side: str | None = None, dt: float = 0.001, controller: ComputedTorqueLQ | None = None,
                   workcell=None, predictor_psd: float = 10.0, max_accel=(60.0, 120.0),
                   jerk_factor: float = 20.0, follow_gain: float = 12.0, offline: bool = False,
                   predictor=None, smooth_hz: float = 0.0, follower: bool = True,
                   elbow: str = "flexion") -> ScaraResult:
    """Simulate dynamic imitation of a recording on the SCARA in MuJoCo at 1/dt Hz.

    Frames captured at t_k reach the controller at t_k + ``latency``. The reference at time t is the
    predictor's estimate at t - latency (no compensation: the human motion, delayed) or at t
    (compensation: predicted forward across the latency and the frame's age). The estimate is
    shaped into (q_r, qd_r, qdd_r) by the jerk-limited follower (default), or by a critically
    damped second-order reference model at ``smooth_hz`` (qdd_r = wn^2 (q_est - q_r) - 2 wn qd_r),
    or passed as it is (``follower=False``). Torques from :class:`ComputedTorqueLQ` (3.9) drive
    MuJoCo; MuJoCo's actuators and the controller clip them to the effort limits.

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
            With ``follower=False`` the LQ gets the recording's exact q, qd, qdd.
        predictor: an object with ``update(t, q)``, ``predict(t) -> (q, qd)``, ``t`` (time of the
            last frame) and ``reset()``, e.g. an :class:`ARPredictor` from :func:`fit_predictor`
            (fitted on *other* recordings); default a :class:`KalmanPredictor`.
        smooth_hz: natural frequency [Hz] of the reference model (0: not used).
        follower: shape the estimate with the jerk-limited follower (ignored if ``smooth_hz`` > 0).
        elbow: the human elbow angle, "planar" or "flexion" (see :func:`arm_angles`).

    Returns:
        :class:`ScaraResult`.
    """
    from robointel.robot import Robot

    if not (0.0 <= latency < 2.0):
        raise InvalidInput(f"latency must be in [0, 2) s, got {latency}", value=latency)
    robot = robot or Robot.load("scara2")
    if robot.nq != 2:
        raise InvalidInput(f"simulate_scara needs a 2-joint robot, got {robot.nq}", value=robot.name)
    t_h, q_true, q_meas = human_reference(skel, side, elbow=elbow)
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
    if smooth_hz < 0 or smooth_hz * dt > 0.05:
        raise InvalidInput(f"smooth_hz must be in [0, {0.05 / dt:g}] Hz at dt = {dt} s, got {smooth_hz}",
                           value=smooth_hz)
    kf = KalmanPredictor(2, accel_psd=predictor_psd) if predictor is None else predictor
    kf.reset()
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
    truth_dd = spline(t, 2)
    wn = 2.0 * np.pi * smooth_hz
    qf, vf = np.array(q_meas[0], float), np.zeros(2)
    for k in range(M):
        while nxt < len(t_h) and arrival[nxt] <= t[k] + 1e-12:
            if nxt > 0:
                kf.update(t_h[nxt], q_meas[nxt])
            nxt += 1
        if offline:
            raw, rate, acc_r = truth[k], truth_d[k], truth_dd[k]
            q_r, qd_r, qdd_r = (follow.step(np.clip(raw, robot.lower, robot.upper), rate) if follower else
                                (raw, rate, acc_r))
        elif smooth_hz > 0:
            # the estimate through a critically damped second-order reference model: a smooth
            # reference with consistent q_r, qd_r, qdd_r
            tq = t[k] if compensate else max(t[k] - latency, t_h[0])
            raw = np.clip(kf.predict(min(tq, kf.t + 0.5))[0], robot.lower, robot.upper)
            acc_r = wn * wn * (raw - qf) - 2.0 * wn * vf
            qf, vf = qf + dt * vf + 0.5 * dt * dt * acc_r, vf + dt * acc_r
            q_r, qd_r, qdd_r = qf, vf, acc_r
        else:
            tq = t[k] if compensate else max(t[k] - latency, t_h[0])
            raw, rate = kf.predict(min(tq, kf.t + 0.5))  # never extrapolate more than 0.5 s
            q_r, qd_r, qdd_r = (follow.step(np.clip(raw, robot.lower, robot.upper), rate) if follower else
                                (raw, rate, np.zeros(2)))
        q_r = np.clip(q_r, robot.lower, robot.upper)
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
