"""Stepping the workcell: reset, torque steps, the joint controller's tracking and holding, the safe stop.

The safe stop puts the robot back at rest where it last was when MuJoCo diverges.
"""
from __future__ import annotations

import mujoco
import numpy as np
import numpy.typing as npt

from robointel._validate import as_array
from robointel.errors import NotFinite, SafetyStop, ShapeError
from robointel.sim.workcell_model import WorkcellModel


class Stepping(WorkcellModel):
    """Reset and step the simulation under the joint controller."""

    def reset(self, q: npt.ArrayLike | None = None, qd: npt.ArrayLike | None = None) -> None:
        """Reset time, objects and obstacles to their initial poses and the robot to ``q`` at ``qd``.

        ``q`` defaults to ``q0``, else zeros clipped into the limits; ``qd`` to 0. Clears the
        controller's integral and the applied wrench, and holds at ``q``.

        Raises:
            ShapeError, NotFinite, LimitViolation: bad ``q``/``qd``.
        """
        if q is None:
            q = self._q0 if self._q0 is not None else np.clip(np.zeros(self.n), self.robot.lower, self.robot.upper)
        q0 = self.robot.check_q(q, "q", limits=True)
        qd0 = np.zeros(self.n) if qd is None else self.robot.check_q(qd, "qd")
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self._qadr] = q0
        self.data.qvel[self._vadr] = qd0
        self.controller.reset()
        # start with the holding (feed-forward) torque so that sensors read a robot at rest
        self.data.ctrl[self._aid] = self.controller.feedforward_torque(q0, qd0, np.zeros(self.n))
        mujoco.mj_forward(self.model, self.data)
        self._wrench = None
        self.data.xfrc_applied[:] = 0
        self._hold = (q0.copy(), np.zeros(self.n), np.zeros(self.n))
        self._q_safe, self._t_safe = q0.copy(), 0.0
        self._warn0 = self._bad_count()


    @property
    def hold_reference(self) -> np.ndarray:
        """The joint position the controller holds when no valid command arrives, (n,) rad."""
        return self._hold[0].copy()


    def step(self, tau: npt.ArrayLike) -> None:
        """One physics step with joint torques ``tau`` (n,) N m (clipped to the effort limits).

        Bypasses the joint controller (for your own torque controller); :meth:`hold` afterwards
        holds the position the robot had at the last step.

        Raises:
            ShapeError, NotFinite: bad ``tau`` (nothing is applied, the state is unchanged; the
                joint controller takes over holding with :meth:`hold`).
            SafetyStop: the simulation became unstable; the robot is put back at rest where it was.
        """
        q = self.data.qpos[self._qadr].copy()
        try:
            tau = as_array(tau, "tau", (self.n,))
        except (ShapeError, NotFinite):
            self._hold = (q, np.zeros(self.n), np.zeros(self.n))
            raise
        self._q_safe, self._t_safe = q, self.data.time
        self._hold = (q, self._zero, self._zero)
        self._physics_step(tau)

    def _physics_step(self, tau: np.ndarray, check: bool = True) -> None:
        d = self.data
        d.ctrl[self._aid] = tau
        if self._wrench is not None:
            self._apply_wrench_now()
        mujoco.mj_step(self.model, d)
        if check and self._bad_count() != self._warn0:
            self._safe_stop()

    def _safe_stop(self) -> None:
        """MuJoCo diverged and reset its state: put the robot back at rest where it last was, and raise.

        The robot holds there (objects stay where MuJoCo's reset put them); raises SafetyStop.
        """
        d = self.data
        self._warn0 = self._bad_count()
        self._wrench = None
        d.xfrc_applied[:] = 0
        d.qpos[self._qadr] = self._q_safe
        d.qvel[:] = 0
        d.time = self._t_safe
        mujoco.mj_forward(self.model, d)
        self.controller.reset()
        self._hold = (self._q_safe.copy(), np.zeros(self.n), np.zeros(self.n))
        raise SafetyStop("the simulation became unstable (MuJoCo: bad qacc); the robot was put back at rest where "
                         "it last was, the external wrench cleared, and it holds there. Lower the torques, wrenches "
                         "or the timestep", value=self._q_safe.copy())

    def track(self, q_ref: npt.ArrayLike, qd_ref: npt.ArrayLike | None = None,
              qdd_ref: npt.ArrayLike | None = None) -> np.ndarray:
        """One 1 kHz control period tracking (q_ref, qd_ref, qdd_ref); returns the applied torques (n,) N m.

        Each is (n,); velocities and accelerations default to 0 (a position command).

        Raises:
            ShapeError, NotFinite: a bad command. The controller then holds the last valid
                reference (zero velocity); nothing is stepped. Call :meth:`hold` to keep holding.
        """
        try:
            q_ref = self._vec(q_ref, "q_ref")
            qd_ref = self._zero if qd_ref is None else self._vec(qd_ref, "qd_ref")
            qdd_ref = self._zero if qdd_ref is None else self._vec(qdd_ref, "qdd_ref")
        except (ShapeError, NotFinite):
            self._hold = (self._hold[0], np.zeros(self.n), np.zeros(self.n))
            raise
        self._hold = (q_ref, np.zeros(self.n), np.zeros(self.n))
        return self._control(q_ref, qd_ref, qdd_ref)

    def _vec(self, x: npt.ArrayLike, name: str) -> np.ndarray:
        """as_array(x, name, (n,)) with a fast path for finite float64 (n,) arrays (a copy)."""
        if type(x) is np.ndarray and x.shape == (self.n,) and x.dtype == np.float64:
            s = float(x.sum())
            if s - s == 0.0:  # finite sum <=> all finite (barring overflow near 1e308)
                return x.copy()
        return as_array(x, name, (self.n,))

    def _control(self, q_ref: np.ndarray, qd_ref: np.ndarray, qdd_ref: np.ndarray) -> np.ndarray:
        d = self.data
        q = d.qpos[self._qadr].copy()
        self._q_safe, self._t_safe = q, d.time
        tau = self.controller.compute(q, d.qvel[self._vadr], q_ref, qd_ref, qdd_ref)
        for k in range(self.substeps):
            self._physics_step(tau, check=k == self.substeps - 1)
        return tau

    def hold(self, duration: float | None = None) -> None:
        """Hold the last valid reference position for ``duration`` s (whole control periods; default one)."""
        steps = 1 if duration is None else max(1, int(round(float(duration) / self.control_dt)))
        q, z, _ = self._hold
        for _ in range(steps):
            self._control(q, z, z)

    def command_velocity(self, qd_cmd: npt.ArrayLike) -> np.ndarray:
        """Velocity command mode: track the held reference advanced by ``qd_cmd`` for one period.

        ``qd_cmd`` (n,) rad/s is integrated into the held reference (clipped to the joint limits). Returns torques.
        """
        try:
            qd_cmd = as_array(qd_cmd, "qd_cmd", (self.n,))
        except (ShapeError, NotFinite):
            self._hold = (self._hold[0], np.zeros(self.n), np.zeros(self.n))
            raise
        q_ref = np.clip(self._hold[0] + qd_cmd * self.control_dt, self.robot.lower, self.robot.upper)
        qd_ref = np.where((q_ref <= self.robot.lower) | (q_ref >= self.robot.upper), 0.0, qd_cmd)
        self._hold = (q_ref, np.zeros(self.n), np.zeros(self.n))
        return self._control(q_ref, qd_ref, np.zeros(self.n))
