"""Grinding by demonstration (Sec. 5.5, Fig. 5.13): learn where to press hard, reproduce the force.

A plate workpiece; the person moves the hand-held demonstration device (here with a stylus tool)
over it in serpentine strokes, pressing hard on two regions and lightly elsewhere. A GMR skill model
maps the tool position on the plate to the pressing force (5.14)-(5.17); the LR Mate, carrying the
same tool, follows a diagonal path across the plate under force control (an axial admittance on top
of its position-controlled joint servo) with the learned force as its set-point.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np
import numpy.typing as npt
from threadpoolctl import threadpool_limits

from robointel.errors import InvalidInput
from robointel.geometry.rotations import so3_log
from robointel.learning.demonstration import Demonstration
from robointel.learning.gmr import GaussianMixtureRegression
from robointel.learning.hdd import Contact, Tool
from robointel.learning.insertion import R_DOWN, HDDScene, RobotCell, tip_point
from robointel.outcome import Failure, TrialOutcome


@dataclass(frozen=True)
class Plate:
    """The workpiece: a plate of ``size`` (m) centred at ``center`` (x, y), top surface at ``top`` z.

    The demonstrator's intended pressing force is ``light`` N, rising to ``hard`` N in Gaussian
    regions (std ``spread`` m) around ``hard_spots`` (plate coordinates, m).
    """

    center: tuple[float, float] = (0.60, 0.0)
    top: float = 0.12
    size: tuple[float, float] = (0.18, 0.18)
    hard_spots: tuple[tuple[float, float], ...] = ((-0.035, -0.035), (0.035, 0.035))
    spread: float = 0.025
    light: float = 5.0
    hard: float = 25.0
    # a grinding pad is compliant and progressive: 10 ms contact time constant, impedance rising from
    # 0.5 at first touch to 0.99 at 0.2 mm compression (why: docs/design/skills.md, "Grinding").
    contact: Contact = field(default_factory=lambda: Contact(friction=0.15, solref=(0.01, 1.0),
                                                             solimp=(0.5, 0.99, 0.0002, 0.5, 2.0)))

    def force_profile(self, xy: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Intended pressing force of the demonstrator at plate coordinates.

        Args:
            xy: Plate coordinates, shape (n, 2) or (2,), m.

        Returns:
            The intended force, shape (n,), N: ``light`` plus ``hard - light`` times the largest
            Gaussian bump (std ``spread``) around the ``hard_spots``.
        """
        xy = np.atleast_2d(np.asarray(xy, float))
        g = np.zeros(len(xy))
        for s in self.hard_spots:
            g = np.maximum(g, np.exp(-0.5 * np.sum((xy - np.asarray(s)) ** 2, axis=1) / self.spread ** 2))
        return self.light + (self.hard - self.light) * g

    def build(self, spec: mujoco.MjSpec) -> None:
        """Add the plate (and a pedestal below it, if it is raised) to a MuJoCo model spec.

        Args:
            spec: The model specification to add the geoms to (its world body).
        """
        cx, cy = self.center
        g = spec.worldbody.add_geom(name="plate", type=mujoco.mjtGeom.mjGEOM_BOX,
                                    size=[self.size[0] / 2, self.size[1] / 2, 0.01], pos=[cx, cy, self.top - 0.01],
                                    rgba=[0.6, 0.6, 0.65, 1], contype=2, conaffinity=3)
        self.contact.apply(g)
        if self.top - 0.02 > 0:
            spec.worldbody.add_geom(name="plate/pedestal", type=mujoco.mjtGeom.mjGEOM_BOX,
                                    size=[0.05, 0.05, (self.top - 0.02) / 2], pos=[cx, cy, (self.top - 0.02) / 2],
                                    rgba=[0.4, 0.4, 0.45, 1], contype=2, conaffinity=3)

    def pre_insert_pose(self, tool: Tool, height: float = 0.003) -> npt.NDArray[np.float64]:
        """Tool pose pointing down over the plate centre.

        Args:
            tool: The tool whose tip length places the tool frame.
            height: Gap between the tool tip and the plate's top surface, m.

        Returns:
            The (4, 4) homogeneous tool pose in the world frame (m).
        """
        T = np.eye(4)
        T[:3, :3] = R_DOWN
        T[:3, 3] = [self.center[0], self.center[1], self.top + height + tool.tip]
        return T

    def tool(self) -> Tool:
        """Return the grinding stylus (a 6 mm radius capsule tip)."""
        return Tool(radius=0.006, length=0.04, offset=0.03, mass=0.2, name="stylus")


def demonstrate_grinding(plate: Plate, rng: np.random.Generator, *, scene: HDDScene | None = None,
                         lines: int | None = None, speed: float = 0.06, stiffness: float = 2000.0,
                         damping: float = 100.0, record_dt: float = 0.01, name: str = "") -> Demonstration:
    """Record one hand-held grinding demonstration on the plate (Sec. 5.5).

    Serpentine strokes along x at ``lines`` y-offsets (randomly shifted), the hand pressing with the
    intended force (plus a human's 8 % force variation and tremor). By default the strokes are at
    most one tool diameter apart, as grinding strokes overlap to cover the surface: a stroke grinds
    (and the F/T sensor samples) a track one tool diameter wide.

    Args:
        plate: The workpiece and the demonstrator's intended force profile.
        rng: Random generator for the stroke offsets, force gain, tremor and sensor noise.
        scene: The demonstration-device scene; a new one for ``plate`` when None.
        lines: Number of strokes; None spaces them one tool diameter apart.
        speed: Stroke speed, m/s.
        stiffness: Axial stiffness of the hand, N/m.
        damping: Translational damping of the hand, N s/m.
        record_dt: F/T and pose sample interval, s (the mean over each interval is recorded).
        name: Name stored in the demonstration.

    Returns:
        The demonstration: time (n,) s, tool poses (n, 4, 4) and wrenches (n, 6) N, N m.

    Raises:
        InvalidInput: ``lines`` is not a positive number.
    """
    tool = plate.tool()
    scene = scene or HDDScene(plate, tool)
    dt = float(scene.model.opt.timestep)
    half = 0.5 * np.array(plate.size) - 0.015
    if lines is None:
        lines = int(np.ceil(2 * half[1] / (2 * tool.radius))) + 1
    if int(lines) < 1:
        raise InvalidInput(f"lines must be a positive number of strokes, got {lines}", value=lines)
    lines = int(lines)
    ys = np.linspace(-half[1], half[1], lines) + rng.uniform(-0.01, 0.01)
    ys = np.clip(ys, -half[1], half[1])
    c = np.array(plate.center)
    gain = rng.uniform(0.92, 1.08)
    T0 = plate.pre_insert_pose(tool, 0.004)
    T0[:3, 3] += np.array([-half[0], ys[0], 0.0])
    scene.reset(T0)
    mg = np.array([0, 0, scene.mass * 9.81])
    ts: list[float] = []
    poses: list[npt.NDArray[np.float64]] = []
    wr: list[npt.NDArray[np.float64]] = []
    rot_k, rot_d = 6.0, 0.2
    step = 0
    every = max(1, int(round(record_dt / dt)))
    phase = rng.uniform(0, 2 * np.pi, 2)
    acc = np.zeros(6)

    def hand(xy: npt.NDArray[np.float64], press: float) -> None:
        nonlocal step, acc
        T = scene.pose()
        v, w = scene.twist()
        ref = np.array([c[0] + xy[0], c[1] + xy[1], plate.top + tool.tip - press / stiffness])
        ref[:2] += 1e-4 * np.sin(2 * np.pi * 9 * step * dt + phase)
        e = ref - T[:3, 3]
        f = np.array([800.0, 800.0, stiffness]) * e - damping * v + mg
        scene.step(f, rot_k * so3_log(R_DOWN @ T[:3, :3].T) - rot_d * w)
        step += 1
        acc += scene.wrench()
        if step % every == 0:  # the sensor's anti-aliasing: the mean over the sample interval
            ts.append(step * dt)
            poses.append(scene.pose())
            wr.append(acc / every + np.r_[0.05 * rng.standard_normal(3), 0.002 * rng.standard_normal(3)])
            acc = np.zeros(6)

    # touch down
    for k in range(300):
        hand(np.array([-half[0], ys[0]]), min(1.0, k / 300) * plate.light)
    x_dir = 1.0
    for i, y in enumerate(ys):
        n = int(2 * half[0] / speed / dt)
        for k in range(n + 1):
            x = -half[0] * x_dir + x_dir * 2 * half[0] * k / n
            xy = np.array([x, y])
            tip_xy = tip_point(scene.pose(), tool)[:2] - c  # the person presses where the tool is
            hand(xy, gain * plate.force_profile(tip_xy)[0])
        if i + 1 < len(ys):  # move over to the next line, pressing lightly
            m = int(abs(ys[i + 1] - y) / speed / dt)
            for k in range(m):
                hand(np.array([x, y + (ys[i + 1] - y) * (k + 1) / m]), plate.light)
        x_dir = -x_dir
    return Demonstration.create(np.array(ts), np.array(poses), np.array(wr), device="hdd", name=name,
                                meta={"task": "grinding", "force_gain": gain})


class GrindingSkill:
    """GMR from the tool-tip position on the plate (x, y) to the pressing force (N), (5.14)-(5.17).

    Args:
        plate: The workpiece (its centre defines the plate coordinates).
        n_components: Number of Gaussian components of the mixture.
        random_state: Seed of the EM initialisation.
    """

    def __init__(self, plate: Plate, n_components: int = 25, *, random_state: int = 0) -> None:
        self.plate = plate
        self.tool = plate.tool()
        self.gmr = GaussianMixtureRegression(n_components, random_state=random_state)

    def samples(self, demo: Demonstration) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Extract the training pairs of one demonstration.

        Args:
            demo: A grinding demonstration (poses and wrenches).

        Returns:
            The tool-tip plate coordinates (m, 2) m and pressing forces (m,) N of the samples in
            contact (pressing force above 1 N).
        """
        tips = np.array([tip_point(T, self.tool) for T in demo.pose])
        xy = tips[:, :2] - np.array(self.plate.center)
        push = -demo.wrench[:, 2]
        m = push > 1.0
        return xy[m], push[m]

    def fit(self, demos: Sequence[Demonstration]) -> GrindingSkill:
        """Fit the position-to-force GMR (5.14)-(5.17) to the demonstrations' contact samples.

        Args:
            demos: Grinding demonstrations.

        Returns:
            This skill, fitted.

        Raises:
            InvalidInput: ``demos`` is empty.
        """
        if len(demos) == 0:
            raise InvalidInput("GrindingSkill.fit needs demonstrations")
        pairs = [self.samples(d) for d in demos]
        X = np.concatenate([p[0] for p in pairs])
        Y = np.concatenate([p[1] for p in pairs])
        self.y_mean_, self.y_scale_ = float(Y.mean()), float(Y.std() + 1e-9)
        self.y_lo_, self.y_hi_ = float(Y.min()), float(Y.max())
        with threadpool_limits(limits=1, user_api="blas"):  # 3-D EM steps: threads cost more than they save
            self.gmr.fit(X / 0.05, (Y[:, None] - self.y_mean_) / self.y_scale_)
        self.X_, self.Y_ = X, Y
        return self

    def predict(self, xy: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Predict the pressing force by GMR (5.17), saturated to the demonstrated force range.

        The saturation stops the regression's local linear models from extrapolating to pulling
        forces off the demonstrated area.

        Args:
            xy: Plate coordinates, shape (n, 2) or (2,), m.

        Returns:
            The pressing force set-points, shape (n,), N.
        """
        f = self.gmr.predict(np.atleast_2d(np.asarray(xy, float)) / 0.05)[:, 0] * self.y_scale_ + self.y_mean_
        return np.clip(f, self.y_lo_, self.y_hi_)


@dataclass
class GrindingResult:
    """Reproduction along the path of :func:`reproduce_grinding`.

    Fields: ``t`` (n,) s, plate coordinates ``xy`` (n, 2) m, measured force (n,) N, the skill's
    set-point (n,) N, the demonstrator's intended profile (n,) N and
    ``rms_rel`` = RMS(measured - intended) / peak intended force (``rms_rel_setpoint``: against
    the skill's set-point, i.e. the force controller alone); ``max_rms_rel``, the success bound on
    ``rms_rel`` used by :attr:`outcome`.
    """

    t: np.ndarray
    xy: np.ndarray
    force: np.ndarray
    setpoint: np.ndarray
    intended: np.ndarray
    rms_rel: float
    rms_rel_setpoint: float
    max_rms_rel: float = 0.25

    @property
    def outcome(self) -> TrialOutcome:
        """The reproduction as a trial: success when ``rms_rel <= max_rms_rel``, else ``Failure.TRACKING``.

        Figures: ``rms_rel``, ``rms_rel_setpoint`` and ``max_force_n`` (largest measured force, N).
        """
        figures = {"rms_rel": float(self.rms_rel), "rms_rel_setpoint": float(self.rms_rel_setpoint),
                   "max_force_n": float(np.max(self.force)) if len(self.force) else float("nan")}
        ok = bool(np.isfinite(self.rms_rel) and self.rms_rel <= self.max_rms_rel)
        detail = f"force RMS error {100 * self.rms_rel:.1f}% of peak (limit {100 * self.max_rms_rel:.0f}%)"
        return TrialOutcome(ok, Failure.NONE if ok else Failure.TRACKING, detail, figures)


def reproduce_grinding(plate: Plate, skill: GrindingSkill, *, cell: RobotCell | None = None,
                       speed: float = 0.03, k_force: float = 1.0 / 1500.0, filter_hz: float = 5.0,
                       t_touch: float = 1.0, seed: int = 0, max_rms_rel: float = 0.25) -> GrindingResult:
    """Reproduce the grinding skill: the LR Mate follows the plate's diagonal (Fig. 5.13).

    Lateral motion is position controlled, the tool axis is force controlled by an admittance
    ``v = k_force (F_set - F_filtered)`` on the joint servo's reference (``filter_hz`` low-pass on
    the F/T signal). The reported force is the raw sensor force averaged over each 10 ms sample.

    Args:
        plate: The workpiece and the demonstrator's intended force profile.
        skill: The learned :class:`GrindingSkill` (any object whose ``predict`` maps plate
            coordinates (n, 2) m to set-points (n,) N).
        cell: The robot cell; a new one for ``plate`` when None.
        speed: Path speed along the diagonal, m/s.
        k_force: Admittance gain, m/(N s).
        filter_hz: Cut-off of the F/T low-pass filter, Hz.
        t_touch: Time pressing at the start point before moving, s.
        seed: Seed of the sensor noise.
        max_rms_rel: Success bound of the result's :attr:`GrindingResult.outcome` on ``rms_rel``.

    Returns:
        The measured, set-point and intended forces along the path, their relative RMS errors and
        the trial outcome.

    Raises:
        IKFailure: The start pose is out of reach.
    """
    cell = cell or RobotCell(plate, tool=plate.tool())
    tool = cell.tool
    rng = np.random.default_rng(seed)
    half = 0.5 * np.array(plate.size) - 0.02
    a_xy, b_xy = -half, half
    L = float(np.linalg.norm(b_xy - a_xy))
    T = plate.pre_insert_pose(tool, 0.0005)
    T[:3, 3] += np.r_[a_xy, 0.0]
    q_ref = cell.ik(T)
    cell.reset(q_ref)
    dt = float(cell.model.opt.timestep)
    c = np.array(plate.center)
    alpha = 1.0 - np.exp(-2 * np.pi * filter_hz * dt)
    p_f = 0.0
    z_cmd = float(tip_point(cell.tool_pose(), tool)[2])
    n = int((t_touch + L / speed) / dt)
    ts: list[float] = []
    xy_log: list[npt.NDArray[np.float64]] = []
    f_log: list[float] = []
    sp_log: list[float] = []
    acc = 0.0
    f_set = 0.0
    for k in range(n):
        t = k * dt
        Tm = cell.ft.pose(cell.data)
        w = cell.ft.wrench(cell.data, Tm[:3, :3])
        push = -w[2] + 0.05 * rng.standard_normal()
        p_f += alpha * (push - p_f)
        acc += push
        s = float(np.clip((t - t_touch) * speed / L, 0.0, 1.0))
        xy = a_xy + s * (b_xy - a_xy)
        if k % 10 == 0:
            f_set = float(skill.predict(xy[None])[0])
        z_cmd += -k_force * (f_set - p_f) * dt
        tip_cmd = np.array([c[0] + xy[0], c[1] + xy[1], z_cmd])
        T_cmd = np.eye(4)
        T_cmd[:3, :3] = R_DOWN
        T_cmd[:3, 3] = tip_cmd - R_DOWN[:, 2] * tool.tip
        Tf = cell.robot.fk(q_ref)
        Tf_cmd = cell.flange_target(T_cmd)
        err = np.concatenate([100.0 * (Tf_cmd[:3, 3] - Tf[:3, 3]), 100.0 * so3_log(Tf_cmd[:3, :3] @ Tf[:3, :3].T)])
        qd_ref = np.linalg.solve(cell.robot.jacobian(q_ref), err)
        q_ref = q_ref + qd_ref * dt
        cell.servo_step(q_ref, qd_ref)
        if k % 10 == 9:
            if t >= t_touch:  # logged like the HDD: the sensor's mean over the 10 ms sample
                tip = tip_point(Tm, tool)
                ts.append(t)
                xy_log.append(tip[:2] - c)
                f_log.append(acc / 10)
                sp_log.append(f_set)
            acc = 0.0
    xys = np.array(xy_log)
    intended = plate.force_profile(xys)
    fs, sp = np.array(f_log), np.array(sp_log)
    peak = float(intended.max())
    return GrindingResult(np.array(ts), xys, fs, sp, intended,
                          float(np.sqrt(np.mean((fs - intended) ** 2)) / peak),
                          float(np.sqrt(np.mean((fs - sp) ** 2)) / peak), float(max_rms_rel))
