"""Human guidance with collision avoidance (Ch. 4): a 1 kHz lead-through controller.

The operator's wrench at the handle gives a lead twist V_lead = C F_E (compliance, (3.11)). The
robot body is covered by spheres on control points (Fig. 4.2); for every obstacle k the closest
sphere gives the distance d_k, the repulsive unit vector u_k (from the obstacle toward the robot)
and the Jacobian J_rep,k of the closest robot point (decomposed Jacobian, (4.5)-(4.6)), so that the
approach rate along u_k is u_k^T J_rep,k dq = dd_k/dq dq.

Methods (``GuidanceConfig.method``):

* ``"qp"`` (proposed, (4.11)): the relaxed QP

      min_dq  ||J dq - V_lead||_W^2 + mu ||dq||^2
      s.t.    u_k^T J_rep,k dq >= 0      for every obstacle k with d_k < d0   (one row per obstacle)
              dq_min(q) <= dq <= dq_max(q)   (joint speed and position limits)

  solved exactly with DAQP (a dual active-set solver). dq = 0 satisfies every constraint (the
  bounds contain 0 by construction), so the QP is always feasible.
* ``"equality"`` ((4.10)): the same with u_k^T J_rep,k dq = 0, the closest point may neither
  approach nor leave the obstacle.
* ``"repulsive"`` ((4.1)): dq = J^# V_lead + sum_k J_rep,k^# v_rep(d_k) u_k, a repulsive velocity at
  the closest point, v_rep(d) = v_max / (1 + e^(alpha (2 d / d0 - 1))).
* ``"nullspace"`` ((4.2)-(4.3)): task-priority avoidance, dq = J_t^# v + (J_n P)^# (v_rep - J_n J_t^# v)
  with P = I - J_t^# J_t and J_n = u^T J_rep of the closest obstacle. A 6-DoF arm has no null space
  for a 6-D task, so the primary task here is the translation only (3-D), as that method needs.

For ``"qp"`` and ``"equality"`` the avoiding command is blended with the free one by the sigmoid
(4.12)-(4.13), dq = lambda dq_avoid + (1 - lambda) dq_free, with the corrected weight

    lambda(d) = (1 + e^-alpha) / (1 + e^(alpha (2 d / d0 - 1))),   lambda(0) = 1, lambda(d0) ~ e^-alpha,

taken at the smallest obstacle distance. (As printed, (4.13) misplaces a parenthesis.)

Faults: a force/torque reading that is NaN/inf, beyond the sensor range, or jumps by more than a
spike threshold in one sample never reaches the command: the controller holds (dq = 0) for a
recovery period and says why in ``GuidanceStep.status`` (or raises :class:`SafetyStop` with
``raise_on_fault=True``). Near singularities the least-squares damping grows (Chiaverini), so the
command stays bounded.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import daqp
import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from robointel._validate import as_array
from robointel.control.admittance import AdmittanceGains
from robointel.errors import InvalidInput, SafetyStop, ShapeError
from robointel.geometry.distance import ObstacleSet, sphere_distances
from robointel.teach.guidance_kernels import active_rows, check_wrench, filter_lead, qp_terms, soft_min

if TYPE_CHECKING:  # pragma: no cover
    from robointel.robot import Robot
    from robointel.robot.collision import SphereModel


__all__ = ["GuidanceConfig", "GuidanceController", "GuidanceStep", "METHODS", "blend_weight", "repulsive_speed"]

METHODS = ("qp", "equality", "repulsive", "nullspace")
_INF = 1e30


def blend_weight(d: ArrayLike, d0: float = 0.15, alpha: float = 6.0) -> NDArray[np.float64]:
    """Sigmoid weight of the avoiding command (4.13), corrected: lambda(0) = 1, lambda(d0) ~ e^-alpha.

    lambda(d) = (1 + e^-alpha) / (1 + e^(alpha (2 d / d0 - 1))), clipped to [0, 1] (d < 0 gives 1).

    Args:
        d: distance(s), m.
        d0: activation distance, m.
        alpha: steepness of the logistic blend.
    """
    d = np.asarray(d, float)
    x = np.minimum(alpha * (2.0 * d / d0 - 1.0), 700.0)
    lam = (1.0 + np.exp(-alpha)) / (1.0 + np.exp(x))
    return np.clip(lam, 0.0, 1.0)


def repulsive_speed(d: ArrayLike, d0: float = 0.15, alpha: float = 6.0,
                    v_max: float = 0.3) -> NDArray[np.float64]:
    """Magnitude of the classic repulsive velocity (4.1): v_max / (1 + e^(alpha (2 d / d0 - 1))), m/s."""
    d = np.asarray(d, float)
    return v_max / (1.0 + np.exp(np.minimum(alpha * (2.0 * d / d0 - 1.0), 700.0)))


@dataclass(frozen=True)
class GuidanceConfig:
    """Parameters of :class:`GuidanceController`.

    Attributes:
        method: "qp" (4.11), "equality" (4.10), "repulsive" (4.1) or "nullspace" (4.2)-(4.3).
        gains: compliance gains (K_d = 0.07 m/(N s) by default), (3.11).
        d0: activation distance of the avoidance (4.13), m.
        alpha: sigmoid steepness (4.13).
        rot_weight: weight of the angular rows in ||J dq - V_lead||_W^2, m^2 (a length^2 that
            makes rad/s comparable with m/s).
        damping: constant Tikhonov term mu_0 (rad^-2 scale), keeps H positive definite.
        singular_epsilon: sigma_min of W^1/2 J below which extra damping starts (Chiaverini).
        singular_damping: damping lambda at the singularity; ||dq|| <= ||V|| / (2 lambda).
        max_speed: tool speed limit, m/s (V_lead is saturated to it).
        max_angular_speed: tool angular speed limit, rad/s.
        velocity_scale: fraction of the robot's joint speed limits used.
        limit_gain: joint position limits become speed bounds k (q_max - q), 1/s.
        max_force: a reading with a larger force norm (N) is a fault (sensor range / impact).
        max_torque: likewise for the torque norm, N m.
        spike_force: a force jump larger than this (N) in one sample is a fault.
        spike_torque: a torque jump larger than this (N m) in one sample is a fault.
        recover_samples: after a fault, good samples needed before moving again.
        repulsive_v_max: v_max of the repulsive and null-space baselines, m/s.
        filter_hz: cut-off of the first-order low-pass filter on the (checked) wrench, Hz; 0 turns
            it off. The payload's inertia is in the admittance loop: unfiltered, a stiff joint
            controller makes the loop ring.
        dt: control period, s.
        softmin_beta: sharpness (1/m) of the smooth minimum over control points that defines each
            obstacle's distance and constraint row; 0 takes the hard minimum (closest control point),
            whose row jumps when the closest point changes and makes the QP chatter. The smooth
            minimum is at most log(m)/beta below the true one (conservative).
        raise_on_fault: raise :class:`SafetyStop` instead of holding silently.
    """

    method: str = "qp"
    gains: AdmittanceGains = field(default_factory=AdmittanceGains)
    d0: float = 0.15
    alpha: float = 6.0
    rot_weight: float = 0.01
    damping: float = 1e-6
    singular_epsilon: float = 0.04
    singular_damping: float = 0.04
    max_speed: float = 0.5
    max_angular_speed: float = 1.0
    velocity_scale: float = 1.0
    limit_gain: float = 10.0
    max_force: float = 150.0
    max_torque: float = 20.0
    spike_force: float = 40.0
    spike_torque: float = 5.0
    recover_samples: int = 50
    repulsive_v_max: float = 0.3
    filter_hz: float = 4.0
    softmin_beta: float = 100.0
    dt: float = 0.001
    raise_on_fault: bool = False

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise InvalidInput(f"method must be one of {METHODS}, got {self.method!r}", value=self.method)
        for name in ("d0", "alpha", "rot_weight", "singular_epsilon", "max_speed", "max_angular_speed",
                     "velocity_scale", "limit_gain", "max_force", "max_torque", "spike_force", "spike_torque",
                     "repulsive_v_max", "dt"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InvalidInput(f"GuidanceConfig.{name} must be finite and > 0, got {v!r}", value=v)
        if not (self.damping > 0 and self.singular_damping >= 0):
            raise InvalidInput("damping must be > 0 and singular_damping >= 0")
        if not (np.isfinite(self.filter_hz) and self.filter_hz >= 0):
            raise InvalidInput("filter_hz must be finite and >= 0", value=self.filter_hz)
        if not (np.isfinite(self.softmin_beta) and self.softmin_beta >= 0):
            raise InvalidInput("softmin_beta must be finite and >= 0", value=self.softmin_beta)
        if self.recover_samples < 0:
            raise InvalidInput("recover_samples must be >= 0", value=self.recover_samples)


@dataclass
class GuidanceStep:
    """One control step's output.

    Attributes:
        qd: (n,) joint velocity command, rad/s (zeros when holding).
        v_lead: (6,) lead twist C F_E (saturated), [m/s; rad/s], world axes at the TCP.
        v_cmd: (6,) commanded TCP twist J qd.
        distance: smallest sphere-obstacle distance, m (inf without obstacles).
        obstacle: index of the closest obstacle (-1 without obstacles).
        u_rep: (3,) repulsive unit vector at the closest point (from obstacle toward robot).
        approach_rate: d(d_k)/dt = (dd_k/dq) qd for the closest obstacle k, m/s (> 0 leaves): with
            the hard minimum u_rep^T J_rep qd, the closest point's speed along u_rep; with the smooth
            minimum (default) the softmax-weighted mean of the nearby control points' speeds.
        weight: the blend weight lambda (4.13) (0 for the baselines far away).
        active: number of obstacles inside d0 (constraint rows of the QP).
        held: True when the controller refused the reading and holds.
        status: "ok", "avoiding", or "hold: <why>".
    """

    qd: np.ndarray
    v_lead: np.ndarray
    v_cmd: np.ndarray
    distance: float
    obstacle: int
    u_rep: np.ndarray
    approach_rate: float
    weight: float
    active: int
    held: bool
    status: str

    @property
    def deviation(self) -> float:
        """||V_cmd - V_lead|| of the translational part, m/s."""
        return float(np.linalg.norm(self.v_cmd[:3] - self.v_lead[:3]))


class GuidanceController:
    """Lead-through controller with collision avoidance (Ch. 4), one :meth:`step` per 1 kHz tick.

    Holds the last good F/T sample, the fault/recovery counter and preallocated arrays.

    Args:
        robot: :class:`robointel.robot.Robot`; its TCP is the handle point.
        obstacles: robointel.geometry obstacles in the robot's world frame (``base_link``).
        config: :class:`GuidanceConfig`.
        spheres: collision sphere model (default ``robot.spheres``).
    """

    def __init__(self, robot: Robot, obstacles: Any = (), config: GuidanceConfig | None = None, *,
                 spheres: SphereModel | None = None) -> None:
        self.robot = robot
        self.config = config or GuidanceConfig()
        self.spheres = robot.spheres if spheres is None else spheres
        self.obstacles = ObstacleSet(obstacles)
        self.n = robot.nq
        c = self.config
        self._data = robot.model.createData()
        self._fid = robot._frame_id(robot.flange_frame)
        self._tool_p = np.asarray(robot.tool, float)[:3, 3].copy()
        self._has_tool = bool(np.any(self._tool_p != 0.0))
        self._W = np.array([1.0, 1.0, 1.0, c.rot_weight, c.rot_weight, c.rot_weight])
        self._vmax = np.asarray(robot.velocity_limit, float) * c.velocity_scale
        self._lower = np.asarray(robot.lower, float)
        self._upper = np.asarray(robot.upper, float)
        self._sense_cache: dict[tuple[int, bool], np.ndarray] = {}
        n = self.n
        K = len(self.obstacles)
        self._H, self._f, self._lb, self._ub = np.empty((n, n)), np.empty(n), np.empty(n), np.empty(n)
        self._A0, self._z0 = np.zeros((0, n)), np.zeros(0)
        self._dk, self._dh, self._rows, self._G = np.empty(K), np.empty(K), np.empty(K, np.int64), np.empty((K, n))
        self._A, self._z, self._inf = np.empty((K, n)), np.zeros(K), np.full(K, _INF)
        self._bu, self._bl = np.empty(n + K), np.empty(n + K)
        self._qp_par = np.array([c.damping, c.singular_epsilon ** 2, c.singular_damping ** 2, c.limit_gain])
        g = c.gains
        self._lead_par = np.array([g.force_deadband, g.torque_deadband, g.translational, g.rotational,
                                   c.max_speed, c.max_angular_speed])
        self._beta_s = float(c.softmin_beta)
        self._beta = 1.0 - np.exp(-2 * np.pi * c.filter_hz * c.dt) if c.filter_hz > 0 else 1.0
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget the last sample and any fault."""
        self._lastw = np.zeros(6)  # last good wrench
        self._has_last = False
        self._wf = np.zeros(6)  # filtered wrench (starts from rest)
        self._hold = 0  # good samples still needed
        self._why = ""
        self._solver_flag = 1
        self.last_step: GuidanceStep | None = None
        #: (H, f, A, lb, ub, solution) of the last QP with active obstacle rows, for inspection
        #: (views of work arrays: valid until the next step)
        self.last_qp: tuple | None = None

    # ------------------------------------------------------------------ pieces
    def _sense(self, k: int, equality: bool) -> np.ndarray:
        key = (k, equality)
        s = self._sense_cache.get(key)
        if s is None:
            s = np.zeros(self.n + k, dtype=np.int32)
            if equality:
                s[self.n:] = 5
            self._sense_cache[key] = s
        return s

    def lead_twist(self, wrench: ArrayLike) -> np.ndarray:
        """V_lead = C F_E (3.11) of one (unfiltered) wrench, with deadbands and speed limits, (6,)."""
        w = as_array(wrench, "wrench", (6,))
        V = np.empty(6)
        filter_lead(w, np.zeros(6), 1.0, True, self._lead_par, V)
        return V

    def tcp_jacobian(self, q: np.ndarray) -> np.ndarray:
        """6xn world-aligned TCP Jacobian (Pinocchio)."""
        m, d = self.robot.model, self._data
        pin.computeJointJacobians(m, d, q)
        pin.updateFramePlacement(m, d, self._fid)
        J = pin.getFrameJacobian(m, d, self._fid, pin.LOCAL_WORLD_ALIGNED)
        if self._has_tool:
            r = d.oMf[self._fid].rotation @ self._tool_p
            J = J.copy()
            J[:3] += np.cross(J[3:].T, r).T  # v_tcp = v + w x r
        return J

    def _solve(self, H: np.ndarray, f: np.ndarray, A: np.ndarray, lb: np.ndarray, ub: np.ndarray,
               bl: np.ndarray, bu: np.ndarray, equality: bool) -> np.ndarray | None:
        """DAQP on min 1/2 x'Hx + f'x, lb <= x <= ub, bl <= A x <= bu.

        None if it did not report an optimum (the caller then holds: never pass garbage on).
        """
        k, n = A.shape[0], self.n
        BU, BL = self._bu[:n + k], self._bl[:n + k]
        BU[:n], BU[n:], BL[:n], BL[n:] = ub, bu, lb, bl
        x, _, flag, _ = daqp.solve(H, f, A, BU, BL, self._sense(k, equality))
        if flag != 1 or not np.isfinite(x).all():
            self._solver_flag = int(flag)
            return None
        return x

    # ------------------------------------------------------------------ the loop
    def step(self, q: ArrayLike, wrench: ArrayLike) -> GuidanceStep:
        """One control step.

        Joint angles q (n,) and the handle wrench [f; tau] (6,) (world axes, about the TCP, payload-compensated) ->
        joint velocity command.

        Raises:
            ShapeError: q or wrench of the wrong shape (a programming error, not a sensor fault).
            SafetyStop: only with ``raise_on_fault=True``, for a bad F/T sample or bad q.
        """
        n, c = self.n, self.config
        q = np.asarray(q, dtype=float)
        w = np.asarray(wrench, dtype=float)
        if q.shape != (n,):
            raise ShapeError(f"q must have shape ({n},), got {q.shape}", value=q)
        if w.shape != (6,):
            raise ShapeError(f"wrench must have shape (6,), got {w.shape}", value=w)
        if not np.isfinite(q).all():
            return self._fault("joint reading is NaN or inf", q, w, bad_q=True)
        code, a, b = check_wrench(w, self._lastw, self._has_last, c.max_force, c.max_torque,
                                   c.spike_force, c.spike_torque)
        if code:
            why = ("F/T reading is NaN or inf" if code == 1 else
                   f"F/T reading out of range (|f| = {a:.1f} N, |tau| = {b:.2f} N m)" if code == 2 else
                   f"F/T spike ({a:.1f} N / {b:.2f} N m in one sample)")
            self._hold = c.recover_samples + 1
            self._why = why
            self._wf[:] = 0.0  # resume from rest: the filter ramps the command up again
            return self._fault(why, q, w)
        self._lastw[:] = w
        self._has_last = True
        if self._hold > 0:
            self._hold -= 1
            if self._hold > 0:
                return self._fault(f"recovering after: {self._why}", q, w)
        V = np.empty(6)
        filter_lead(w, self._wf, self._beta, False, self._lead_par, V)
        J = self.tcp_jacobian(q)
        H, f, lb, ub, qd_free = self._H, self._f, self._lb, self._ub, np.empty(n)
        inside = qp_terms(J, self._W, V, self._qp_par, q, self._lower, self._upper, self._vmax, H, f, lb, ub, qd_free)
        if not inside:  # free command: least squares within the joint bounds
            qd_sol = self._solve(H, f, self._A0, lb, ub, self._z0, self._z0, False)
            if qd_sol is None:
                return self._fault(f"QP solver failed (DAQP exit flag {self._solver_flag})", q, w)
            qd_free = qd_sol
        # distances of every movable sphere to every obstacle, closest sphere per obstacle
        K = len(self.obstacles)
        if K == 0:
            qd = qd_free
            dmin, kmin, u, rate, lam, nact = np.inf, -1, np.zeros(3), 0.0, 0.0, 0
        else:
            sd = sphere_distances(self.robot, q, self.obstacles, self.spheres, movable_only=True)
            dk, dhard, rows, G = self._dk, self._dh, self._rows, self._G
            soft_min(sd.d, sd.grad, self._beta_s, dk, dhard, rows, G)
            kmin = int(np.argmin(dk))
            dmin = float(dhard.min())
            u = sd.normals[rows[kmin], kmin]
            method = c.method
            eq = method == "equality"
            A = self._A
            nact, feasible = active_rows(dk, G, c.d0, qd_free, A)
            if method in ("qp", "equality"):
                lam = _blend_scalar(float(dk[kmin]), c.d0, c.alpha)
                if nact == 0:
                    qd = qd_free
                else:
                    A = A[:nact]
                    if feasible and not eq:
                        qd_av = qd_free  # unconstrained optimum is feasible: it is the QP's optimum
                    else:
                        z = self._z[:nact]
                        qd_sol = self._solve(H, f, A, lb, ub, z, z if eq else self._inf[:nact], eq)
                        if qd_sol is None:
                            return self._fault(f"QP solver failed (DAQP exit flag {self._solver_flag})", q, w)
                        qd_av = qd_sol
                    self.last_qp = (H, f, A, lb, ub, qd_av)
                    qd = lam * qd_av + (1.0 - lam) * qd_free
            else:
                act = dk < c.d0
                lam = _blend_scalar(float(dk[kmin]), c.d0, c.alpha) if nact else 0.0
                qd = self._baseline(q, V, J, sd, rows, dhard, act, qd_free, lb, ub)
            rate = float(G[kmin] @ qd)
        Vc = J @ qd
        status = "avoiding" if nact else "ok"
        out = GuidanceStep(qd, V, Vc, dmin, kmin, u, rate, lam, nact, False, status)
        self.last_step = out
        return out

    def _fault(self, why: str, q: ArrayLike, w: ArrayLike, bad_q: bool = False) -> GuidanceStep:
        if self.config.raise_on_fault:
            raise SafetyStop(f"guidance controller holds the robot: {why}", value=w if not bad_q else q)
        z = np.zeros(self.n)
        out = GuidanceStep(z, np.zeros(6), np.zeros(6), np.nan, -1, np.zeros(3), 0.0, 0.0, 0, True, f"hold: {why}")
        self.last_step = out
        return out

    def _baseline(self, q: np.ndarray, V: np.ndarray, J: np.ndarray, sd: Any, rows: np.ndarray,
                  dk: np.ndarray, act: np.ndarray, qd_free: np.ndarray, lb: np.ndarray,
                  ub: np.ndarray) -> np.ndarray:
        """Repulsive-vector (4.1) and null-space (4.2)-(4.3) baselines."""
        c = self.config
        _, Js = self.spheres.kinematics(q)
        mov = sd.spheres
        if c.method == "repulsive":
            qd = qd_free.copy()
            for k in np.flatnonzero(act):
                i = int(rows[k])
                Jr = Js[mov[i]]  # (3, n) linear Jacobian of the closest sphere
                vrep = float(repulsive_speed(dk[k], c.d0, c.alpha, c.repulsive_v_max))
                qd += _dls(Jr, 1e-3) @ (vrep * sd.normals[i, k])
        else:  # nullspace, translational lead task
            Jt = J[:3]
            Jt_p = _dls(Jt, 1e-3)
            v = V[:3]
            qd = Jt_p @ v
            if act.any():
                kc = int(np.argmin(dk))
                ic = int(rows[kc])
                Jn = sd.normals[ic, kc] @ Js[mov[ic]]  # (n,)
                P = np.eye(self.n) - Jt_p @ Jt
                JnP = Jn @ P
                vrep = float(repulsive_speed(dk[kc], c.d0, c.alpha, c.repulsive_v_max))
                # damped scalar pseudo-inverse of J_n P (bounded near its singularity)
                qd = qd + JnP * ((vrep - Jn @ qd) / (JnP @ JnP + 1e-3))
        # joint bounds: uniform scaling keeps the direction
        s = 1.0
        for i in range(self.n):
            if qd[i] > ub[i] > 0:
                s = min(s, ub[i] / qd[i])
            elif qd[i] < lb[i] < 0:
                s = min(s, lb[i] / qd[i])
            elif (qd[i] > 0 and ub[i] <= 0) or (qd[i] < 0 and lb[i] >= 0):
                s = 0.0
        return qd * s


def _blend_scalar(d: float, d0: float, alpha: float) -> float:
    """:func:`blend_weight` for one float (no numpy overhead in the 1 kHz loop)."""
    x = min(alpha * (2.0 * d / d0 - 1.0), 700.0)
    return min(1.0, max(0.0, (1.0 + math.exp(-alpha)) / (1.0 + math.exp(x))))


def _dls(J: np.ndarray, lam: float) -> np.ndarray:
    """Damped least-squares inverse J^T (J J^T + lam^2 I)^-1."""
    return J.T @ np.linalg.inv(J @ J.T + lam * lam * np.eye(J.shape[0]))
