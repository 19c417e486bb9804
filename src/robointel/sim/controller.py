"""The basic joint controller of Fig. 2.3: decentralised PID per joint plus model-based feed-forward.

    tau = sat( tau_ff + Kp e + Ki int(e) dt + Kd de/dt ),   e = q_ref - q,
    tau_ff = M(q_ref) qdd_ref + C(q_ref, qd_ref) qd_ref + G(q_ref) + F_v qd_ref + F_c sign(qd_ref)

The feed-forward is the rigid-body inverse dynamics (2.5) of the robot core (Pinocchio RNEA on
``robot.model``, optionally with the payload added to the last link) plus the URDF friction model;
``sat`` clips to the effort limits. The PID runs on the measured joint position and velocity at the
control rate (1 kHz in the :class:`~robointel.sim.Workcell`), with anti-windup (the integral
is frozen while the output saturates, and clamped to ``i_limit``).

Default gains: inertia-scheduled. Each joint is treated as a double integrator with the effective
inertia it has right now, J_i(q) = 1 / (M(q)^-1)_ii (the inertia felt at joint i when the other
joints are free; Pinocchio's M^-1 at the measured q, payload and armature included), and the
closed loop J s^3 + Kd s^2 + Kp s + Ki = J (s + w)^3 gets a triple pole at -w:

    Kp = 3 J_i(q) w^2,   Kd = 3 J_i(q) w,   Ki = J_i(q) w^3,   w = 2 pi f_i,

with f = (10, 10, 15, 30, 40, 50) Hz for a 6-axis arm (padded with the last value). The integral is
kept as a torque (sum of Ki e dt), so changing gains never bumps the output. Scheduling matters:
the LR Mate's J1 inertia varies 46-fold over the workspace (0.067 to 3.07 kg m^2), so fixed gains
sized for the stretched arm make the discrete loop unstable when the arm is folded (Kd dt / J > 2).
The effective inertia (not M_ii) matters for coupled joints: with M_ii the UR5's shoulder-elbow
pair, whose M_ii (M^-1)_ii reaches 5, oscillates at 1 kHz.
The wrist gets the higher bandwidths because its link inertias are tiny next to its Coulomb
friction (the LR Mate's J6: 2e-5 kg m^2 against 0.2 N m; no rotor inertia is modelled): lower
gains let a step command hunt in a stick-slip limit cycle of a few centiradians; at 50 Hz the
cycle stays below 1 mrad. Fixed gains (:class:`PIDGains`) can be passed instead.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numba import njit
from numpy.typing import ArrayLike, NDArray

from robointel._validate import as_array
from robointel.errors import InvalidInput

if TYPE_CHECKING:  # pragma: no cover
    from robointel.robot import Robot
    from robointel.sim.mjcf import Payload

#: any numpy array (the compiled kernels take contiguous float64/int64/bool arrays)
Arr = NDArray[Any]

DEFAULT_BANDWIDTH_HZ = (10.0, 10.0, 15.0, 30.0, 40.0, 50.0)


@dataclass
class PIDGains:
    """Per-joint PID gains (SI: N m/rad, N m s/rad, N m/(rad s)) and integral clamp (N m)."""

    kp: np.ndarray
    ki: np.ndarray
    kd: np.ndarray
    i_limit: np.ndarray

    @classmethod
    def from_inertia(cls, inertia: ArrayLike, bandwidth_hz: ArrayLike | None = None, *,
                     effort_limit: ArrayLike | None = None) -> PIDGains:
        """Triple-pole gains Kp = 3 J w^2, Kd = 3 J w, Ki = J w^3 for inertias J (n,) kg m^2.

        ``bandwidth_hz`` (scalar or (n,)) defaults to :data:`DEFAULT_BANDWIDTH_HZ` (padded with its
        last value). The integral clamp is the effort limit (or inf).
        """
        J = as_array(inertia, "inertia", (None,))
        n = len(J)
        if np.any(J <= 0):
            raise InvalidInput("inertias must be positive (kg m^2)", value=inertia)
        if bandwidth_hz is None:
            f = np.array([DEFAULT_BANDWIDTH_HZ[min(i, len(DEFAULT_BANDWIDTH_HZ) - 1)] for i in range(n)])
        else:
            f = np.broadcast_to(as_array(bandwidth_hz, "bandwidth_hz"), (n,)).astype(float)
        if np.any(f <= 0):
            raise InvalidInput("bandwidth_hz must be positive", value=bandwidth_hz)
        w = 2 * np.pi * f
        lim = np.full(n, np.inf) if effort_limit is None else as_array(effort_limit, "effort_limit", (n,)).copy()
        return cls(kp=3 * J * w**2, ki=J * w**3, kd=3 * J * w, i_limit=lim)


class JointController:
    """Decentralised PID + model-based feed-forward (Fig. 2.3), one call per control period.

    Args:
        robot: the robot core (:class:`robointel.robot.Robot`); its model gives the feed-forward.
        gains: fixed :class:`PIDGains`; default (None): inertia-scheduled triple-pole gains.
        bandwidth_hz: scalar or (n,) closed-loop pole frequency of the scheduled gains (default
            :data:`DEFAULT_BANDWIDTH_HZ`).
        dt: control period (s), 1 ms by default.
        feedforward: add the inverse-dynamics feed-forward torque.
        friction_compensation: add F_v qd_ref + F_c tanh(qd_ref / 1e-3) from the URDF.
        model: Pinocchio model for the feed-forward (default ``robot.model``; pass
            :func:`model_with_payload` to compensate a known payload).
        gain_model: Pinocchio model whose inertia schedules the gains (default ``model``). It
            should include the payload even when the feed-forward does not: gains sized for an
            inertia under 1/9 of the real one make the triple-pole PID unstable (Routh).
    """

    def __init__(self, robot: Robot, gains: PIDGains | None = None, *,
                 bandwidth_hz: ArrayLike | None = None, dt: float = 0.001,
                 feedforward: bool = True, friction_compensation: bool = True,
                 model: pin.Model | None = None, gain_model: pin.Model | None = None) -> None:
        if not (np.isfinite(dt) and dt > 0):
            raise InvalidInput(f"dt must be a positive number of seconds, got {dt!r}", value=dt)
        self.robot = robot
        self.n = robot.nq
        self.dt = float(dt)
        self.model = robot.model if model is None else model
        self._data = self.model.createData()
        self._viscous = np.ascontiguousarray(robot.viscous, dtype=float)
        self._coulomb = np.ascontiguousarray(robot.coulomb, dtype=float)
        self.gain_model = self.model if gain_model is None else gain_model
        self._gdata = self.gain_model.createData()
        self.effort_limit = np.where(np.isfinite(robot.effort_limit) & (robot.effort_limit > 0),
                                     robot.effort_limit, np.inf)
        self.scheduled = gains is None
        if bandwidth_hz is None:
            f = np.array([DEFAULT_BANDWIDTH_HZ[min(i, len(DEFAULT_BANDWIDTH_HZ) - 1)] for i in range(self.n)])
        else:
            f = np.broadcast_to(as_array(bandwidth_hz, "bandwidth_hz"), (self.n,)).astype(float)
            if np.any(f <= 0):
                raise InvalidInput("bandwidth_hz must be positive", value=bandwidth_hz)
        self.omega = 2 * np.pi * f
        self.i_limit = self.effort_limit.copy()
        if gains is not None:
            if any(np.shape(getattr(gains, k)) != (self.n,) for k in ("kp", "ki", "kd", "i_limit")):
                raise InvalidInput(f"gains must hold (n,) = ({self.n},) arrays", value=gains)
            self.gains = gains
        else:
            self.gains = PIDGains(np.zeros(self.n), np.zeros(self.n), np.zeros(self.n), self.i_limit.copy())
        self.feedforward = feedforward
        self.friction_compensation = friction_compensation
        self.reset()
        q0 = np.clip(np.zeros(self.n), robot.lower, robot.upper)
        self.compute(q0, np.zeros(self.n), q0, np.zeros(self.n), np.zeros(self.n))  # load the numba kernels now
        self.reset()

    def reset(self) -> None:
        """Clear the integral state."""
        self.integral = np.zeros(self.n)  # integral term sum(Ki e dt), N m
        self.last_tau = np.zeros(self.n)
        self.last_ff = np.zeros(self.n)
        self.saturated = np.zeros(self.n, dtype=bool)

    def feedforward_torque(self, q_ref: np.ndarray, qd_ref: np.ndarray,
                           qdd_ref: np.ndarray) -> np.ndarray:
        """tau_ff = RNEA(q_ref, qd_ref, qdd_ref) (+ F_v qd_ref + F_c tanh(qd_ref / 1e-3)), (n,) N m."""
        tau = np.array(pin.rnea(self.model, self._data, q_ref, qd_ref, qdd_ref))
        if self.friction_compensation:
            _add_friction(tau, qd_ref, self._viscous, self._coulomb)
        return tau

    def compute(self, q: np.ndarray, qd: np.ndarray, q_ref: np.ndarray, qd_ref: np.ndarray,
                qdd_ref: np.ndarray) -> np.ndarray:
        """One control period.

        The saturated joint torques (n,) N m. Inputs are (n,) arrays that the caller has validated (finite, right
        shape).
        """
        if self.feedforward:
            ff = np.array(pin.rnea(self.model, self._data, q_ref, qd_ref, qdd_ref))
        else:
            ff = np.zeros(self.n)
        g = self.gains
        q = np.ascontiguousarray(q, dtype=float)
        if self.scheduled:
            Minv = pin.computeMinverse(self.gain_model, self._gdata, q)
            _schedule(Minv, self.omega, g.kp, g.ki, g.kd)
        tau = np.empty(self.n)
        _pid(q, np.ascontiguousarray(qd, dtype=float), q_ref, qd_ref, ff,
             self._viscous, self._coulomb, self.feedforward and self.friction_compensation,
             g.kp, g.ki, g.kd, g.i_limit, self.effort_limit, self.dt, self.integral, self.saturated, self.last_tau,
             tau)
        self.last_tau = tau
        self.last_ff = ff
        return tau


@njit(cache=True)
def _add_friction(tau: Arr, qd: Arr, viscous: Arr, coulomb: Arr) -> None:
    """Tau += F_v qd + F_c tanh(qd / 1e-3) (in place)."""
    for i in range(tau.shape[0]):
        tau[i] += viscous[i] * qd[i] + coulomb[i] * np.tanh(qd[i] * 1e3)


@njit(cache=True)
def _schedule(Minv: Arr, w: Arr, kp: Arr, ki: Arr, kd: Arr) -> None:
    """Triple-pole gains for the effective inertias J_i = 1 / (M^-1)_ii.

    Kp = 3 J w^2, Kd = 3 J w, Ki = J w^3 (in place).
    """
    for i in range(w.shape[0]):
        J = 1.0 / Minv[i, i]
        kp[i] = 3.0 * J * w[i] * w[i]
        kd[i] = 3.0 * J * w[i]
        ki[i] = J * w[i] * w[i] * w[i]


@njit(cache=True)
def _pid(q: Arr, qd: Arr, q_ref: Arr, qd_ref: Arr, ff: Arr,
         viscous: Arr, coulomb: Arr, friction: bool, kp: Arr, ki: Arr,
         kd: Arr, i_limit: Arr, effort: Arr, dt: float, integral: Arr,
         saturated: Arr, last_tau: Arr, out: Arr) -> None:
    """PID + feed-forward (``ff`` gets the friction compensation added in place when ``friction``).

    ``integral`` is the integral torque (clamped to +-i_limit), not integrated while the joint is saturated in the
    direction that grows its error.
    """
    for i in range(q.shape[0]):
        if friction:
            ff[i] += viscous[i] * qd_ref[i] + coulomb[i] * np.tanh(qd_ref[i] * 1e3)
        e = q_ref[i] - q[i]
        if not (saturated[i] and ((e > 0 and last_tau[i] > 0) or (e < 0 and last_tau[i] < 0))):
            integral[i] += ki[i] * e * dt
        integral[i] = min(max(integral[i], -i_limit[i]), i_limit[i])
        t = ff[i] + kp[i] * e + kd[i] * (qd_ref[i] - qd[i]) + integral[i]
        sat = min(max(t, -effort[i]), effort[i])
        saturated[i] = sat != t
        out[i] = sat


def max_inertia(model: pin.Model, samples: int = 64, seed: int = 0) -> np.ndarray:
    """Largest diagonal entry of M(q) per joint over random configurations within the limits.

    For fixed gains (``PIDGains.from_inertia(max_inertia(model))``); note that fixed gains sized
    for the largest inertia can destabilise the discrete loop where the inertia is small (see the
    module doc), which the default scheduled gains avoid.
    """
    data = model.createData()
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(model.lowerPositionLimit), model.lowerPositionLimit, -np.pi)
    hi = np.where(np.isfinite(model.upperPositionLimit), model.upperPositionLimit, np.pi)
    best = np.zeros(model.nv)
    for _ in range(samples):
        q = rng.uniform(lo, hi)
        M = pin.crba(model, data, q)
        best = np.maximum(best, np.diag(M))
    return best


def model_with_payload(robot: Robot, payload: Payload) -> pin.Model:
    """A copy of ``robot.model`` with a :class:`~robointel.sim.Payload` rigidly added at the flange."""
    model = robot.model.copy()
    if payload is None:
        return model
    m, com, inertia = payload.checked()
    fr = model.frames[model.getFrameId(robot.flange_frame)]
    pl = fr.placement  # flange in its parent joint frame
    c = pl.rotation @ com + pl.translation
    I = pl.rotation @ inertia @ pl.rotation.T
    model.inertias[fr.parentJoint] = model.inertias[fr.parentJoint] + pin.Inertia(m, c, I)
    return model
