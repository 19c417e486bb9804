"""The simulated workcell: the LR Mate (or any robot) on a table in MuJoCo, under the joint controller.

Frames: the MuJoCo world frame is the robot root frame (``base_link`` on the mounting plane; the
table top is the plane z = 0; the floor is at z = -0.75 m). Joint vectors are in
``robot.joint_names`` order. Control runs at 1 kHz; the physics step defaults to 1 ms.

F/T sensor: the site ``"ft_sensor"`` at the flange, axes = the flange frame
(``robot.frame_pose(q, "flange")``; for the LR Mate x points out of the flange along the J6 axis).
:meth:`Workcell.ft_reading` returns the wrench [f; m] **exerted by the tool (and whatever acts on
it: payload weight, the human's hand, contacts) on the sensor**, in the sensor frame, torque about
the sensor origin. A payload of mass m with its CoM at r (sensor frame) at rest reads
f = m g_s and m = r x (m g_s), with g_s gravity in the sensor frame. Readings come from MuJoCo's
``force``/``torque`` sensors (the interaction wrench between the tool body and the flange, with the
sign flipped) computed at the start of the last physics step: one step (1 ms) of latency.
Bias and white noise are added in Python (:class:`FTSensor`, or per call).

Faults: bad commands raise ``robointel.errors`` (ShapeError, NotFinite, LimitViolation) before
anything is applied, and the controller keeps holding the last valid reference; if MuJoCo ever
diverges, the robot is put back at rest where it was and :class:`~robointel.errors.SafetyStop`
is raised.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline

from robointel._validate import as_array, check_limits
from robointel.control.servo import JointController, PIDGains, model_with_payload
from robointel.errors import InvalidInput
from robointel.robot import Robot
from robointel.sim.contacts import Contact, ContactSensing
from robointel.sim.ft_sensing import FTSensing, FTSensor
from robointel.sim.grasp_welds import GraspWelds
from robointel.sim.mjcf import Payload, SimObject, shape_geoms
from robointel.sim.render import render, render_frames
from robointel.sim.snapshots import Snapshots
from robointel.sim.stepping import Stepping
from robointel.sim.tracking_log import TrackingLog
from robointel.sim.workcell_model import CONTROL_DT
from robointel.trajectory import Trajectory

__all__ = ["Workcell", "TrackingLog", "Contact", "FTSensor", "CONTROL_DT"]


class Workcell(Stepping, FTSensing, ContactSensing, GraspWelds, Snapshots):
    """A MuJoCo workcell built from the robot's URDF, driven by the Fig. 2.3 joint controller.

    Args:
        robot: a :class:`robointel.robot.Robot` or a name for ``Robot.load`` (default: the LR Mate).
        obstacles: ``robointel.geometry`` shapes in the world frame (mocap bodies, movable).
        objects: :class:`SimObject` free bodies.
        table: add the table (top at z = 0) and the floor.
        ft_sensor: add the flange F/T sensor; pass an :class:`FTSensor` to set bias and noise.
        payload: optional :class:`Payload` after the sensor.
        timestep: physics step (s). The controller runs every 1 ms (``timestep`` must divide it),
            or at the physics rate when ``timestep`` >= 1 ms (:attr:`control_dt`).
        gains: fixed :class:`PIDGains`; default: inertia-scheduled gains (see ``controller``).
        bandwidth_hz: closed-loop bandwidth of the scheduled gains, scalar or (n,) Hz.
        compensate_payload: include the payload in the controller's feed-forward model (the gain
            schedule always includes it).
        armature: optional (n,) reflected rotor inertia (kg m^2) in MuJoCo and in the controller.
        self_collision: robot-robot contacts in MuJoCo (off by default, see ``mjcf.build_spec``).
        q0: initial configuration, also the default of :meth:`reset` (default: zeros clipped into
            the limits).
    """

    def __init__(self, robot: Robot | str | None = None, obstacles: Sequence[Any] = (),
                 objects: Sequence[SimObject] = (), table: bool = True, ft_sensor: bool | FTSensor = True,
                 payload: Payload | None = None,
                 timestep: float = 0.001, *, gains: PIDGains | None = None,
                 bandwidth_hz: float | npt.ArrayLike | None = None,
                 compensate_payload: bool = True,
                 armature: npt.ArrayLike | None = None, self_collision: bool = False,
                 q0: npt.ArrayLike | None = None) -> None:
        if robot is None or isinstance(robot, str):
            robot = Robot.load(robot or "lrmate200id7l")
        self.robot = robot
        self.n = robot.nq
        self.timestep = float(timestep)
        if not (np.isfinite(self.timestep) and self.timestep > 0):
            raise InvalidInput(f"timestep must be a positive number of seconds, got {timestep!r}", value=timestep)
        if self.timestep >= CONTROL_DT - 1e-12:  # coarse physics: control at the physics rate
            self.control_dt, self.substeps = self.timestep, 1
        else:
            sub = CONTROL_DT / self.timestep
            if abs(sub - round(sub)) > 1e-6:
                raise InvalidInput(f"timestep {timestep!r} must divide the 1 ms control period", value=timestep)
            self.control_dt, self.substeps = CONTROL_DT, int(round(sub))
        self.ft_config = ft_sensor if isinstance(ft_sensor, FTSensor) else FTSensor()
        self._has_ft = bool(ft_sensor)
        self.payload = payload
        self._armature = None if armature is None else as_array(armature, "armature", (self.n,))
        self._table = table
        self._self_collision = bool(self_collision)
        self._obstacles = list(obstacles)
        self._objects = list(objects)
        self._build()
        pin_model = model_with_payload(robot, payload if compensate_payload else None)
        gain_model = model_with_payload(robot, payload)  # the servo tuning knows the tool
        if self._armature is not None:
            pin_model.armature = self._armature.copy()
            gain_model.armature = self._armature.copy()
        self.controller = JointController(robot, gains, bandwidth_hz=bandwidth_hz, dt=self.control_dt, model=pin_model,
                                          gain_model=gain_model)
        self._wrench: tuple[int, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._q0 = None if q0 is None else self.robot.check_q(q0, "q0", limits=True).copy()
        self.reset()


    def run_trajectory(self, t: npt.ArrayLike | Trajectory, q: npt.ArrayLike | None = None,
                       qd: npt.ArrayLike | None = None, qdd: npt.ArrayLike | None = None, *, reset: bool = True,
                       record_ft: bool = True, distance_every: int = 10, stop_on_contact: bool = False) -> TrackingLog:
        """Track a joint trajectory with the controller at 1 kHz and log the result.

        Args:
            t: (N,) strictly increasing times (s), or a trajectory object with ``t``, ``q``,
                ``qd``, ``qdd`` attributes (``robointel.io.trajectory.Trajectory``).
            q: (N, n) joint positions within the limits. The reference is
                ``Trajectory.resample`` on the 1 kHz grid: the cubic Hermite interpolant of (q, qd)
                and its derivatives; without qd, the knot velocities of the not-a-knot cubic spline
                through q (so the reference is that spline). ``qdd`` is accepted for compatibility;
                the reference acceleration is the interpolant's.
            qd: (N, n) joint velocities, rad/s (optional).
            qdd: (N, n) joint accelerations, rad/s^2 (optional, checked, not used).
            reset: start from rest at q[0] (else from the current state).
            record_ft: log the F/T wrench each period.
            distance_every: evaluate the robot-obstacle distance every this many periods.
            stop_on_contact: stop at the first contact with the environment.

        Raises:
            ShapeError, NotFinite, LimitViolation, InvalidInput: bad trajectory (nothing runs).
        """
        src: Any = t
        if q is None and hasattr(src, "t") and hasattr(src, "q"):
            src, q, qd, qdd = src.t, src.q, getattr(src, "qd", None), getattr(src, "qdd", None)
        if q is None:
            raise InvalidInput("run_trajectory needs q (N, n) or a trajectory object", value=src)
        t = as_array(src, "t", (None,))
        N = len(t)
        if N < 2:
            raise InvalidInput("a trajectory needs at least 2 samples", value=t)
        if np.any(np.diff(t) <= 0):
            raise InvalidInput("t must be strictly increasing", value=t)
        q = as_array(q, "q", (N, self.n))
        if np.any(q < self.robot.lower - 1e-6) or np.any(q > self.robot.upper + 1e-6):
            k = int(np.flatnonzero(np.any((q < self.robot.lower - 1e-6) | (q > self.robot.upper + 1e-6), axis=1))[0])
            check_limits(q[k], self.robot.lower, self.robot.upper, self.robot.joint_names, f"q[{k}]", tol=1e-6)
        if qd is None:
            qd = CubicSpline(t, q)(t, 1)
        qd = as_array(qd, "qd", (N, self.n))
        if qdd is not None:
            as_array(qdd, "qdd", (N, self.n))
        ref = Trajectory(t, q, qd, np.zeros_like(q)).resample(self.control_dt)
        tg, Q, QD, QDD = ref.t, np.clip(ref.q, self.robot.lower, self.robot.upper), ref.qd, ref.qdd
        if reset:
            self.reset(Q[0], QD[0])
        K = len(tg)
        t0 = self.time
        logs = {k: np.empty((K, self.n)) for k in ("q", "qd", "tau")}
        ft = np.empty((K, 6)) if (record_ft and self._has_ft) else None
        ncon = np.zeros(K, dtype=int)
        dist = np.full(K, np.inf if len(self._obstacle_geoms) == 0 else np.nan)
        sat = np.zeros((K, self.n), dtype=bool)
        d = self.data
        last = K
        qadr, vadr = self._qadr, self._vadr
        nobst = len(self._obstacle_geoms)
        fa = self._ft_adr if ft is not None else 0
        zero = np.zeros(self.n)
        ctrl = self.controller
        for k in range(K):
            logs["q"][k] = d.qpos[qadr]
            logs["qd"][k] = d.qvel[vadr]
            self._hold = (Q[k], zero, zero)
            logs["tau"][k] = self._control(Q[k], QD[k], QDD[k])
            sat[k] = ctrl.saturated
            if ft is not None:
                ft[k] = d.sensordata[fa:fa + 6]
            if d.ncon:
                ncon[k] = self._environment_contact_count()
            if nobst and (k % distance_every == 0 or ncon[k]):
                dist[k] = self.obstacle_distance()[0]
            if stop_on_contact and ncon[k]:
                last = k + 1
                break
        if ft is not None:  # sign convention, bias and noise as in ft_reading
            cfg = self.ft_config
            ft = -ft + cfg.bias
            if np.any(cfg.noise_std > 0):
                ft = ft + cfg.noise_std * cfg.rng.standard_normal(ft.shape)
        sl = slice(0, last)
        return TrackingLog(t=t0 + tg[sl] - tg[0], q=logs["q"][sl], qd=logs["qd"][sl], q_ref=Q[sl], qd_ref=QD[sl],
                           tau=logs["tau"][sl], ft=None if ft is None else ft[sl], contacts=ncon[sl],
                           distance=dist[sl], joint_names=list(self.robot.joint_names), saturated=sat[sl])


    # ------------------------------------------------------------------ scene edits
    def add_obstacle(self, shape: Any) -> str:
        """Add a ``robointel.geometry`` shape (recompiles the model, keeps the state); return its name."""
        shape_geoms(shape)  # validate first
        state = self._save_state()
        wrench = None if self._wrench is None else (self._body_names[self._wrench[0]],) + self._wrench[1:]
        self._obstacles.append(shape)
        try:
            self._build()
        except Exception:
            self._obstacles.pop()
            self._build()
            self._restore_state(state)
            raise
        self._restore_state(state)
        if wrench is not None:
            self._wrench = (self._body_id(wrench[0]),) + wrench[1:]
        return self.info["obstacles"][-1]


    # ------------------------------------------------------------------ rendering
    def render(self, path: str | Path | None = None, *, width: int = 640, height: int = 480,
               camera: dict | None = None) -> np.ndarray:
        """Render the scene offscreen to an (h, w, 3) uint8 image, saved as PNG when ``path``.

        Raises:
            RobointelError: no offscreen OpenGL (EGL/OSMesa) available, with the reason.
        """
        return render(self, path, width=width, height=height, camera=camera)

    def render_frames(self, qs: Sequence[npt.ArrayLike] | np.ndarray, path: str | Path | None = None,
                      *, width: int = 480, height: int = 360, camera: dict | None = None,
                      columns: int | None = None) -> np.ndarray:
        """Render robot configurations ``qs`` ((k, n) or full qpos vectors) into one montage image.

        See :func:`robointel.sim.render.render_frames`.
        """
        return render_frames(self, qs, path, width=width, height=height, camera=camera, columns=columns)

    def __repr__(self) -> str:
        return (f"Workcell({self.robot.name!r}, obstacles={self.obstacle_names}, objects={self.info['objects']}, "
                f"payload={self.payload is not None}, t={self.time:.3f}s)")
