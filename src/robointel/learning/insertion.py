"""Simulated remote lead-through teaching (RLTT) of a tight peg-in-hole insertion (Sec. 5.5).

Three parts, all in MuJoCo:

1. :class:`PegHole` - the task: a round peg (hemispherical tip) and a hole whose diametral clearance
   is ``clearance`` (default 30 um, the dissertation's H7/h7 fit was under 30 um). The hole is
   built from primitive geoms (a ring of ``n_sides`` boxes whose inner faces are tangent to the hole
   circle, and a bottom plate): a hole mesh would collide as its convex hull. Contacts are stiff
   (1 ms step, solref time constant 2 ms, solimp width 5 um below the 15 um radial gap, elliptic
   cones, zero margins); :func:`press_test` proves the physics honest: a peg with interference does
   not go in.
2. :func:`demonstrate` - a scripted person holding the hand-held demonstration device (a free body with
   the F/T sensor and the peg, :mod:`robointel.learning.hdd`) performs approach, rotation, insertion
   and completion with human-like variation (speed changes, tremor, different approach tilts,
   occasional hesitation), reacting to the felt wrench during insertion; recorded at 100 Hz with
   ground-truth phase labels.
3. :class:`RobotPegHole` - the LR Mate 200iD/7L (the sim module's MuJoCo model of the robot core's
   URDF, reflected rotor inertia (armature) included) carrying the same tool; trials start from
   randomised pose errors (lateral +/-1 mm, tilt up to 3 deg). The reproduction controller is
   :meth:`RobotPegHole.run_impedance`: a torque-level Cartesian impedance (:class:`CartesianImpedance`,
   tau = J^T W + h(q, qd) + friction, no joint servo) about the tip sphere's centre, stiff in rotation,
   soft laterally, force-limited damper along the tool axis. It first measures the hole axis by
   touching the hole part's top face at three points (F/T sensor + the robot's kinematics), rotates
   about the sphere centre onto that axis, then the learned skill model (:class:`InsertionSkill`, GMR
   wrench -> tool velocity, (5.14)-(5.17)) moves the lateral equilibrium and sets the axial speed.
   :meth:`RobotPegHole.run` keeps the earlier controllers: the position-only baseline (stiff joint
   servo, straight line) and the admittance-on-servo hybrid controller. Success = seated within 1 mm of
   the bottom, wall penetration below half the clearance, within the time limit.

Why the probe: a 25.4 mm cylinder with 30 um clearance passes the rim only when its tilt is below
about c / (mu D) ~ 0.3 deg; with more, the first cylinder contact makes a two-point contact whose
normals pass within ~1 mm of the sphere centre, so friction locks the rotation (Whitney's wedge;
measured: thousands of newtons of pinch). The human's light, loose grip gets through; the arm (0.3 kg m^2
of rotational inertia about the tip, joint friction) does not, even with a rotational stiffness of
1 N m/rad and zero joint friction (tried). The tilt must therefore be removed before the cylinder
reaches the rim, and the F/T torque gives no usable tilt signal while the sphere alone is in contact
(its contact normals pass through the sphere centre).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

import mujoco
import numpy as np

from robointel.errors import InvalidInput
from robointel.learning.demonstration import Demonstration
from robointel.learning.gmr import GaussianMixtureRegression
from robointel.learning.hdd import GRAVITY, Contact, Tool, ToolFT, add_tool_sensors, cross

PHASES = ("approach", "rotation", "insertion", "completion")
#: tool frame in the flange frame: the tool axis (z) is the flange's approach axis (x)
R_FLANGE_TOOL = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
#: tool pointing straight down in the world
R_DOWN = np.diag([1.0, -1.0, -1.0])
#: reflected motor-rotor inertia of the LR Mate's joints (kg m^2), in MuJoCo and in the controller's
#: model: gear-reduced rotors dominate the wrist's tiny link inertias (without it the wrist is a
#: few grams of effective mass and MuJoCo's soft contacts yield under the joint servo's force)
ARMATURE = (0.5, 0.5, 0.2, 0.05, 0.05, 0.02)
PERCEPTION = (0, 1, 2, 3, 4)  # fx fy fz tx ty (tool frame)
POLICY = ("vx", "vy", "vz", "wx", "wy")  # tool-frame linear (m/s) and angular (rad/s) velocity


def _rot(axis, angle) -> np.ndarray:
    """Rotation matrix of ``angle`` (rad) about ``axis`` (3,)."""
    q = np.empty(4)
    mujoco.mju_axisAngle2Quat(q, np.asarray(axis, float), float(angle))
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, q)
    return R.reshape(3, 3)


def _exp(w) -> np.ndarray:
    """Rotation matrix of the rotation vector ``w`` (3,)."""
    a = float(np.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]))
    # mju_axisAngle2Quat expects a unit axis: passing w itself rotated by |w|^2, not |w|
    return np.eye(3) if a < 1e-15 else _rot(np.asarray(w, float) / a, a)


def _log(R) -> np.ndarray:
    """Rotation vector of R (3,)."""
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R).ravel())
    v = np.empty(3)
    mujoco.mju_quat2Vel(v, q, 1.0)
    return v


@dataclass(frozen=True)
class PegHole:
    """The peg-hole task. Lengths in metres; ``clearance`` is diametral (hole minus peg diameter).

    Args:
        peg_radius: 12.7 mm (a 25.4 mm peg, as in the dissertation).
        clearance: diametral clearance (m), <= 40 um for a tight fit.
        depth: hole depth (m).
        top: world position of the hole's top centre (m), on a pedestal on the table.
        n_sides: boxes in the ring forming the hole wall.
        contact: stiff contact parameters.
    """

    peg_radius: float = 0.0127
    clearance: float = 30e-6
    depth: float = 0.03
    top: tuple[float, float, float] = (0.60, 0.0, 0.20)
    n_sides: int = 24
    wall: float = 0.012
    peg_length: float = 0.06
    contact: Contact = field(default_factory=Contact)

    def __post_init__(self) -> None:
        if not (0 < self.clearance < 0.002):
            raise InvalidInput(f"clearance must be in (0, 2 mm), got {self.clearance!r}", value=self.clearance)
        if self.contact.solimp[2] >= 0.5 * self.clearance:
            raise InvalidInput("the contact impedance width must be below the radial clearance", value=self.contact)

    @property
    def hole_radius(self) -> float:
        return self.peg_radius + 0.5 * self.clearance

    @property
    def bottom_z(self) -> float:
        return self.top[2] - self.depth

    def tool(self, *, interference: float = 0.0) -> Tool:
        """The peg; with ``interference`` > 0 (m, diametral) the peg is that much larger than the hole."""
        r = self.hole_radius + 0.5 * interference if interference > 0 else self.peg_radius
        return Tool(radius=r, length=self.peg_length)

    def add_hole(self, spec: mujoco.MjSpec, *, contype: int = 2, conaffinity: int = 3) -> None:
        """Add the hole (ring of boxes ``hole/wall_k``, ``hole/bottom``) and its pedestal to the world."""
        wb = spec.worldbody
        cx, cy, top = self.top
        R, t, n, D = self.hole_radius, self.wall, self.n_sides, self.depth
        width = 2 * (R + t) * np.tan(np.pi / n) * 1.05
        for k in range(n):
            th = 2 * np.pi * k / n
            q = np.empty(4)
            mujoco.mju_axisAngle2Quat(q, np.array([0.0, 0.0, 1.0]), th)
            g = wb.add_geom(name=f"hole/wall_{k}", type=mujoco.mjtGeom.mjGEOM_BOX, size=[t / 2, width / 2, D / 2],
                            pos=[cx + (R + t / 2) * np.cos(th), cy + (R + t / 2) * np.sin(th), top - D / 2], quat=q,
                            rgba=[0.55, 0.6, 0.7, 1], contype=contype, conaffinity=conaffinity)
            self.contact.apply(g)
        g = wb.add_geom(name="hole/bottom", type=mujoco.mjtGeom.mjGEOM_BOX, size=[R + t, R + t, 0.005],
                        pos=[cx, cy, top - D - 0.005], rgba=[0.5, 0.55, 0.65, 1], contype=contype, conaffinity=conaffinity)
        self.contact.apply(g)
        ph = top - D - 0.01
        if ph > 0:
            g = wb.add_geom(name="hole/pedestal", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.04, 0.04, ph / 2],
                            pos=[cx, cy, ph / 2], rgba=[0.4, 0.4, 0.45, 1], contype=contype, conaffinity=conaffinity)
            self.contact.apply(g)

    def build(self, spec: mujoco.MjSpec) -> None:
        """Add the task's environment (the hole) to a spec."""
        self.add_hole(spec)

    def pre_insert_pose(self, tool: Tool, height: float = 0.003) -> np.ndarray:
        """Tool pose (4x4) with the tool pointing down on the hole axis, tip ``height`` above the top."""
        T = np.eye(4)
        T[:3, :3] = R_DOWN
        T[:3, 3] = np.array(self.top) + np.array([0, 0, height + tool.tip])
        return T


def _wall_ids(model) -> np.ndarray:
    return np.array([g for g in range(model.ngeom) if (model.geom(g).name or "").startswith("hole/wall")])


def _tip(T: np.ndarray, tool: Tool) -> np.ndarray:
    return T[:3, 3] + T[:3, 2] * tool.tip


def _wall_penetration(data, walls_lo: int, walls_hi: int, peg: int) -> float:
    n = data.ncon
    if n == 0:
        return 0.0
    g = data.contact.geom[:n]
    dist = data.contact.dist[:n]
    other = np.where(g[:, 0] == peg, g[:, 1], np.where(g[:, 1] == peg, g[:, 0], -1))
    m = (other >= walls_lo) & (other <= walls_hi)
    return float(max(0.0, -dist[m].min())) if np.any(m) else 0.0


# ------------------------------------------------------------------------------ the HDD scene
class HDDScene:
    """The hand-held demonstration device over the hole: a free handle (mass ``handle_mass``) with
    the tool and F/T sensor, on the table. The person pushes the handle with :meth:`step`."""

    def __init__(self, task: PegHole, tool: Tool | None = None, *, handle_mass: float = 0.4) -> None:
        self.task = task
        self.tool = tool or task.tool()
        spec = mujoco.MjSpec()
        spec.option.timestep = 0.001
        spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        spec.option.gravity = GRAVITY
        spec.worldbody.add_geom(name="table", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1, 1, 0.1],
                                rgba=[0.55, 0.42, 0.3, 1], contype=2, conaffinity=3)
        spec.worldbody.add_light(name="light", pos=[0.5, -1.0, 2.5], dir=[-0.2, 0.4, -1.0])
        task.build(spec)
        h = spec.worldbody.add_body(name="handle", pos=[0, 0, 0.5])
        h.add_freejoint(name="handle")
        h.mass = handle_mass
        h.inertia = [2e-4, 2e-4, 2e-4]
        h.explicitinertial = True
        h.add_geom(name="handle/grip", type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.015, 0.04, 0],
                   pos=[0, 0, -0.05], rgba=[0.2, 0.2, 0.25, 1], contype=0, conaffinity=0, mass=0, density=0)
        self.tool.add_to(h, task.contact, contype=1, conaffinity=2)
        add_tool_sensors(spec)
        self.spec = spec
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self._hid = self.model.body("handle").id
        self.mass = float(self.model.body_subtreemass[self._hid])
        walls = _wall_ids(self.model)
        self._walls = (int(walls.min()), int(walls.max())) if len(walls) else (-1, -2)
        self._peg = self.model.geom(self.tool.name + "/peg").id
        self.ft = ToolFT(self.model, self.tool)

    def reset(self, T_tool: np.ndarray) -> None:
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:3] = T_tool[:3, 3]
        q = np.empty(4)
        mujoco.mju_mat2Quat(q, np.ascontiguousarray(T_tool[:3, :3]).ravel())
        self.data.qpos[3:7] = q
        mujoco.mj_forward(self.model, self.data)

    def pose(self) -> np.ndarray:
        return self.ft.pose(self.data)

    def wrench(self) -> np.ndarray:
        return self.ft.wrench(self.data)

    def twist(self) -> tuple[np.ndarray, np.ndarray]:
        """World linear velocity of the tool origin and angular velocity (3,), (3,)."""
        v = self.data.qvel
        return v[:3].copy(), self.data.xmat[self._hid].reshape(3, 3) @ v[3:6]

    def step(self, force: np.ndarray, torque: np.ndarray) -> None:
        """One 1 ms step with the hand's force (N) and torque (N m), world frame, at the tool origin."""
        d = self.data
        p = d.xpos[self._hid]
        d.xfrc_applied[self._hid, :3] = force
        d.xfrc_applied[self._hid, 3:] = torque + cross(p - d.xipos[self._hid], force)
        mujoco.mj_step(self.model, d)

    def wall_penetration(self) -> float:
        return _wall_penetration(self.data, self._walls[0], self._walls[1], self._peg)


# ------------------------------------------------------------------------------ the person
@dataclass(frozen=True)
class Demonstrator:
    """A scripted person: hand impedance, corrective reflexes and their variation between demonstrations."""

    stiffness: float = 800.0      # N/m
    damping: float = 60.0         # N s/m
    rot_stiffness: float = 6.0    # N m/rad (firm grip: approach, rotation)
    grip_rot_stiffness: float = 0.4  # N m/rad (loose grip while inserting)
    grip_lateral_stiffness: float = 100.0  # N/m across the tool axis while inserting
    rot_damping: float = 0.2      # N m s/rad
    record_dt: float = 0.01       # s (100 Hz)
    force_noise: float = 0.05     # N, sensor noise std
    torque_noise: float = 0.002   # N m
    hesitation_prob: float = 0.35
    insertion_timeout: float = 8.0


def _minjerk(s):
    s = np.clip(s, 0.0, 1.0)
    return s ** 3 * (10 - 15 * s + 6 * s * s)


def _trapezoid(s, ramp: float = 0.1):
    """Progress (0..1) of a trapezoidal velocity profile with acceleration ramps of ``ramp`` of the
    duration: a deliberate hand motion that starts and stops within ~0.1-0.2 s."""
    s = np.clip(s, 0.0, 1.0)
    vmax = 1.0 / (1.0 - ramp)
    if s < ramp:
        return 0.5 * vmax * s * s / ramp
    if s > 1 - ramp:
        return 1.0 - 0.5 * vmax * (1 - s) ** 2 / ramp
    return 0.5 * vmax * ramp + vmax * (s - ramp)


def demonstrate(task: PegHole, rng: np.random.Generator, *, scene: HDDScene | None = None,
                person: Demonstrator = Demonstrator(), name: str = "") -> Demonstration:
    """One human-like demonstration with the HDD: approach, rotation, insertion, completion.

    Returns a :class:`Demonstration` at 100 Hz with ground-truth ``labels`` (indices into
    :data:`PHASES`) and ``meta`` (phase times, start errors, whether the peg was seated).
    """
    scene = scene or HDDScene(task)
    tool = scene.tool
    dt = float(scene.model.opt.timestep)
    top = np.array(task.top)
    # --- randomised script
    tilt0 = np.radians(rng.uniform(6, 14))
    ax0 = rng.normal(size=2)
    ax0 = np.array([*ax0 / np.linalg.norm(ax0), 0.0])
    R_start = _rot(ax0, tilt0) @ R_DOWN
    tilt_r = np.radians(rng.uniform(0.5, 2.5))
    axr = rng.normal(size=2)
    axr = np.array([*axr / np.linalg.norm(axr), 0.0])
    R_rot = _rot(axr, tilt_r) @ R_DOWN
    lat_err = rng.uniform(-1e-3, 1e-3, 2)
    entry_tip = top + np.array([lat_err[0], lat_err[1], rng.uniform(0.002, 0.004)])
    start_tip = top + np.array([*rng.uniform(0.04, 0.08, 2) * rng.choice([-1, 1], 2), rng.uniform(0.05, 0.09)])
    T_a, T_r, T_c = rng.uniform(1.3, 2.0), rng.uniform(0.6, 1.0), rng.uniform(0.5, 0.8)
    gamma = rng.uniform(0.8, 1.25)  # speed profile
    pause = (rng.uniform(0.3, 0.7), rng.uniform(0.15, 0.4)) if rng.random() < person.hesitation_prob else None
    # reflex gains: lateral m/s per N; rotational rad/s per N m about the handle. (With 3-5 rad/s/(N m)
    # the handle rotation swings the tip into the wall and feeds the lateral force back as torque:
    # 40/60 demonstrations seated once _exp rotated by the right angle.)
    k_f, k_t = rng.uniform(0.8e-3, 1.4e-3), rng.uniform(0.3, 0.5)
    v_ins, f_lim, tau_lim = rng.uniform(0.006, 0.010), rng.uniform(6.0, 10.0), rng.uniform(0.3, 0.5)
    f_press = rng.uniform(8.0, 15.0)
    tremor_f = rng.uniform(8, 12, 3)
    tremor_a = rng.uniform(0.5e-4, 1.5e-4, 3)
    tremor_ph = rng.uniform(0, 2 * np.pi, (3, 3))

    def tip_to_origin(tip, R):
        return tip - R[:, 2] * tool.tip

    T0 = np.eye(4)
    T0[:3, :3] = R_start
    T0[:3, 3] = tip_to_origin(start_tip, R_start)
    scene.reset(T0)
    mg = np.array([0, 0, scene.mass * 9.81])

    ts, poses, wrenches, labels = [], [], [], []
    rec_every = max(1, int(round(person.record_dt / dt)))
    step = 0
    t = 0.0
    phase_t = [0.0]
    max_pen = 0.0

    k_rot = person.rot_stiffness
    k_lat = None

    def hand(p_ref, R_ref):
        nonlocal step, t, max_pen
        T = scene.pose()
        v, w = scene.twist()
        trem = tremor_a @ np.sin(2 * np.pi * tremor_f[:, None] * t + tremor_ph)
        e = p_ref + trem - T[:3, 3]
        if k_lat is not None:  # loose grip across the tool axis
            z = T[:3, 2]
            e = (e @ z) * z + (k_lat / person.stiffness) * (e - (e @ z) * z)
        f = person.stiffness * e - person.damping * v + mg
        tq = k_rot * _log(R_ref @ T[:3, :3].T) - person.rot_damping * w
        scene.step(f, tq)
        step += 1
        t = step * dt
        max_pen = max(max_pen, scene.wall_penetration())

    def record(label):
        if step % rec_every == 0:
            ts.append(t)
            poses.append(scene.pose())
            w = scene.wrench()
            w[:3] += person.force_noise * rng.standard_normal(3)
            w[3:] += person.torque_noise * rng.standard_normal(3)
            wrenches.append(w)
            labels.append(label)

    # approach: min-jerk with a speed profile and an optional pause
    n_a = int(T_a / dt)
    n_pause = int(pause[1] / dt) if pause else 0
    k = 0
    paused = 0
    while k < n_a or paused < n_pause:
        if pause and k >= int(pause[0] * n_a) and paused < n_pause:
            paused += 1
        else:
            k += 1
        s = _trapezoid((k / n_a) ** gamma)
        tip = start_tip + s * (entry_tip - start_tip)
        R = R_start  # orientation kept while approaching
        hand(tip_to_origin(tip, R), R)
        record(0)
    phase_t.append(t)
    # rotation about the tip: from the approach tilt to a small residual tilt
    rv = _log(R_rot @ R_start.T)
    n_r = int(T_r / dt)
    for k in range(1, n_r + 1):
        R = _exp(rv * _trapezoid(k / n_r, 0.15)) @ R_start
        hand(tip_to_origin(entry_tip, R), R)
        record(1)
    phase_t.append(t)
    # insertion: push along the tool axis, comply with the felt wrench (the skill to learn)
    R_ref = R_rot.copy()
    p_ref = tip_to_origin(entry_tip, R_ref)
    t_ins = t
    k_rot = person.grip_rot_stiffness
    k_lat = person.grip_lateral_stiffness
    while True:
        w = scene.wrench()
        f_push = max(0.0, -w[2])
        slow = np.clip(1 - f_push / f_lim - np.hypot(w[3], w[4]) / tau_lim, 0.0, 1.0)
        v_tool = np.array([k_f * w[0], k_f * w[1], v_ins * slow])
        om_tool = np.array([k_t * w[3], k_t * w[4], 0.0])
        p_ref = p_ref + R_ref @ v_tool * dt
        # the hand leads the tool by at most the push force it is willing to apply
        lead = R_ref.T @ (p_ref - scene.pose()[:3, 3])
        if lead[2] > f_lim / person.stiffness:
            p_ref = p_ref - R_ref[:, 2] * (lead[2] - f_lim / person.stiffness)
        R_ref = R_ref @ _exp(om_tool * dt)
        hand(p_ref, R_ref)
        record(2)
        if _tip(scene.pose(), tool)[2] - task.bottom_z < 3e-4 or t - t_ins > person.insertion_timeout:
            break
    phase_t.append(t)
    # completion: a final press, then release
    T = scene.pose()
    p_hold, R_hold = T[:3, 3].copy(), T[:3, :3].copy()
    n_c = int(T_c / dt)
    R_hold = scene.pose()[:3, :3].copy()
    for k in range(1, n_c + 1):
        s = k / n_c
        push = f_press * np.sin(np.pi * min(1.0, 1.6 * s)) if s < 1 / 1.6 else 0.0
        hand(p_hold + R_hold[:, 2] * push / person.stiffness, R_hold)
        record(3)
    seated = _tip(scene.pose(), tool)[2] - task.bottom_z < 1e-3
    meta = {"phase_times": phase_t[1:], "seated": bool(seated), "max_wall_penetration": max_pen,
            "lateral_error": lat_err.tolist(), "residual_tilt": float(tilt_r), "approach_tilt": float(tilt0),
            "hesitation": pause is not None}
    return Demonstration.create(np.array(ts), np.array(poses), np.array(wrenches), np.array(labels),
                                action_names=PHASES, device="hdd", name=name, meta=meta)


# ------------------------------------------------------------------------------ the skill
def tool_velocities(demo: Demonstration, *, smooth: int = 5) -> np.ndarray:
    """Tool-frame twist of a demonstration (N, 6) [v (m/s); w (rad/s)] by central differences of the
    recorded poses (moving average of ``smooth`` samples)."""
    t, T = demo.t, demo.pose
    n = len(t)
    p = T[:, :3, 3]
    v = np.gradient(p, t, axis=0)
    w = np.zeros((n, 3))
    for k in range(n):
        a, b = max(k - 1, 0), min(k + 1, n - 1)
        w[k] = _log(T[b, :3, :3] @ T[a, :3, :3].T) / (t[b] - t[a])
    tw = np.concatenate([np.einsum("nji,nj->ni", T[:, :3, :3], v), np.einsum("nji,nj->ni", T[:, :3, :3], w)], 1)
    if smooth > 1:
        k = np.ones(smooth) / smooth
        pad = smooth // 2
        tp = np.pad(tw, ((pad, smooth - 1 - pad), (0, 0)), mode="edge")
        tw = np.stack([np.convolve(tp[:, i], k, mode="valid") for i in range(6)], 1)
    return tw


class InsertionSkill:
    """The insertion skill model: GMR from the felt wrench [fx, fy, fz, tx, ty] (tool frame) to the
    corrective tool velocity [vx, vy, vz, wx, wy] (tool frame), (5.14)-(5.17). Inputs and outputs
    are standardised before the mixture is fitted (k-means needs comparable scales)."""

    def __init__(self, n_components: int = 6, *, random_state: int = 0, max_samples: int = 12000) -> None:
        self.gmr = GaussianMixtureRegression(n_components, random_state=random_state)
        self.max_samples = int(max_samples)

    def fit(self, demos: Sequence[Demonstration], labels: Sequence[np.ndarray] | None = None,
            *, phase: int = PHASES.index("insertion")) -> "InsertionSkill":
        """Fit on the samples of ``phase`` (labels from the decomposition, or each demo's own labels).

        Raises:
            InvalidInput: no demonstrations or no samples of the phase.
        """
        if len(demos) == 0:
            raise InvalidInput("InsertionSkill.fit needs at least one demonstration")
        X, Y = [], []
        for i, d in enumerate(demos):
            lab = d.labels if labels is None else np.asarray(labels[i])
            if lab is None:
                raise InvalidInput(f"demonstration {i} has no labels; decompose it first")
            m = lab == phase
            tw = tool_velocities(d)
            X.append(d.wrench[m][:, list(PERCEPTION)])
            Y.append(tw[m][:, [0, 1, 2, 3, 4]])
        X, Y = np.concatenate(X), np.concatenate(Y)
        if len(X) == 0:
            raise InvalidInput(f"no samples labelled {PHASES[phase]!r} in the demonstrations")
        if len(X) > self.max_samples:  # EM cost grows with the samples; a seeded subsample suffices
            keep = np.sort(np.random.default_rng(0).choice(len(X), self.max_samples, replace=False))
            X, Y = X[keep], Y[keep]
        self.x_lo_, self.x_hi_ = np.percentile(X, 0.5, axis=0), np.percentile(X, 99.5, axis=0)
        self.y_lo_, self.y_hi_ = np.percentile(Y, 0.5, axis=0), np.percentile(Y, 99.5, axis=0)
        self.x_mean_, self.x_scale_ = X.mean(0), X.std(0) + 1e-9
        self.y_mean_, self.y_scale_ = Y.mean(0), Y.std(0) + 1e-12
        self.gmr.fit((X - self.x_mean_) / self.x_scale_, (Y - self.y_mean_) / self.y_scale_)
        self.X_, self.Y_ = X, Y
        return self

    def predict(self, wrench) -> np.ndarray:
        """Corrective tool velocity (n, 5) for wrenches (n, 6) or (6,) -> (5,). The wrench is
        saturated to the demonstrated range and so is the output: the skill does not extrapolate."""
        w = np.asarray(wrench, float)
        one = w.ndim == 1
        w = np.clip(np.atleast_2d(w)[:, list(PERCEPTION)], self.x_lo_, self.x_hi_)
        y = self.gmr.predict((w - self.x_mean_) / self.x_scale_) * self.y_scale_ + self.y_mean_
        y = np.clip(y, self.y_lo_, self.y_hi_)
        return y[0] if one else y


# ------------------------------------------------------------------------------ the robot
@dataclass
class TrialResult:
    """One reproduction: ``success``; ``seated`` (tip within 1 mm of the bottom); ``depth_error``
    final tip height above the bottom (m); ``max_penetration`` into the hole wall (m); ``time`` (s)
    to seat (or the time limit); ``max_force`` (N); ``reason``; logs ``t`` (n,), ``tip`` (n, 3),
    ``wrench`` (n, 6), ``twist`` (n, 5) at the 100 Hz skill rate."""

    success: bool
    seated: bool
    depth_error: float
    max_penetration: float
    time: float
    max_force: float
    reason: str
    t: np.ndarray
    tip: np.ndarray
    wrench: np.ndarray
    twist: np.ndarray


class RobotPegHole:
    """The LR Mate 200iD/7L with the HDD's tool at its flange over the hole, in MuJoCo.

    The robot model is :func:`robointel.sim.build_spec` (the robot core's URDF, table, motors,
    ``armature``); the hole and the tool (with its F/T sensor) are added to that spec. Two control
    schemes: :meth:`run_impedance` (the reproduction controller: torque-level Cartesian impedance,
    :class:`CartesianImpedance`, with the hole axis probed by touch and the skill model moving its
    equilibrium) and :meth:`run` (the sim module's Fig. 2.3 joint controller, PID + inverse-dynamics
    feed-forward with the tool as payload, either tracking a straight line - the position-only
    baseline - or the reference of an admittance about the tip).
    """

    def __init__(self, task: PegHole | None = None, robot=None, *, tool: Tool | None = None,
                 interference: float = 0.0, armature=ARMATURE) -> None:
        from robointel.robot import Robot
        from robointel.sim import JointController, Payload, build_spec, model_with_payload

        self.task = task or PegHole()
        self.robot = robot if robot is not None else Robot.load("lrmate200id7l")
        self.tool = tool or self.task.tool(interference=interference)
        self.armature = np.asarray(armature, float)
        spec, info = build_spec(self.robot, table=True, ft_sensor=False, armature=self.armature)
        self.task.build(spec)
        self.tool.add_to(spec.body("tool"), self.task.contact, R_body_tool=R_FLANGE_TOOL, contype=1, conaffinity=2)
        add_tool_sensors(spec)
        self.spec = spec
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.qadr = np.array([m.jnt_qposadr[m.joint(n).id] for n in self.robot.joint_names])
        self.vadr = np.array([m.jnt_dofadr[m.joint(n).id] for n in self.robot.joint_names])
        self.aid = np.array([m.actuator(n).id for n in self.robot.joint_names])
        self.ft = ToolFT(m, self.tool)
        walls = _wall_ids(m)
        self._walls = (int(walls.min()), int(walls.max())) if len(walls) else (-1, -2)
        self._peg = m.geom(self.tool.name + "/peg").id
        I_tool = np.diag([self.tool.mass * (3 * self.tool.radius ** 2 + self.tool.length ** 2) / 12] * 2
                         + [0.5 * self.tool.mass * self.tool.radius ** 2])
        payload = Payload(mass=self.tool.mass, com=R_FLANGE_TOOL @ self.tool.com,
                          inertia=R_FLANGE_TOOL @ I_tool @ R_FLANGE_TOOL.T)
        pin_model = model_with_payload(self.robot, payload)
        pin_model.armature = self.armature.copy()
        self.controller = JointController(self.robot, model=pin_model)
        self.T_flange_tool = np.eye(4)
        self.T_flange_tool[:3, :3] = R_FLANGE_TOOL
        self._q_nominal = None

    def flange_target(self, T_tool: np.ndarray) -> np.ndarray:
        return T_tool @ np.linalg.inv(self.T_flange_tool)

    def ik(self, T_tool: np.ndarray) -> np.ndarray:
        """Joint configuration placing the tool frame at ``T_tool`` (closed-form IK, elbow up)."""
        if self._q_nominal is None:
            self._q_nominal = self.robot.ik(self.flange_target(self.task.pre_insert_pose(self.tool)),
                                            q_ref=np.array([0, 0.5, -0.4, 0, -0.7, 0]))[0]
        return self.robot.ik(self.flange_target(T_tool), q_ref=self._q_nominal)[0]

    def tool_pose(self) -> np.ndarray:
        return self.ft.pose(self.data)

    def reset(self, q: np.ndarray, settle: float = 0.3) -> None:
        """Put the robot at ``q`` and hold it there for ``settle`` seconds."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self.qadr] = q
        mujoco.mj_forward(self.model, self.data)
        self.controller.reset()
        z = np.zeros(len(q))
        for _ in range(int(settle / self.model.opt.timestep)):
            self._step(q, z)

    def _step(self, q_ref, qd_ref) -> None:
        d = self.data
        tau = self.controller.compute(d.qpos[self.qadr], d.qvel[self.vadr], q_ref, qd_ref, np.zeros(len(q_ref)))
        d.ctrl[self.aid] = tau
        mujoco.mj_step(self.model, d)

    def start_pose(self, lateral, tilt_axis_angle) -> np.ndarray:
        """Pre-insertion tool pose with a pose error: ``lateral`` (2,) m in the table plane and a tilt
        (rad) about a horizontal axis at angle ``tilt_axis_angle[0]`` (rad), by ``tilt_axis_angle[1]``,
        about the tip point."""
        T = self.task.pre_insert_pose(self.tool)
        phi, tilt = tilt_axis_angle
        R = _rot([np.cos(phi), np.sin(phi), 0.0], tilt)
        tip = _tip(T, self.tool)
        T2 = np.eye(4)
        T2[:3, :3] = R @ T[:3, :3]
        T2[:3, 3] = tip - T2[:3, 2] * self.tool.tip + np.array([lateral[0], lateral[1], 0.0])
        return T2

    def run(self, policy: Callable[[np.ndarray], np.ndarray] | None, T_start: np.ndarray, *,
            time_limit: float = 10.0, gains: "AdmittanceGains | None" = None, v_nominal: float = 0.008,
            f_abort: float = 150.0, skill_dt: float = 0.01, force_noise: float = 0.05,
            torque_noise: float = 0.002, seed: int = 0) -> TrialResult:
        """One insertion from ``T_start`` (4x4 tool pose) with the stiff joint servo (the
        position-only baseline and the earlier admittance controller; the reproduction controller
        is :meth:`run_impedance`).

        With a ``policy`` (wrench (6,) in the tool frame -> tool twist [vx, vy, vz, wx, wy]) the
        robot runs the hybrid position/force controller: an admittance (virtual mass-spring-damper,
        :class:`AdmittanceGains`) about the peg tip, whose equilibrium the skill's corrective
        velocities move, while along the tool axis the skill's velocity sets a damper (so the axial
        contact force is bounded by ``axial_damping * vz``); the admittance output is the pose
        reference of the stiff PID joint servo (the usual force-control scheme of a
        position-controlled industrial robot). ``policy=None`` is the position-only baseline: the
        servo tracks a straight line along the tool axis at ``v_nominal`` with no force feedback.
        Faults (force above ``f_abort`` N) stop the trial (a safety stop: failure).
        """
        g = gains or AdmittanceGains()
        rng = np.random.default_rng(seed)
        q_ref = self.ik(T_start)
        self.reset(q_ref)
        dt = float(self.model.opt.timestep)
        n_skill = max(1, int(round(skill_dt / dt)))
        n = int(time_limit / dt)
        tool = self.tool
        T = self.ft.pose(self.data)
        # commanded tip pose (virtual body) and the equilibrium the skill moves
        back = g.center_from_tip if g.center_from_tip is not None else tool.radius
        reach = tool.tip - back  # sensor -> compliance centre along the tool axis
        x_c, R_c = T[:3, 3] + T[:3, 2] * reach, T[:3, :3].copy()
        x_0, R_0 = x_c.copy(), R_c.copy()
        v_c, w_c = np.zeros(3), np.zeros(3)
        tw = np.zeros(5)
        v_s, w_s = np.zeros(3), np.zeros(3)
        w_f = np.zeros(6)
        alpha = 1.0 - np.exp(-2 * np.pi * g.force_filter_hz * dt)
        beta = 1.0 - np.exp(-2 * np.pi * (g.torque_filter_hz or g.force_filter_hz) * dt)
        t_f = np.zeros(3)
        max_pen, max_force = 0.0, 0.0
        logs_t, logs_tip, logs_w, logs_tw = [], [], [], []
        reason, seated = "time limit", False
        bottom = self.task.bottom_z
        for k in range(n):
            T = self.ft.pose(self.data)
            w = self.ft.wrench(self.data, T[:3, :3])
            w[:3] += force_noise * rng.standard_normal(3)
            w[3:] += torque_noise * rng.standard_normal(3)
            tip = _tip(T, tool)
            fmag = float(np.sqrt(w[0] ** 2 + w[1] ** 2 + w[2] ** 2))
            max_force = max(max_force, fmag)
            if k % 10 == 0:
                logs_t.append(k * dt)
                logs_tip.append(tip)
                logs_w.append(w)
                logs_tw.append(tw.copy())
            if tip[2] - bottom <= 1e-3:
                seated, reason = True, "seated"
                break
            if fmag > f_abort:
                reason = "force limit (safety stop)"
                break
            a = R_c[:, 2]
            if policy is None:
                v_c = a * v_nominal
                w_c = np.zeros(3)
            else:
                if k % n_skill == 0:
                    tw = np.asarray(policy(w), float)
                    v_s = R_c @ np.array([tw[0], tw[1], 0.0])
                    w_s = R_c @ np.array([tw[3], tw[4], 0.0])
                # the skill moves the equilibrium and the commanded pose (velocity feed-forward) ...
                x_0 = x_0 + v_s * dt
                x_0 = x_0 + a * (a @ (x_c - x_0))  # no axial spring: the axis is force controlled
                if g.rotate:
                    R_0 = _exp(w_s * dt) @ R_0
                # ... and the admittance (virtual mass-spring-damper about the compliance centre) adds
                # the deviation driven by the low-passed environment wrench, world frame
                w_f += alpha * (w - w_f)
                f_w = T[:3, :3] @ w_f[:3]
                if g.torque_filter_hz is None:
                    t_w = T[:3, :3] @ w_f[3:] - cross(T[:3, 2] * reach, f_w)
                else:  # torque about the compliance centre from the raw wrench, then its own low-pass
                    t_f += beta * (T[:3, :3] @ w[3:] - cross(T[:3, 2] * reach, T[:3, :3] @ w[:3]) - t_f)
                    t_w = t_f
                e = x_0 - x_c
                e_lat = e - (e @ a) * a
                dv = v_c - v_s
                v_ax = a @ v_c
                v_max = g.max_axial_speed
                if g.rim_speed is not None and g.rim_zone[0] <= self.task.top[2] - tip[2] <= g.rim_zone[1]:
                    v_max = g.rim_speed  # slow while the cylinder passes the rim: the compliance has time to act
                F = f_w + g.lateral_stiffness * e_lat - g.lateral_damping * (dv - (a @ dv) * a) \
                    + a * g.axial_damping * (float(np.clip(tw[2], -v_max, v_max)) - v_ax)
                Tq = t_w + g.rot_stiffness * _log(R_0 @ R_c.T) - g.rot_damping * (w_c - w_s)
                Tq = Tq - (Tq @ a) * a  # no rotation about the tool axis
                v_c = v_c + F / g.mass * dt
                w_c = w_c + Tq / g.inertia * dt
                w_c = w_c - (w_c @ a) * a
            x_c = x_c + v_c * dt
            if g.rotate:
                R_c = _exp(w_c * dt) @ R_c
            # commanded tool pose -> flange twist -> joint reference of the PID servo
            Tf = self.robot.fk(q_ref)
            p_f = Tf[:3, 3]
            v_f = v_c + cross(w_c, p_f - x_c)
            # drift correction toward the commanded pose
            R_cmd_flange = R_c @ R_FLANGE_TOOL.T
            p_cmd_flange = x_c - R_c[:, 2] * reach
            corr = np.concatenate([50.0 * (p_cmd_flange - p_f), 50.0 * _log(R_cmd_flange @ Tf[:3, :3].T)])
            qd_ref = np.linalg.solve(self.robot.jacobian(q_ref), np.concatenate([v_f, w_c]) + corr)
            q_ref = q_ref + qd_ref * dt
            self._step(q_ref, qd_ref)
            max_pen = max(max_pen, _wall_penetration(self.data, self._walls[0], self._walls[1], self._peg))
        depth = float(_tip(self.ft.pose(self.data), self.tool)[2] - bottom)
        ok_pen = max_pen < 0.5 * self.task.clearance
        if seated and not ok_pen:
            reason = "seated but wall penetration exceeded half the clearance"
        return TrialResult(seated and ok_pen, seated, depth, max_pen, float(self.data.time), max_force, reason,
                           np.array(logs_t), np.array(logs_tip), np.array(logs_w), np.array(logs_tw))

    def impedance(self, gains: "ImpedanceGains | None" = None) -> "CartesianImpedance":
        """The torque-level :class:`CartesianImpedance` of this cell (Pinocchio model with the tool
        as payload and the armature), compliance centre on the tool axis (default: the tip sphere's
        centre)."""
        g = gains or ImpedanceGains()
        back = g.center_from_tip if g.center_from_tip is not None else self.tool.radius
        T_fc = self.T_flange_tool.copy()
        T_fc[:3, 3] = R_FLANGE_TOOL @ np.array([0.0, 0.0, self.tool.tip - back])
        return CartesianImpedance(self.controller.model, self.robot.flange_frame, T_fc, g, self.robot.viscous,
                                  self.robot.coulomb, self.controller.effort_limit)

    def run_impedance(self, policy: Callable[[np.ndarray], np.ndarray] | None, T_start: np.ndarray, *,
                      time_limit: float = 10.0, gains: "ImpedanceGains | None" = None, v_push: float = 0.008,
                      probe: bool = True, f_abort: float = 150.0, skill_dt: float = 0.01,
                      force_noise: float = 0.05, torque_noise: float = 0.002, settle: float = 0.3,
                      seed: int = 0) -> TrialResult:
        """One insertion from ``T_start`` (4x4 tool pose) under torque-level Cartesian impedance
        (:class:`CartesianImpedance`): the motors get tau = J^T W + h(q, qd) + friction; there is no
        joint position servo.

        1. ``probe`` (default on): the hole's axis is measured by touch before inserting. The tip
           sphere touches the flat top face of the hole part at three points around the hole
           (:attr:`ImpedanceGains.probe_radius` from the nominal axis, 120 deg apart, lowered along the
           tool axis at ``probe_speed`` until the felt axial force exceeds ``probe_force``); the
           sphere centres at first touch lie on a plane parallel to the face, whose normal (the
           face is perpendicular to the bore) is the hole axis. The equilibrium is then rotated
           about the compliance centre (the tip sphere's centre) to put the tool axis on it, and
           moved back over the nominal hole position. Only the F/T sensor and the robot's own
           kinematics are used; the true hole pose is never read.
        2. insertion: with a ``policy`` (the skill: wrench (6,) tool frame -> tool twist
           [vx, vy, vz, wx, wy]) the skill moves the impedance equilibrium (lateral, and rotation
           about the compliance centre) and sets the axial speed of the force-limited axial damper
           (so the axial force is bounded by ``axial_damping`` x its speed). ``policy=None``
           replaces the skill by a constant axial push at ``v_push`` with the equilibrium fixed
           (what the compliant controller does without the skill).

        Success as in :meth:`run`: tip within 1 mm of the bottom, wall penetration below half the
        clearance, within ``time_limit`` s (probing included).
        """
        g = gains or ImpedanceGains()
        imp = self.impedance(g)
        rng = np.random.default_rng(seed)
        q0 = self.ik(T_start)
        d, m = self.data, self.model
        mujoco.mj_resetData(m, d)
        d.qpos[self.qadr] = q0
        mujoco.mj_forward(m, d)
        imp.set_gains(q0)
        dt = float(m.opt.timestep)
        n_skill = max(1, int(round(skill_dt / dt)))
        tool = self.tool
        bottom = self.task.bottom_z
        st = {"k": 0, "max_pen": 0.0, "max_force": 0.0, "stop": None, "tw": np.zeros(5)}
        logs_t, logs_tip, logs_w, logs_tw = [], [], [], []
        n_live = int(time_limit / dt)

        def step(x0, R0, v_ref):
            """One 1 ms control period; returns the measured tool pose, wrench and centre pose."""
            q, qd = d.qpos[self.qadr], d.qvel[self.vadr]
            tau, _ = imp.torque(q, qd, x0, R0, v_ref)
            d.ctrl[self.aid] = tau
            mujoco.mj_step(m, d)
            T = self.ft.pose(d)
            w = self.ft.wrench(d, T[:3, :3])
            w[:3] += force_noise * rng.standard_normal(3)
            w[3:] += torque_noise * rng.standard_normal(3)
            x, R, _, _ = imp.pose_twist(d.qpos[self.qadr], d.qvel[self.vadr])
            return T, w, x, R

        # hold the start pose (gravity compensated) for ``settle`` s
        x0, R0, _, _ = imp.pose_twist(q0, np.zeros(len(q0)))
        for _ in range(int(settle / dt)):
            step(x0, R0, 0.0)

        def live(x0, R0, v_ref):
            T, w, x, R = step(x0, R0, v_ref)
            st["x"] = x
            k = st["k"]
            st["k"] += 1
            tip = _tip(T, tool)
            fmag = float(np.sqrt(w[0] ** 2 + w[1] ** 2 + w[2] ** 2))
            st["max_force"] = max(st["max_force"], fmag)
            st["max_pen"] = max(st["max_pen"], _wall_penetration(d, self._walls[0], self._walls[1], self._peg))
            if k % 10 == 0:
                logs_t.append(k * dt)
                logs_tip.append(tip)
                logs_w.append(w)
                logs_tw.append(st["tw"].copy())
            if tip[2] - bottom <= 1e-3:
                st["stop"] = "seated"
            elif fmag > f_abort:
                st["stop"] = "force limit (safety stop)"
            elif st["k"] >= n_live:
                st["stop"] = "time limit"
            return T, w, x, R

        def move(x0, R0, target, speed):
            """Move the equilibrium's lateral position to ``target`` (min-jerk); the axial channel
            holds the axial position with a P law through the damper."""
            start = x0.copy()
            n = max(1, int(np.linalg.norm(target - start) / speed / dt))
            for i in range(1, n + 1):
                x0 = start + _minjerk(i / n) * (target - start)
                live(x0, R0, float(g.probe_gain * (R0[:, 2] @ (x0 - st["x"]))))
                if st["stop"]:
                    break
            return x0

        x_start = x0.copy()
        st["x"] = x0.copy()
        if probe:
            a = R0[:, 2]
            pts = []
            for phi in (0.0, 2 * np.pi / 3, 4 * np.pi / 3):
                off = R0 @ np.array([np.cos(phi), np.sin(phi), 0.0]) * g.probe_radius
                x0 = move(x0, R0, x_start + off, g.probe_move_speed)
                touched = None
                i = 0
                x_top = st["x"].copy()
                while not st["stop"]:
                    i += 1  # speed ramped over 0.1 s: the tool's inertial force stays below the threshold
                    # fast for the first probe_fast_depth, then slow: a gentle touch
                    v = g.probe_speed if a @ (st["x"] - x_top) < g.probe_fast_depth else g.probe_touch_speed
                    T, w, x, R = live(x0 + a * (a @ (st["x"] - x0)), R0, v * min(1.0, i * dt / 0.1))
                    if -w[2] > g.probe_force:
                        touched = x.copy()
                        break
                if st["stop"]:
                    break
                pts.append(touched)
                x0 = move(x0 + a * (a @ (touched - x0)), R0, x_start + off - a * g.probe_lift, g.probe_move_speed)
                x0 = x_start + off - a * g.probe_lift
            if len(pts) == 3 and not st["stop"]:
                nrm = np.cross(pts[1] - pts[0], pts[2] - pts[0])
                nrm = nrm / np.linalg.norm(nrm)
                if nrm @ a < 0:
                    nrm = -nrm
                # rotate the equilibrium about the compliance centre: tool axis onto the measured axis
                R0 = _exp(np.arcsin(np.clip(np.linalg.norm(np.cross(a, nrm)), 0, 1))
                          * np.cross(a, nrm) / max(np.linalg.norm(np.cross(a, nrm)), 1e-12)) @ R0
                x0 = move(x0, R0, x_start, g.probe_move_speed)
            self.last_probe = {"points": np.array(pts), "axis": nrm if len(pts) == 3 else None,
                               "time": st["k"] * dt}
        # insertion
        imp.set_gains(d.qpos[self.qadr].copy(), lateral_stiffness=g.insert_lateral_stiffness)
        tw = np.zeros(5)
        kk = 0
        T, w, x, R = live(x0, R0, 0.0) if not st["stop"] else (None, None, None, None)
        while not st["stop"]:
            if policy is None:
                tw = np.array([0.0, 0.0, v_push, 0.0, 0.0])
            elif kk % n_skill == 0:
                tw = np.asarray(policy(w), float)
            st["tw"] = tw
            kk += 1
            x0 = x0 + R @ np.array([tw[0], tw[1], 0.0]) * dt
            x0 = x0 + R[:, 2] * (R[:, 2] @ (x - x0))  # no axial spring: the axis is force controlled
            if g.skill_rotation:
                R0 = _exp(R @ np.array([tw[3], tw[4], 0.0]) * dt) @ R0
            T, w, x, R = live(x0, R0, float(tw[2]))
        reason = st["stop"]
        seated = reason == "seated"
        max_pen = st["max_pen"]
        depth = float(_tip(self.ft.pose(d), tool)[2] - bottom)
        ok_pen = max_pen < 0.5 * self.task.clearance
        if seated and not ok_pen:
            reason = "seated but wall penetration exceeded half the clearance"
        return TrialResult(seated and ok_pen, seated, depth, max_pen, st["k"] * dt, st["max_force"], reason,
                           np.array(logs_t), np.array(logs_tip), np.array(logs_w), np.array(logs_tw))

@dataclass(frozen=True)
class AdmittanceGains:
    """Virtual dynamics of the hybrid controller about a compliance centre on the tool axis
    (default: the centre of the peg's hemispherical tip, the point the hole constrains first; SI units): lateral
    mass-spring-damper, axial damper (force = damping x (skill speed - speed)), rotational
    inertia-spring-damper about the tip (no rotation about the tool axis).

    Optional (off by default): ``rim_speed`` limits the axial speed while the tip depth below the
    hole top is within ``rim_zone`` (where the cylinder meets the rim: the tip sphere's centre at the
    top; a tilted peg wedges there within a few ms at the nominal speed), and ``torque_filter_hz``
    gives the torque about the compliance centre its own low-pass (from the raw wrench) against the
    contact chatter. Measured on the benchmark's 50 starts with rim_speed=1 mm/s,
    rim_zone=(12.5, 15.5) mm, axial_damping=800, inertia=0.2, rot_damping=0.2, torque_filter_hz=5:
    17/50 against 13/50 with a 20-demonstration skill, but 7/50 against 11/50 with the benchmark's
    60-demonstration skill, and neighbouring settings gave 9-12/50: no robust gain, so the defaults
    leave both off."""

    center_from_tip: float | None = None  # compliance centre behind the tip (m); None: the tip sphere's centre
    #: rotate the commanded pose (rotational admittance). Off by default: every figure measured on this
    #: path (11/50) was taken while ``_exp`` rotated by |w|^2 instead of |w| (a bug, now fixed), i.e. with
    #: the rotation effectively off; turning it on now gives a different, unmeasured controller.
    rotate: bool = False
    mass: float = 10.0
    lateral_stiffness: float = 300.0
    lateral_damping: float = 1000.0
    axial_damping: float = 2000.0
    max_axial_speed: float = 0.015
    inertia: float = 0.5
    rot_stiffness: float = 0.05
    rot_damping: float = 0.1
    force_filter_hz: float = 20.0
    torque_filter_hz: float | None = None  # own low-pass of the torque about the centre (None: force_filter_hz)
    rim_speed: float | None = None  # axial speed limit (m/s) while the tip depth is within rim_zone
    rim_zone: tuple[float, float] = (0.0125, 0.0155)  # tip depth below the hole top (m): the cylinder meets the rim


# ------------------------------------------------------------------------------ torque-level impedance
@dataclass(frozen=True)
class ImpedanceGains:
    """Gains of :class:`CartesianImpedance` (SI units), all expressed in the tool frame at the
    compliance centre (default: the centre of the peg's hemispherical tip).

    Lateral (tool x, y): spring ``lateral_stiffness`` (N/m) to the equilibrium, damper
    ``lateral_damping`` (N s/m; None: critical, 2 sqrt(K Lambda_ii) with the operational-space
    inertia Lambda at the start). Axial (tool z): no spring; force = ``axial_damping`` x (skill
    speed - speed), clipped to +-``max_axial_force`` (N): a force-limited damper, so the axial
    contact force is set by the skill's velocity. Rotation about the tool x, y axes through the
    centre: spring ``rot_stiffness`` (N m/rad), damper ``rot_damping`` (None: critical); about the
    tool axis: ``twist_stiffness`` (N m/rad, critical damping). ``friction_compensation`` adds the
    URDF's viscous + Coulomb joint friction at the measured joint velocity (Coulomb smoothed by
    tanh(qd / ``friction_velocity``)).

    Defaults: the rotational stiffness (300 N m/rad) is high so that the J4/J5 Coulomb friction
    (0.4 N m) leaves at most ~0.08 deg between the equilibrium and the tool after the probed
    alignment; the lateral stiffness is 2000 N/m while moving and probing (the shoulder joints' 2 N m
    friction) and ``insert_lateral_stiffness`` (300 N/m) while inserting, where the sphere and the
    bore centre the peg. ``skill_rotation`` (off): the skill's [wx, wy] would rotate the equilibrium
    away from the probed axis (the demonstrator's rotational reflex, at the human's torque scale; on
    tilted starts (2.2-2.9 deg) it turned 6/6 into 2/6, and 5/5 into 0/3 with another skill, by force-limit stops). ``probe_*``: the touch probing of
    :meth:`RobotPegHole.run_impedance`.
    """

    center_from_tip: float | None = None
    lateral_stiffness: float = 2000.0
    lateral_damping: float | None = None
    axial_damping: float = 1000.0
    max_axial_force: float = 20.0
    rot_stiffness: float = 300.0
    rot_damping: float | None = None
    twist_stiffness: float = 50.0
    damping_ratio: float = 1.0
    friction_compensation: bool = True
    friction_velocity: float = 0.01
    skill_rotation: bool = False  # let the skill's [wx, wy] rotate the equilibrium while inserting
    insert_lateral_stiffness: float | None = 300.0  # N/m while inserting (None: lateral_stiffness)
    probe_radius: float = 0.0187  # lateral offset (m) of the touches from the nominal hole axis
    probe_speed: float = 0.02  # m/s toward the face for the first probe_fast_depth
    probe_fast_depth: float = 0.0015  # m
    probe_touch_speed: float = 0.006  # m/s after that, until the touch
    probe_force: float = 2.0  # N: a touch
    probe_lift: float = 0.001  # m back off after a touch
    probe_move_speed: float = 0.08  # m/s mean speed of the lateral moves
    probe_gain: float = 20.0  # 1/s: axial position hold while moving (speed = gain x axial error)


class CartesianImpedance:
    """Torque-level Cartesian impedance about a compliance centre on the tool (hybrid
    position/force control as on a torque-controlled arm):

        tau = J_c(q)^T W + h(q, qd) + tau_f(qd),
        W = [K_l (x_0 - x)_xy - D_l v_xy ;  clip(D_a (v_ref - v_z), +-f_max) ;
             K_r log(R_0 R^T)_xy - D_r w_xy ;  K_t log(R_0 R^T)_z - D_t w_z],

    all in the frame of the compliance centre C (tool axes, origin on the tool axis), where
    J_c is C's 6xn body Jacobian [v; w] (Pinocchio, LOCAL), (x, R) its pose and (v, w) its twist
    from the measured joints, h = C(q, qd) qd + g(q) the Coriolis/centrifugal and gravity torques of
    the Pinocchio model with the tool as payload (RNEA at zero acceleration), tau_f the URDF's
    viscous + Coulomb friction at the measured velocity. (x_0, R_0) is the equilibrium the skill
    moves; v_ref the axial speed it asks for. The inertia is not shaped: the arm keeps its own
    operational-space inertia Lambda = (J_c M^-1 J_c^T)^-1 (armature included).
    """

    def __init__(self, pin_model, flange_frame: str, T_flange_centre: np.ndarray, gains: ImpedanceGains,
                 viscous, coulomb, effort_limit) -> None:
        import pinocchio as pin

        self.pin = pin
        model = pin_model.copy()
        parent = model.frames[model.getFrameId(flange_frame)]
        placement = parent.placement * pin.SE3(np.ascontiguousarray(T_flange_centre[:3, :3]),
                                               np.ascontiguousarray(T_flange_centre[:3, 3]))
        self.fid = model.addFrame(pin.Frame("compliance_centre", parent.parentJoint, placement,
                                            pin.FrameType.OP_FRAME))
        self.model = model
        self.data = model.createData()
        self.gains = gains
        self.viscous = np.asarray(viscous, float)
        self.coulomb = np.asarray(coulomb, float)
        self.effort = np.asarray(effort_limit, float)
        self.K = np.zeros(6)
        self.D = np.zeros(6)

    def pose_twist(self, q, qd) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Pose (x (3,), R (3,3)), body twist [v; w] (6,) of the centre and its LOCAL Jacobian (6, n)."""
        pin, m, d = self.pin, self.model, self.data
        pin.forwardKinematics(m, d, q, qd)
        pin.updateFramePlacement(m, d, self.fid)
        M = d.oMf[self.fid]
        tw = pin.getFrameVelocity(m, d, self.fid, pin.LOCAL)
        J = pin.computeFrameJacobian(m, d, q, self.fid, pin.LOCAL)
        return M.translation.copy(), M.rotation.copy(), np.concatenate([tw.linear, tw.angular]), J

    def set_gains(self, q, *, lateral_stiffness: float | None = None) -> None:
        """Stiffness K and damping D (6,) for the operational inertia at ``q`` (critical where None);
        ``lateral_stiffness`` overrides the gains' (N/m)."""
        pin, m, d = self.pin, self.model, self.data
        g = self.gains
        if lateral_stiffness is not None:
            g = replace(g, lateral_stiffness=float(lateral_stiffness))
        J = pin.computeFrameJacobian(m, d, q, self.fid, pin.LOCAL)
        Minv = pin.computeMinverse(m, d, q)
        Minv = np.triu(Minv) + np.triu(Minv, 1).T
        lam = np.diag(np.linalg.inv(J @ Minv @ J.T))
        self.K = np.array([g.lateral_stiffness, g.lateral_stiffness, 0.0, g.rot_stiffness, g.rot_stiffness,
                           g.twist_stiffness])
        crit = 2.0 * g.damping_ratio * np.sqrt(self.K * lam)
        self.D = crit.copy()
        if g.lateral_damping is not None:
            self.D[:2] = g.lateral_damping
        if g.rot_damping is not None:
            self.D[3:5] = g.rot_damping
        self.D[2] = 0.0
        self.lam = lam

    def torque(self, q, qd, x0, R0, v_ref: float) -> tuple[np.ndarray, np.ndarray]:
        """Joint torques (n,) N m (clipped to the effort limits) and the commanded wrench W (6,)."""
        x, R, tw, J = self.pose_twist(q, qd)
        e = np.concatenate([R.T @ (x0 - x), R.T @ _log(R0 @ R.T)])
        W = self.K * e - self.D * tw
        g = self.gains
        W[2] = float(np.clip(g.axial_damping * (v_ref - tw[2]), -g.max_axial_force, g.max_axial_force))
        tau = J.T @ W + self.pin.rnea(self.model, self.data, q, qd, np.zeros_like(q))
        if g.friction_compensation:
            tau += self.viscous * qd + self.coulomb * np.tanh(qd / g.friction_velocity)
        return np.clip(tau, -self.effort, self.effort), W


def random_start_errors(rng: np.random.Generator, n: int, *, lateral: float = 1e-3,
                        max_tilt: float = np.radians(3.0)) -> list[tuple[np.ndarray, tuple[float, float]]]:
    """``n`` randomised start errors: lateral uniform in +/-``lateral`` (m) per axis, tilt uniform in
    [0, ``max_tilt``] (rad) about a random horizontal axis."""
    return [(rng.uniform(-lateral, lateral, 2), (float(rng.uniform(0, 2 * np.pi)), float(rng.uniform(0, max_tilt))))
            for _ in range(n)]


@dataclass(frozen=True)
class PressResult:
    """:func:`press_test` outcome: ``inserted`` (tip within 1 mm of the bottom), final tip height
    above the bottom (m), maximum wall penetration (m), mean axial contact force (N) at the end."""

    inserted: bool
    height: float
    max_penetration: float
    axial_force: float


def press_test(task: PegHole, *, interference: float = 0.0, force: float = 100.0, duration: float = 4.0,
               lateral: float = 0.0, tilt: float = 0.0) -> PressResult:
    """Press the HDD's peg into the hole with up to ``force`` N along the hole axis (the hand a stiff
    spring whose reference sinks at 10 mm/s to 20 mm below the bottom, laterally compliant) for
    ``duration`` s. With
    ``interference`` > 0 (diametral, m) the peg is larger than the hole: an honest simulation must
    not let it in."""
    tool = task.tool(interference=interference)
    scene = HDDScene(task, tool)
    T = task.pre_insert_pose(tool, height=0.001)
    T[:3, :3] = _rot([0.0, 1.0, 0.0], tilt) @ T[:3, :3]
    T[:3, 3] = np.array(task.top) + np.array([lateral, 0.0, 0.001]) - T[:3, 2] * tool.tip
    scene.reset(T)
    dt = float(scene.model.opt.timestep)
    z0 = T[:3, 3].copy()
    max_pen = 0.0
    mg = np.array([0, 0, scene.mass * 9.81])
    for k in range(int(duration / dt)):
        P = scene.pose()
        v, w = scene.twist()
        ref = z0 - np.array([0, 0, min(0.01 * k * dt, task.depth + 0.02)])
        e = ref - P[:3, 3]
        fz = float(np.clip(20000 * e[2] - 150 * v[2], -force, force))
        f = np.array([300 * e[0] - 20 * v[0], 300 * e[1] - 20 * v[1], fz]) + mg
        scene.step(f, -0.05 * w)
        max_pen = max(max_pen, scene.wall_penetration())
    h = float(_tip(scene.pose(), tool)[2] - task.bottom_z)
    return PressResult(h <= 1e-3, h, max_pen, float(-scene.wrench()[2]))
