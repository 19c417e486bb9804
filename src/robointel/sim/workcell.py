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

from dataclasses import dataclass, field
from typing import Any, Sequence

import mujoco
import numpy as np
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from robointel._validate import as_array, check_limits
from robointel.errors import InvalidInput, NotFinite, SafetyStop, ShapeError
from robointel.control.servo import JointController, PIDGains, model_with_payload
from robointel.sim.mjcf import (FT_SITE, OBJECT_PREFIX, OBSTACLE_PREFIX, TOOL_BODY, Payload, SimObject,
                                build_spec, shape_geoms)

CONTROL_DT = 0.001  # 1 kHz joint controller


@dataclass
class FTSensor:
    """Configuration of the simulated F/T sensor's imperfections (added in Python).

    Args:
        bias: (6,) constant offset [N, N, N, N m, N m, N m] added to every reading.
        noise_std: scalar or (6,) standard deviation of white Gaussian noise.
        seed: seed of the noise generator (deterministic by default).
    """

    bias: Any = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    noise_std: Any = 0.0
    seed: int | None = 0

    def __post_init__(self) -> None:
        self.bias = as_array(self.bias, "FTSensor.bias", (6,))
        self.noise_std = np.broadcast_to(as_array(self.noise_std, "FTSensor.noise_std"), (6,)).astype(float)
        if np.any(self.noise_std < 0):
            raise InvalidInput("FTSensor.noise_std must be >= 0", value=self.noise_std)
        self.rng = np.random.default_rng(self.seed)


@dataclass(frozen=True)
class Contact:
    """One MuJoCo contact involving the robot (or its tool).

    ``distance`` is MuJoCo's signed contact distance (m, negative = penetration); ``position``
    (3,) the contact point and ``normal`` (3,) the unit normal pointing from ``robot_geom`` toward
    ``other_geom``, both in the world frame. ``force`` (3,) N is the contact force the other geom
    exerts on the robot geom (world frame; normal + friction). ``kind`` is "obstacle", "table",
    "floor", "object", "self" (robot-robot) or "world".
    """

    robot_geom: str
    other_geom: str
    robot_body: str
    other_body: str
    kind: str
    distance: float
    position: np.ndarray
    normal: np.ndarray
    force: np.ndarray


@dataclass
class TrackingLog:
    """What :meth:`Workcell.run_trajectory` recorded at each 1 kHz control step.

    Arrays: ``t`` (N,) s; ``q``, ``qd``, ``q_ref``, ``qd_ref``, ``tau`` (N, n) rad, rad/s, N m;
    ``ft`` (N, 6) sensor wrench or None; ``contacts`` (N,) number of robot contacts with the
    environment (obstacles, table, floor, self); ``distance`` (N,) minimum robot-obstacle signed
    distance (m; NaN where not evaluated, ``inf`` without obstacles).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    q_ref: np.ndarray
    qd_ref: np.ndarray
    tau: np.ndarray
    ft: np.ndarray | None
    contacts: np.ndarray
    distance: np.ndarray
    joint_names: list[str] = field(default_factory=list)
    saturated: np.ndarray | None = None

    @property
    def error(self) -> np.ndarray:
        """Tracking error q_ref - q, (N, n) rad."""
        return self.q_ref - self.q

    @property
    def rms_error(self) -> np.ndarray:
        """RMS tracking error per joint, (n,) rad."""
        return np.sqrt(np.mean(self.error**2, axis=0))

    @property
    def max_error(self) -> np.ndarray:
        """Maximum absolute tracking error per joint, (n,) rad."""
        return np.max(np.abs(self.error), axis=0)

    @property
    def min_distance(self) -> float:
        """Smallest robot-obstacle distance over the run (m; ``inf`` without obstacles)."""
        d = self.distance[np.isfinite(self.distance) | np.isinf(self.distance)]
        return float(np.min(d)) if d.size else float("inf")

    @property
    def collided(self) -> bool:
        """True if the robot touched an obstacle, the table, the floor or itself."""
        return bool(np.any(self.contacts > 0)) or self.min_distance < 0

    @property
    def saturation_fraction(self) -> np.ndarray:
        """Fraction of control periods each joint's torque was at its effort limit, (n,)."""
        if self.saturated is None or len(self.saturated) == 0:
            return np.zeros(self.q.shape[1])
        return self.saturated.mean(axis=0)

    def velocity_ratio(self, robot) -> np.ndarray:
        """max_t |qd_ref| / velocity limit per joint, (n,): > 1 means the reference was too fast."""
        return np.max(np.abs(self.qd_ref), axis=0) / robot.velocity_limit

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self.t) else 0.0

    def tcp_error(self, robot) -> np.ndarray:
        """TCP position error |p(q_ref) - p(q)| per sample, (N,) m."""
        return np.array([np.linalg.norm(robot.fk(a)[:3, 3] - robot.fk(b)[:3, 3]) for a, b in zip(self.q_ref, self.q)])

    def to_dict(self) -> dict:
        """All arrays and the joint names (for ``np.savez`` / JSON)."""
        out = {k: getattr(self, k) for k in ("t", "q", "qd", "q_ref", "qd_ref", "tau", "contacts", "distance")}
        if self.ft is not None:
            out["ft"] = self.ft
        if self.saturated is not None:
            out["saturated"] = self.saturated
        out["joint_names"] = np.array(self.joint_names)
        return out

    def save(self, path) -> None:
        """Write the log as a compressed ``.npz``."""
        np.savez_compressed(path, **self.to_dict())

    @classmethod
    def load(cls, path) -> "TrackingLog":
        """Read a log written by :meth:`save`."""
        with np.load(path) as z:
            d = {k: z[k] for k in z.files}
        return cls(t=d["t"], q=d["q"], qd=d["qd"], q_ref=d["q_ref"], qd_ref=d["qd_ref"], tau=d["tau"],
                   ft=d.get("ft"), contacts=d["contacts"], distance=d["distance"],
                   joint_names=[str(x) for x in d["joint_names"]], saturated=d.get("saturated"))

    def summary(self) -> dict:
        """Scalars for reports: RMS/max error per joint (rad), min distance, collided, duration."""
        return {"rms_error_rad": self.rms_error.tolist(), "max_error_rad": self.max_error.tolist(),
                "rms_error_all_rad": float(np.sqrt(np.mean(self.error**2))),
                "min_distance_m": self.min_distance, "collided": self.collided, "duration_s": self.duration}


class Workcell:
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

    def __init__(self, robot=None, obstacles: Sequence[Any] = (), objects: Sequence[SimObject] = (),
                 table: bool = True, ft_sensor: bool | FTSensor = True, payload: Payload | None = None,
                 timestep: float = 0.001, *, gains: PIDGains | None = None, bandwidth_hz=None,
                 compensate_payload: bool = True,
                 armature=None, self_collision: bool = False, q0=None) -> None:
        if robot is None or isinstance(robot, str):
            from robointel.robot import Robot

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

    # ------------------------------------------------------------------ model
    def _build(self) -> None:
        self.spec, self.info = build_spec(self.robot, table=self._table, obstacles=self._obstacles,
                                          objects=self._objects, ft_sensor=self._has_ft, payload=self.payload,
                                          timestep=self.timestep, armature=self._armature,
                                          self_collision=self._self_collision)
        try:
            self.model = self.spec.compile()
        except Exception as exc:
            from robointel.errors import DescriptionError

            raise DescriptionError(f"MuJoCo could not compile the workcell: {exc}") from None
        self.data = mujoco.MjData(self.model)
        m = self.model
        jids = [m.joint(nm).id for nm in self.robot.joint_names]
        self._qadr = np.array([m.jnt_qposadr[j] for j in jids])
        self._vadr = np.array([m.jnt_dofadr[j] for j in jids])
        self._aid = np.array([m.actuator(nm).id for nm in self.robot.joint_names])
        if np.array_equal(self._qadr, np.arange(self.n)) and np.array_equal(self._vadr, np.arange(self.n)):
            self._qadr = self._vadr = slice(0, self.n)
        if np.array_equal(self._aid, np.arange(self.n)):
            self._aid = slice(0, self.n)
        # which geoms belong to the robot (bodies in the subtree of the robot's root link)
        root = m.body(self._root_link()).id
        robot_bodies = {b for b in range(m.nbody) if self._in_subtree(b, root)}
        self._robot_body = np.array([b in robot_bodies for b in range(m.nbody)])
        self._geom_robot = self._robot_body[m.geom_bodyid]
        self._geom_names = [m.geom(g).name or f"geom{g}" for g in range(m.ngeom)]
        self._body_names = [m.body(b).name for b in range(m.nbody)]
        self._obstacle_geoms = np.array([g for g in range(m.ngeom) if self._geom_names[g].startswith(OBSTACLE_PREFIX)],
                                        dtype=int)
        self._robot_geoms = np.flatnonzero(self._geom_robot & ((m.geom_contype | m.geom_conaffinity) > 0))
        self._mocap = {nm: int(m.body_mocapid[m.body(OBSTACLE_PREFIX + nm).id]) for nm in self.info["obstacles"]}
        self._tool_id = m.body(TOOL_BODY).id
        if self._has_ft:
            self._ft_adr = int(m.sensor_adr[m.sensor("ft_force").id])
            self._site_id = m.site(FT_SITE).id
        self._warn0 = 0
        self._zero = np.zeros(self.n)
        self._zero.flags.writeable = False

    def _root_link(self) -> str:
        """The robot's root body: the ancestor of the first joint's body that hangs on the world."""
        m = self.model
        b = int(m.jnt_bodyid[m.joint(self.robot.joint_names[0]).id])
        while m.body_parentid[b] != 0:
            b = int(m.body_parentid[b])
        return m.body(b).name

    def _in_subtree(self, b: int, root: int) -> bool:
        m = self.model
        while b > 0:
            if b == root:
                return True
            b = m.body_parentid[b]
        return b == root

    # ------------------------------------------------------------------ state
    def reset(self, q=None, qd=None) -> None:
        """Reset time, objects and obstacles to their initial poses and the robot to ``q``
        (default ``q0``, else zeros clipped into the limits) at velocity ``qd`` (default 0); clear the
        controller's integral, the applied wrench and hold at ``q``.

        Raises:
            ShapeError, NotFinite, LimitViolation: bad ``q``/``qd``.
        """
        if q is None:
            q = self._q0 if self._q0 is not None else np.clip(np.zeros(self.n), self.robot.lower, self.robot.upper)
        q = self.robot.check_q(q, "q", limits=True)
        qd = np.zeros(self.n) if qd is None else self.robot.check_q(qd, "qd")
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self._qadr] = q
        self.data.qvel[self._vadr] = qd
        self.controller.reset()
        # start with the holding (feed-forward) torque so that sensors read a robot at rest
        self.data.ctrl[self._aid] = self.controller.feedforward_torque(q, qd, np.zeros(self.n))
        mujoco.mj_forward(self.model, self.data)
        self._wrench = None
        self.data.xfrc_applied[:] = 0
        self._hold = (q.copy(), np.zeros(self.n), np.zeros(self.n))
        self._q_safe, self._t_safe = q.copy(), 0.0
        self._warn0 = self._bad_count()

    @property
    def q(self) -> np.ndarray:
        """Joint positions (n,) rad."""
        return self.data.qpos[self._qadr].copy()

    @property
    def qd(self) -> np.ndarray:
        """Joint velocities (n,) rad/s."""
        return self.data.qvel[self._vadr].copy()

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return float(self.data.time)

    @property
    def qpos_index(self):
        """Where the robot's joints sit in MuJoCo's ``qpos`` (a slice or an index array)."""
        return self._qadr

    @property
    def hold_reference(self) -> np.ndarray:
        """The joint position the controller holds when no valid command arrives, (n,) rad."""
        return self._hold[0].copy()

    def _bad_count(self) -> int:
        w = self.data.warning
        return int(w[mujoco.mjtWarning.mjWARN_BADQACC].number)

    # ------------------------------------------------------------------ stepping
    def step(self, tau) -> None:
        """One physics step with joint torques ``tau`` (n,) N m (clipped to the effort limits),
        bypassing the joint controller (for your own torque controller). :meth:`hold` afterwards
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
        """MuJoCo diverged and reset its state: put the robot back where it last was, at rest,
        holding there (objects stay where MuJoCo's reset put them), and raise SafetyStop."""
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

    def track(self, q_ref, qd_ref=None, qdd_ref=None) -> np.ndarray:
        """One 1 kHz control period tracking (q_ref, qd_ref, qdd_ref) (each (n,); velocities and
        accelerations default to 0, i.e. position command). Returns the applied torques (n,).

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

    def _vec(self, x, name: str) -> np.ndarray:
        """as_array(x, name, (n,)) with a fast path for finite float64 (n,) arrays (a copy)."""
        if type(x) is np.ndarray and x.shape == (self.n,) and x.dtype == np.float64:
            s = float(x.sum())
            if s - s == 0.0:  # finite sum <=> all finite (barring overflow near 1e308)
                return x.copy()
        return as_array(x, name, (self.n,))

    def _control(self, q_ref, qd_ref, qdd_ref) -> np.ndarray:
        d = self.data
        q = d.qpos[self._qadr].copy()
        self._q_safe, self._t_safe = q, d.time
        tau = self.controller.compute(q, d.qvel[self._vadr], q_ref, qd_ref, qdd_ref)
        for k in range(self.substeps):
            self._physics_step(tau, check=k == self.substeps - 1)
        return tau

    def hold(self, duration: float | None = None) -> None:
        """Hold the last valid reference position for ``duration`` seconds (whole control periods;
        default one period)."""
        steps = 1 if duration is None else max(1, int(round(float(duration) / self.control_dt)))
        q, z, _ = self._hold
        for _ in range(steps):
            self._control(q, z, z)

    def command_velocity(self, qd_cmd) -> np.ndarray:
        """Velocity command mode: integrate ``qd_cmd`` (n,) rad/s into the held reference
        (clipped to the joint limits) and track it for one control period. Returns torques."""
        try:
            qd_cmd = as_array(qd_cmd, "qd_cmd", (self.n,))
        except (ShapeError, NotFinite):
            self._hold = (self._hold[0], np.zeros(self.n), np.zeros(self.n))
            raise
        q_ref = np.clip(self._hold[0] + qd_cmd * self.control_dt, self.robot.lower, self.robot.upper)
        qd_ref = np.where((q_ref <= self.robot.lower) | (q_ref >= self.robot.upper), 0.0, qd_cmd)
        self._hold = (q_ref, np.zeros(self.n), np.zeros(self.n))
        return self._control(q_ref, qd_ref, np.zeros(self.n))

    def run_trajectory(self, t, q=None, qd=None, qdd=None, *, reset: bool = True, record_ft: bool = True,
                       distance_every: int = 10, stop_on_contact: bool = False) -> TrackingLog:
        """Track a joint trajectory with the controller at 1 kHz and log the result.

        Args:
            t: (N,) strictly increasing times (s), or a trajectory object with ``t``, ``q``,
                ``qd``, ``qdd`` attributes (``robointel.io.trajectory.Trajectory``).
            q: (N, n) joint positions within the limits; ``qd``, ``qdd`` (N, n) optional. The
                reference is resampled on the 1 kHz grid: cubic Hermite on (q, qd) when qd is
                given (qdd linearly interpolated, or from the Hermite spline), else a
                not-a-knot cubic spline through q and its derivatives.
            reset: start from rest at q[0] (else from the current state).
            record_ft: log the F/T wrench each period.
            distance_every: evaluate the robot-obstacle distance every this many periods.
            stop_on_contact: stop at the first contact with the environment.

        Raises:
            ShapeError, NotFinite, LimitViolation, InvalidInput: bad trajectory (nothing runs).
        """
        if q is None and hasattr(t, "t") and hasattr(t, "q"):
            t, q, qd, qdd = t.t, t.q, getattr(t, "qd", None), getattr(t, "qdd", None)
        if q is None:
            raise InvalidInput("run_trajectory needs q (N, n) or a trajectory object", value=t)
        t = as_array(t, "t", (None,))
        N = len(t)
        if N < 2:
            raise InvalidInput("a trajectory needs at least 2 samples", value=t)
        if np.any(np.diff(t) <= 0):
            raise InvalidInput("t must be strictly increasing", value=t)
        q = as_array(q, "q", (N, self.n))
        if np.any(q < self.robot.lower - 1e-6) or np.any(q > self.robot.upper + 1e-6):
            k = int(np.flatnonzero(np.any((q < self.robot.lower - 1e-6) | (q > self.robot.upper + 1e-6), axis=1))[0])
            check_limits(q[k], self.robot.lower, self.robot.upper, self.robot.joint_names, f"q[{k}]", tol=1e-6)
        qd = None if qd is None else as_array(qd, "qd", (N, self.n))
        qdd = None if qdd is None else as_array(qdd, "qdd", (N, self.n))
        tg = np.arange(t[0], t[-1] + 0.5 * self.control_dt, self.control_dt)
        tg = tg[tg <= t[-1] + 1e-12]
        if qd is not None:
            sp = CubicHermiteSpline(t, q, qd)
            Q, QD = sp(tg), sp(tg, 1)
            QDD = (np.stack([np.interp(tg, t, qdd[:, j]) for j in range(self.n)], axis=1)
                   if qdd is not None else sp(tg, 2))
        else:
            sp = CubicSpline(t, q)
            Q, QD = sp(tg), sp(tg, 1)
            QDD = (np.stack([np.interp(tg, t, qdd[:, j]) for j in range(self.n)], axis=1)
                   if qdd is not None else sp(tg, 2))
        Q = np.clip(Q, self.robot.lower, self.robot.upper)
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

    # ------------------------------------------------------------------ sensing and interaction
    def ft_reading(self, noise=None, bias=None, *, frame: str = "sensor") -> np.ndarray:
        """The F/T wrench [f (N); m (N m)] exerted by the tool on the sensor, (6,).

        ``frame="sensor"`` (the flange frame) or ``"world"`` (same wrench, axes of the world
        frame, torque still about the sensor origin). ``noise`` (std, scalar or (6,)) and ``bias``
        (6,) override the :class:`FTSensor` configuration for this reading. The value is the one
        computed in the last physics step.
        """
        if not self._has_ft:
            raise InvalidInput("this workcell has no F/T sensor; build it with ft_sensor=True")
        w = -self.data.sensordata[self._ft_adr:self._ft_adr + 6].copy()
        cfg = self.ft_config
        b = cfg.bias if bias is None else as_array(bias, "bias", (6,))
        s = cfg.noise_std if noise is None else np.broadcast_to(as_array(noise, "noise"), (6,))
        w = w + b
        if np.any(s > 0):
            w = w + s * cfg.rng.standard_normal(6)
        if frame == "world":
            R = self.data.site_xmat[self._site_id].reshape(3, 3)
            return np.concatenate([R @ w[:3], R @ w[3:]])
        if frame != "sensor":
            raise InvalidInput(f"frame must be 'sensor' or 'world', got {frame!r}", value=frame)
        return w

    def sensor_pose(self) -> np.ndarray:
        """4x4 world pose of the F/T sensor frame."""
        if not self._has_ft:
            raise InvalidInput("this workcell has no F/T sensor")
        T = np.eye(4)
        T[:3, :3] = self.data.site_xmat[self._site_id].reshape(3, 3)
        T[:3, 3] = self.data.site_xpos[self._site_id]
        return T

    def apply_wrench(self, force, torque=(0.0, 0.0, 0.0), point=None, body: str | None = None) -> None:
        """Apply a persistent external wrench (the human's hand) until :meth:`clear_wrench`.

        Args:
            force: (3,) N, world frame.
            torque: (3,) N m, world frame (a pure couple).
            point: (3,) world point where the force acts at the time of the call; it then moves
                with the body. Default: the body frame origin.
            body: MuJoCo body name; default the tool after the F/T sensor (so the sensor feels the
                wrench; use ``"link_6"`` to push the flange link before the sensor).
        """
        f = as_array(force, "force", (3,))
        tq = as_array(torque, "torque", (3,))
        name = TOOL_BODY if body is None else body
        bid = self._body_id(name)
        d = self.data
        R = d.xmat[bid].reshape(3, 3)
        p = d.xpos[bid].copy() if point is None else as_array(point, "point", (3,))
        self._wrench = (bid, f.copy(), tq.copy(), R.T @ (p - d.xpos[bid]))
        self._apply_wrench_now()

    def clear_wrench(self) -> None:
        """Remove the external wrench."""
        self._wrench = None
        self.data.xfrc_applied[:] = 0

    def _apply_wrench_now(self) -> None:
        bid, f, tq, p_local = self._wrench
        d = self.data
        p = d.xmat[bid].reshape(3, 3) @ p_local + d.xpos[bid]
        d.xfrc_applied[bid, :3] = f
        d.xfrc_applied[bid, 3:] = tq + np.cross(p - d.xipos[bid], f)

    def _body_id(self, name: str) -> int:
        m = self.model
        for cand in (name, OBSTACLE_PREFIX + name, OBJECT_PREFIX + name):
            i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, cand)
            if i >= 0:
                return i
        raise InvalidInput(f"no body {name!r}; bodies: {self._body_names}", value=name)

    def body_pose(self, name: str) -> np.ndarray:
        """4x4 world pose of a MuJoCo body (robot links, ``"tool"``, obstacles and objects by
        their names)."""
        i = self._body_id(name)
        T = np.eye(4)
        T[:3, :3] = self.data.xmat[i].reshape(3, 3)
        T[:3, 3] = self.data.xpos[i]
        return T

    def _contact_kind(self, g: int) -> str:
        n = self._geom_names[g]
        if self._geom_robot[g]:
            return "self"
        if n.startswith(OBSTACLE_PREFIX):
            return "obstacle"
        if n.startswith(OBJECT_PREFIX):
            return "object"
        if n in ("table", "floor"):
            return n
        return "world"

    def contacts(self) -> list[Contact]:
        """Current contacts with at least one robot geom (the robot geom first)."""
        out = []
        d = self.data
        f6 = np.zeros(6)
        for i in range(d.ncon):
            c = d.contact[i]
            g1, g2 = int(c.geom1), int(c.geom2)
            r1, r2 = self._geom_robot[g1], self._geom_robot[g2]
            if not (r1 or r2):
                continue
            normal = np.array(c.frame[:3])
            # mj_contactForce: force of geom1 on geom2 in the contact frame (rows of c.frame)
            mujoco.mj_contactForce(self.model, d, i, f6)
            f_on_2 = np.asarray(c.frame).reshape(3, 3).T @ f6[:3]
            force = -f_on_2
            if not r1:
                g1, g2, normal, force = g2, g1, -normal, f_on_2
            out.append(Contact(self._geom_names[g1], self._geom_names[g2],
                               self._body_names[self.model.geom_bodyid[g1]],
                               self._body_names[self.model.geom_bodyid[g2]], self._contact_kind(g2),
                               float(c.dist), np.array(c.pos), normal, force))
        return out

    def _environment_contact_count(self) -> int:
        d = self.data
        if d.ncon == 0:
            return 0
        g1 = d.contact.geom1[: d.ncon]
        g2 = d.contact.geom2[: d.ncon]
        r1, r2 = self._geom_robot[g1], self._geom_robot[g2]
        objs = np.array([self._geom_names[g].startswith(OBJECT_PREFIX) for g in np.concatenate([g1, g2])])
        obj = objs[: d.ncon] | objs[d.ncon:]
        return int(np.count_nonzero((r1 | r2) & ~obj))

    def obstacle_distance(self, distmax: float = 1.0) -> tuple[float, str | None, str | None]:
        """Minimum signed distance (m) between robot geoms and obstacle geoms, with the two geom
        names (``inf``, None, None without obstacles or beyond ``distmax``)."""
        if len(self._obstacle_geoms) == 0:
            return float("inf"), None, None
        m, d = self.model, self.data
        rg, og = self._robot_geoms, self._obstacle_geoms
        centre = np.linalg.norm(d.geom_xpos[rg][:, None] - d.geom_xpos[og][None], axis=2)
        gap = centre - m.geom_rbound[rg][:, None] - m.geom_rbound[og][None]
        best, pair = float("inf"), (None, None)
        for i, j in zip(*np.nonzero(gap < distmax)):
            dd = mujoco.mj_geomDistance(m, d, int(rg[i]), int(og[j]), distmax, None)
            if dd < best:
                best, pair = dd, (self._geom_names[rg[i]], self._geom_names[og[j]])
        return best, pair[0], pair[1]

    def grasp(self, name: str) -> None:
        """Rigidly attach object ``name`` to the tool where it is now (a MuJoCo weld; an idealised
        grasp). Its mass is then carried by the arm and felt by the F/T sensor; the controller's
        feed-forward does not know it (the integral takes it up)."""
        eq = self._object_eq(name)
        m, d = self.model, self.data
        Tt, To = self.body_pose(TOOL_BODY), self.body_pose(name)
        Tr = np.linalg.inv(Tt) @ To  # object pose in the tool frame
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(Tr[:3, :3]).reshape(9))
        m.eq_data[eq, 0:3] = 0.0
        m.eq_data[eq, 3:6] = Tr[:3, 3]
        m.eq_data[eq, 6:10] = quat
        d.eq_active[eq] = 1

    def release(self, name: str) -> None:
        """Detach an object attached by :meth:`grasp`."""
        self.data.eq_active[self._object_eq(name)] = 0

    def grasped(self) -> list[str]:
        """Names of the objects currently attached to the tool."""
        return [n for n in self.info["objects"] if self.data.eq_active[self._object_eq(n)]]

    def _object_eq(self, name: str) -> int:
        if name not in self.info["objects"]:
            raise InvalidInput(f"no object {name!r}; objects: {self.info['objects']}", value=name)
        return int(mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_EQUALITY, OBJECT_PREFIX + name))

    # ------------------------------------------------------------------ scene edits
    @property
    def obstacle_names(self) -> list[str]:
        return list(self.info["obstacles"])

    def add_obstacle(self, shape) -> str:
        """Add a ``robointel.geometry`` shape (recompiles the model, keeps the state). Returns
        its name."""
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

    def set_obstacle_pose(self, name: str, position, rotation=None) -> None:
        """Move an obstacle (its reference point: centre / axis midpoint) to ``position`` (3,)
        with optional 3x3 ``rotation`` (world frame). Takes effect immediately (moving obstacles)."""
        if name not in self._mocap:
            raise InvalidInput(f"no obstacle {name!r}; obstacles: {self.obstacle_names}", value=name)
        i = self._mocap[name]
        self.data.mocap_pos[i] = as_array(position, "position", (3,))
        if rotation is not None:
            R = as_array(rotation, "rotation", (3, 3))
            if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
                raise InvalidInput("rotation must be a proper rotation matrix", value=rotation)
            mujoco.mju_mat2Quat(self.data.mocap_quat[i], R.reshape(9))
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_collision(self.model, self.data)

    def snapshot(self) -> dict:
        """The full simulation state (MuJoCo state, controller integral, hold reference, applied
        wrench, grasps) for :meth:`restore` (e.g. to roll out alternatives from one state)."""
        s = self._save_state()
        s["act"] = self.data.act.copy()
        s["qacc_warmstart"] = self.data.qacc_warmstart.copy()
        c = self.controller
        s["controller"] = (c.integral.copy(), c.saturated.copy(), c.last_tau.copy())
        s["hold"] = tuple(x.copy() for x in self._hold)
        s["wrench"] = None if self._wrench is None else (self._wrench[0],) + tuple(x.copy() for x in self._wrench[1:])
        s["nbody"] = self.model.nbody
        return s

    def restore(self, snapshot: dict) -> None:
        """Return to a :meth:`snapshot` of this workcell (same scene).

        Raises:
            InvalidInput: the snapshot is from another scene.
        """
        if not isinstance(snapshot, dict) or snapshot.get("nbody") != self.model.nbody \
                or snapshot["qpos"].shape != self.data.qpos.shape:
            raise InvalidInput("the snapshot does not belong to this workcell's scene", value=None)
        self._restore_state(snapshot)
        self.data.act[:] = snapshot["act"]
        self.data.qacc_warmstart[:] = snapshot["qacc_warmstart"]
        c = self.controller
        c.integral[:], c.saturated[:], c.last_tau = (snapshot["controller"][0], snapshot["controller"][1],
                                                     snapshot["controller"][2].copy())
        self._hold = tuple(x.copy() for x in snapshot["hold"])
        self._wrench = snapshot["wrench"]
        self.data.xfrc_applied[:] = 0
        if self._wrench is not None:
            self._apply_wrench_now()

    def _save_state(self) -> dict:
        d = self.data
        return {"qpos": d.qpos.copy(), "qvel": d.qvel.copy(), "time": d.time, "mocap_pos": d.mocap_pos.copy(),
                "mocap_quat": d.mocap_quat.copy(), "ctrl": d.ctrl.copy(), "eq_active": d.eq_active.copy(),
                "eq_data": self.model.eq_data.copy()}

    def _restore_state(self, s: dict) -> None:
        d = self.data
        d.qpos[:] = s["qpos"]
        d.qvel[:] = s["qvel"]
        d.time = s["time"]
        k = len(s["mocap_pos"])
        d.mocap_pos[:k] = s["mocap_pos"]
        d.mocap_quat[:k] = s["mocap_quat"]
        d.ctrl[:] = s["ctrl"]
        k = len(s["eq_active"])  # objects come before nothing else with equalities: same order
        d.eq_active[:k] = s["eq_active"]
        self.model.eq_data[:k] = s["eq_data"]
        mujoco.mj_forward(self.model, d)
        self._warn0 = self._bad_count()

    # ------------------------------------------------------------------ rendering
    def render(self, path=None, *, width: int = 640, height: int = 480, camera: dict | None = None):
        """Render the scene offscreen to an (h, w, 3) uint8 image, saved as PNG when ``path``.

        Raises:
            RobointelError: no offscreen OpenGL (EGL/OSMesa) available, with the reason.
        """
        from robointel.sim.render import render

        return render(self, path, width=width, height=height, camera=camera)

    def render_frames(self, qs, path=None, *, width: int = 480, height: int = 360, camera: dict | None = None,
                      columns: int | None = None):
        """Render robot configurations ``qs`` ((k, n) or full qpos vectors) into one montage
        image (see :func:`robointel.sim.render.render_frames`)."""
        from robointel.sim.render import render_frames

        return render_frames(self, qs, path, width=width, height=height, camera=camera, columns=columns)

    def __repr__(self) -> str:
        return (f"Workcell({self.robot.name!r}, obstacles={self.obstacle_names}, objects={self.info['objects']}, "
                f"payload={self.payload is not None}, t={self.time:.3f}s)")
