"""The flexible-joint robot model (2.1)-(2.2) as a simulation model: motor side and load side.

Each joint is a motor (rotor inertia J_m, viscous friction B_m, gear ratio N) connected to its link
through a torsional spring K with damping D (the gearbox/harmonic-drive compliance). With the motor
angle expressed on the joint side, theta = theta_m / N, and the motor quantities reflected,
J = N^2 J_m, B = N^2 B_m, tau = N tau_m:

    (2.1) load side:   M(q) qdd + C(q, qd) qd + G(q) = K (theta - q) + D (thetad - qd) + tau_ext
    (2.2) motor side:  J thetadd + B thetad + K (theta - q) + D (thetad - qd) = N tau_m

M, C, G come from the robot core (Pinocchio, the same rigid model MuJoCo simulates). At rest
K (theta - q) = G(q): gravity winds up the springs. As K -> inf, theta -> q and the model becomes the
rigid arm with the reflected rotor inertia and friction added: (M + J) qdd + C qd + G + B qd = N tau_m.

Integration is linearly implicit (backward) Euler in the stiff linear parts: the spring, the two
dampers and the motor friction are taken at the end of the step, the rigid-body terms M, C qd + G
at its start. It is stable for any K (no step-size limit from the joint resonance), which is what
lets very stiff joints run at 1 kHz; numerical damping of a mode of frequency w is about
(w h)^2 / 2 per step, so use ``substeps`` to resolve soft-joint resonances.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike
from scipy.linalg import eigh

from robointel._validate import as_array
from robointel.control import JointController
from robointel.errors import InvalidInput, SafetyStop

if TYPE_CHECKING:  # pragma: no cover
    from robointel.robot import Robot

#: ESTIMATES for the LR Mate 200iD/7L (no public data): joint stiffness (N m/rad), joint damping
#: (N m s/rad), rotor inertia (kg m^2), motor viscous friction (N m s/rad), gear ratio.
LRMATE_FLEXIBLE = dict(
    stiffness=(6.0e4, 6.0e4, 3.0e4, 4.0e3, 4.0e3, 2.0e3),
    damping=(60.0, 60.0, 30.0, 2.0, 2.0, 1.0),
    rotor_inertia=(2.0e-4, 2.0e-4, 1.0e-4, 2.0e-5, 2.0e-5, 1.0e-5),
    motor_friction=(1.0e-4, 1.0e-4, 5.0e-5, 1.0e-5, 1.0e-5, 1.0e-5),
    gear_ratio=(120.0, 120.0, 100.0, 80.0, 80.0, 50.0),
)


@dataclass
class FlexibleJointParams:
    """Per-joint parameters of (2.1)-(2.2), each (n,) (scalars broadcast).

    Args:
        stiffness: K, joint-side torsional stiffness (N m/rad) > 0.
        damping: D, joint-side spring damping (N m s/rad) >= 0.
        rotor_inertia: J_m, motor-side rotor inertia (kg m^2) > 0.
        motor_friction: B_m, motor-side viscous friction (N m s/rad) >= 0.
        gear_ratio: N (motor turns per joint turn) > 0.
    """

    stiffness: np.ndarray
    damping: np.ndarray
    rotor_inertia: np.ndarray
    motor_friction: np.ndarray
    gear_ratio: np.ndarray

    @classmethod
    def lrmate(cls, **overrides: Any) -> FlexibleJointParams:
        """The LR Mate estimates :data:`LRMATE_FLEXIBLE` (override any field)."""
        return cls(**{**LRMATE_FLEXIBLE, **overrides})

    def checked(self, n: int) -> FlexibleJointParams:
        """These parameters validated for ``n`` joints."""
        out = {}
        for name, positive in (("stiffness", True), ("damping", False), ("rotor_inertia", True),
                               ("motor_friction", False), ("gear_ratio", True)):
            v = np.broadcast_to(as_array(getattr(self, name), name), (n,)).astype(float).copy()
            if np.any(v <= 0) if positive else np.any(v < 0):
                raise InvalidInput(f"{name} must be {'> 0' if positive else '>= 0'} for every joint, got {v}", value=v)
            out[name] = v
        return FlexibleJointParams(**out)

    @property
    def reflected_inertia(self) -> np.ndarray:
        """J = N^2 J_m (kg m^2), the rotor inertia seen at the joint."""
        return np.asarray(self.gear_ratio) ** 2 * np.asarray(self.rotor_inertia)

    @property
    def reflected_friction(self) -> np.ndarray:
        """B = N^2 B_m (N m s/rad)."""
        return np.asarray(self.gear_ratio) ** 2 * np.asarray(self.motor_friction)


class FlexibleJointModel:
    """Simulate the flexible-joint arm (2.1)-(2.2) with the robot core's rigid dynamics on the load side.

    State (all on the joint side, SI): link positions/velocities ``q``, ``qd`` and motor positions/
    velocities ``theta``, ``thetad`` (motor angle / N), each (n,).

    Args:
        robot: :class:`robointel.robot.Robot` (its Pinocchio model gives M, C, G).
        params: :class:`FlexibleJointParams` (default: the LR Mate estimates).
        dt: step (s) of :meth:`step`, 1 ms by default.
        substeps: internal integration steps per :meth:`step`.
    """

    def __init__(self, robot: Robot, params: FlexibleJointParams | None = None, *, dt: float = 0.001,
                 substeps: int = 1) -> None:
        if not (np.isfinite(dt) and dt > 0) or int(substeps) < 1:
            raise InvalidInput(f"dt must be > 0 and substeps >= 1, got {dt!r}, {substeps!r}", value=(dt, substeps))
        self.robot = robot
        self.n = robot.nq
        self.params = (params or FlexibleJointParams.lrmate()).checked(self.n)
        self.dt = float(dt)
        self.substeps = int(substeps)
        self._model = robot.model
        self._data = robot.model.createData()
        p = self.params
        self._K, self._D = p.stiffness, p.damping
        self._J, self._B, self._N = p.reflected_inertia, p.reflected_friction, p.gear_ratio
        self.reset(np.clip(np.zeros(self.n), robot.lower, robot.upper))

    # ------------------------------------------------------------------ state
    def reset(self, q: ArrayLike, qd: ArrayLike | None = None, *, theta: ArrayLike | None = None,
              thetad: ArrayLike | None = None) -> None:
        """Set the state.

        ``theta`` defaults to the static equilibrium q + K^-1 G(q) (springs wound up by gravity), ``thetad`` to
        ``qd``.
        """
        q = self.robot.check_q(q, "q")
        qd = np.zeros(self.n) if qd is None else self.robot.check_q(qd, "qd")
        self.q, self.qd = q.copy(), qd.copy()
        self.theta = self.equilibrium_motor_position(q) if theta is None else self.robot.check_q(theta, "theta").copy()
        self.thetad = qd.copy() if thetad is None else self.robot.check_q(thetad, "thetad").copy()
        self.time = 0.0

    def equilibrium_motor_position(self, q: ArrayLike) -> np.ndarray:
        """Theta with K (theta - q) = G(q): the motor position holding the arm still at q, (n,)."""
        q = self.robot.check_q(q)
        return q + pin.computeGeneralizedGravity(self._model, self._data, q) / self._K

    def holding_torque(self, q: ArrayLike) -> np.ndarray:
        """Motor torque tau_m (motor side, N m) that holds the arm at rest at q: G(q) / N."""
        q = self.robot.check_q(q)
        return pin.computeGeneralizedGravity(self._model, self._data, q) / self._N

    @property
    def deflection(self) -> np.ndarray:
        """Theta - q, (n,) rad: the joint (spring) deflection."""
        return self.theta - self.q

    @property
    def joint_torque(self) -> np.ndarray:
        """Spring torque transmitted to the links K (theta - q) + D (thetad - qd), (n,) N m."""
        return self._K * (self.theta - self.q) + self._D * (self.thetad - self.qd)

    # ------------------------------------------------------------------ dynamics
    def step(self, tau_m: ArrayLike, tau_ext: ArrayLike | None = None) -> None:
        """Advance the flexible-joint model by one step ``dt``.

        Advance by ``dt`` with motor torques ``tau_m`` (n,) N m (motor side, held constant) and an optional external
        joint torque ``tau_ext`` (n,) on the links.

        Raises:
            ShapeError, NotFinite: bad torques (the state is unchanged).
            SafetyStop: the state became non-finite.
        """
        tau_m = as_array(tau_m, "tau_m", (self.n,))
        tau_ext = np.zeros(self.n) if tau_ext is None else as_array(tau_ext, "tau_ext", (self.n,))
        h = self.dt / self.substeps
        K, D, J, B = self._K, self._D, self._J, self._B
        u = self._N * tau_m
        S = h * (h * K + D)  # implicit spring-damper coupling
        A22 = J + h * B + S
        for _ in range(self.substeps):
            q, qd, th, thd = self.q, self.qd, self.theta, self.thetad
            M = pin.crba(self._model, self._data, q)
            M = np.triu(M) + np.triu(M, 1).T
            c = pin.nonLinearEffects(self._model, self._data, q, qd)
            spring = K * (th - q)
            r1 = M @ qd + h * (spring - c + tau_ext)
            r2 = J * thd + h * (u - spring)
            # eliminate thetad+ = (r2 + S qd+) / A22 from the 2n x 2n system
            A = M + np.diag(S - S * S / A22)
            qd_new = np.linalg.solve(A, r1 + S * r2 / A22)
            thd_new = (r2 + S * qd_new) / A22
            self.q = q + h * qd_new
            self.qd = qd_new
            self.theta = th + h * thd_new
            self.thetad = thd_new
            self.time += h
        if not (np.all(np.isfinite(self.q)) and np.all(np.isfinite(self.theta))):
            raise SafetyStop("the flexible-joint simulation diverged (non-finite state); check the parameters")

    def controller(self, **kwargs: Any) -> JointController:
        """A Fig.

        2.3 :class:`~robointel.sim.JointController` for this arm: feed-forward and gain schedule from the rigid
        limit (M(q) + J, RNEA with the rotor inertia; keyword arguments go to the controller). The URDF friction
        compensation is off (this model has motor friction B).
        """
        rigid = self.rigid_model()
        kwargs.setdefault("friction_compensation", False)
        return JointController(self.robot, dt=self.dt, model=rigid, gain_model=rigid, **kwargs)

    def track(self, controller: JointController, q_ref: ArrayLike, qd_ref: ArrayLike | None = None,
              qdd_ref: ArrayLike | None = None, *, measure: str = "motor") -> np.ndarray:
        """One control period of ``controller`` (a :class:`~robointel.sim.JointController`) on this arm.

        It measures the motor encoders (``measure="motor"``, theta, as a real drive does) or the links (``"link"``,
        q), its joint torque is sent as tau_m = tau / N. Returns tau (n,).

        Raises:
            ShapeError, NotFinite: bad references.
        """
        z = np.zeros(self.n)
        q_ref = as_array(q_ref, "q_ref", (self.n,))
        qd_ref = z if qd_ref is None else as_array(qd_ref, "qd_ref", (self.n,))
        qdd_ref = z if qdd_ref is None else as_array(qdd_ref, "qdd_ref", (self.n,))
        if measure == "motor":
            pos, vel = self.theta, self.thetad
        elif measure == "link":
            pos, vel = self.q, self.qd
        else:
            raise InvalidInput(f"measure must be 'motor' or 'link', got {measure!r}", value=measure)
        tau = controller.compute(pos, vel, q_ref, qd_ref, qdd_ref)
        self.step(tau / self._N)
        return tau

    def simulate(self, tau_m_fn: Callable[[FlexibleJointModel], np.ndarray], duration: float) -> dict[str, np.ndarray]:
        """Run for ``duration`` s calling ``tau_m_fn(model) -> tau_m`` every ``dt``.

        Returns arrays ``t`` (N,), ``q``, ``qd``, ``theta``, ``thetad``, ``tau_m`` (N, n) sampled before each step.
        """
        steps = int(round(float(duration) / self.dt))
        out: dict[str, np.ndarray] = {k: np.empty((steps, self.n)) for k in ("q", "qd", "theta", "thetad", "tau_m")}
        t = np.empty(steps)
        for k in range(steps):
            t[k] = self.time
            out["q"][k], out["qd"][k] = self.q, self.qd
            out["theta"][k], out["thetad"][k] = self.theta, self.thetad
            tau = np.asarray(tau_m_fn(self), dtype=np.float64)
            out["tau_m"][k] = tau
            self.step(tau)
        out["t"] = t
        return out

    def resonance_frequencies(self, q: ArrayLike) -> np.ndarray:
        """Natural frequencies of the elastic modes of (2.1)-(2.2), Hz.

        Natural frequencies (Hz, ascending, n of them) of the elastic modes of (2.1)-(2.2) linearised at rest at q
        without damping: the nonzero roots of det([[K - w^2 M, -K], [-K, K - w^2 J]]) = 0.

        Raises:
            InvalidInput: bad q.
        """
        q = self.robot.check_q(q)
        M = pin.crba(self._model, self._data, q)
        M = np.triu(M) + np.triu(M, 1).T
        n = self.n
        Kf = np.block([[np.diag(self._K), -np.diag(self._K)], [-np.diag(self._K), np.diag(self._K)]])
        Mf = np.block([[M, np.zeros((n, n))], [np.zeros((n, n)), np.diag(self._J)]])
        w2 = eigh(Kf, Mf, eigvals_only=True)
        w2 = np.sort(w2)[n:]  # the n rigid-body modes have w = 0
        return np.sqrt(np.maximum(w2, 0.0)) / (2 * np.pi)

    def rigid_model(self) -> pin.Model:
        """The K -> inf limit as a Pinocchio model.

        ``robot.model`` with armature J = N^2 J_m (its viscous friction B = N^2 B_m is
        :attr:`FlexibleJointParams.reflected_friction`).
        """
        m = self._model.copy()
        m.armature = self._J.copy()
        return m
