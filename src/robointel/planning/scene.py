"""Planning scenes as YAML: robot, obstacles, stop-by waypoints, limits, weights (Ch. 7).

Format (all keys but ``robot``, ``waypoints`` and a step size optional)::

    name: table71
    robot: lrmate200id7l          # built-in name, 'ur5', 'panda' or a URDF path (relative to the file)
    operational_time: 15.0        # s over all steps at a fixed step (or give dt: 0.158)
    steps: [19, 19, 19, 19, 19]   # steps per segment (one entry per segment, or one int for all)
    d_min: 0.05                   # m, clearance robot spheres <-> obstacles
    limits:                       # velocity/acceleration: rad/s, rad/s^2 per joint, or *_scale of the robot's
      velocity_scale: 0.3
      acceleration_scale: 0.3
    weights: {w1: 1.0, w2: 0.02, w3: 1.0, w4: 1.0}   # (7.1) tracking/acceleration, (7.7) time/smoothness
    planner: {safety: 0.005, margin: 0.15, slots: 8, substeps: 1, eps: 0.001, max_iter: 30}
    table: true                   # the workcell's table (top z = 0) and floor are obstacles (default true)
    obstacles:                    # robointel.geometry shapes: box, sphere, capsule, cylinder, pointcloud
      - {type: box, name: box_A, center: [0.5, 0.0, 0.15], size: [0.3, 0.1, 0.3]}
    waypoints:                    # q (rad), q_deg (deg), or pose: {xyz: [m], rpy_deg: [deg]} solved by IK
      - {name: home, q_deg: [0, 0, -20, 0, -70, 0]}
      - {name: pick, pose: {xyz: [0.5, 0.35, 0.12], rpy_deg: [0, 90, 34]}}

Built-in scenes live in ``robointel/planning/scenes``; :func:`load_scene` accepts their names. The
YAML file itself is read and written by :mod:`robointel.io.scene`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from robointel.errors import IKFailure, InvalidInput, LimitViolation, RobointelError
from robointel.geometry import obstacle_from_dict
from robointel.geometry.obstacles import Obstacle
from robointel.geometry.rotations import rpy_to_matrix
from robointel.geometry.table import ENVIRONMENT_NAMES, table_obstacles
from robointel.io.scene import read_scene_file, write_scene_file
from robointel.planning.waypoints import PlannerSettings
from robointel.robot import Robot

__all__ = ["SCENES", "Scene", "builtin_scenes", "load_scene", "scene_from_dict"]

#: directory of the built-in scenes
SCENES = Path(__file__).resolve().parent / "scenes"


@dataclass
class Scene:
    """A planning scene (see the module docstring for the file format).

    Attributes:
        name: scene name.
        robot: the loaded :class:`robointel.robot.Robot`.
        waypoints: (W, n) stop-by configurations (rad), W >= 2.
        waypoint_names: W names.
        steps: W-1 step counts, one per segment.
        dt: the fixed time step (s).
        obstacles: list of :mod:`robointel.geometry` obstacles (with ``table``: the table and floor
            boxes of :func:`robointel.geometry.table.table_obstacles` last, named "table", "floor").
        vmax, amax: (n,) joint velocity / acceleration limits (rad/s, rad/s^2).
        d_min: clearance (m).
        weights: w1, w2 of (7.1), w3, w4 of (7.7).
        planner: extra :class:`robointel.planning.waypoints.PlannerSettings` fields.
        source: the file it came from (None for built in code).
    """

    name: str
    robot: Robot
    waypoints: NDArray[np.float64]
    waypoint_names: list[str]
    steps: list[int]
    dt: float
    obstacles: list[Obstacle]
    vmax: NDArray[np.float64]
    amax: NDArray[np.float64]
    d_min: float = 0.05
    weights: dict[str, float] = field(default_factory=lambda: {"w1": 1.0, "w2": 0.02, "w3": 1.0, "w4": 1.0})
    planner: dict[str, Any] = field(default_factory=dict)
    source: Path | None = None
    description: str = ""
    table: bool = True

    @property
    def total_steps(self) -> int:
        """Steps over all segments."""
        return int(sum(self.steps))

    @property
    def fixed_time(self) -> float:
        """Operational time of the fixed-dt schedule (s)."""
        return self.total_steps * self.dt

    def to_dict(self) -> dict[str, Any]:
        """Plain data (joint angles in degrees), inverse of :func:`scene_from_dict`."""
        return {"name": self.name, "description": self.description, "robot": self.robot.name,
                "dt": self.dt, "steps": list(self.steps), "d_min": self.d_min,
                "limits": {"velocity": self.vmax.tolist(), "acceleration": self.amax.tolist()},
                "weights": dict(self.weights), "planner": dict(self.planner),
                "table": self.table,
                "obstacles": [o.to_dict() for o in self.obstacles
                              if not (self.table and getattr(o, "name", None) in ENVIRONMENT_NAMES)],
                "waypoints": [{"name": n, "q_deg": np.degrees(q).round(6).tolist()}
                              for n, q in zip(self.waypoint_names, self.waypoints)]}

    def save(self, path: str | Path) -> Path:
        """Write the scene as YAML (:func:`robointel.io.scene.write_scene_file`); returns the path."""
        return write_scene_file(self.to_dict(), path)


def builtin_scenes() -> list[str]:
    """Names of the scenes shipped with robointel."""
    return sorted(p.stem for p in SCENES.glob("*.yaml"))


def _num(d: dict, key: str, default: Any = None, *, positive: bool = False) -> float:
    v = d.get(key, default)
    try:
        v = float(v)
    except (TypeError, ValueError, OverflowError):
        raise InvalidInput(f"scene key {key!r} must be a number, got {v!r}", value=v) from None
    if not np.isfinite(v) or (positive and v <= 0):
        raise InvalidInput(f"scene key {key!r} must be finite{' and positive' if positive else ''}, got {v}", value=v)
    return v


def _vector(v: ArrayLike, n: int, what: str) -> np.ndarray:
    try:
        a = np.asarray(v, float).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        raise InvalidInput(f"{what} must be a list of {n} numbers, got {v!r}", value=v) from None
    if a.size != n:
        raise InvalidInput(f"{what} must have {n} entries, got {a.size}", value=v)
    if not np.all(np.isfinite(a)):
        raise InvalidInput(f"{what} contains NaN or inf", value=v)
    return a


def scene_from_dict(d: dict, *, base: Path | None = None) -> Scene:
    """Build a :class:`Scene` from parsed YAML.

    Raises:
        InvalidInput: missing/ill-typed keys, NaN. LimitViolation: waypoints outside the joint
        limits, impossible (non-positive) limits. IKFailure (as InvalidInput): unreachable pose.
    """
    if not isinstance(d, dict):
        raise InvalidInput(f"a scene must be a mapping, got {type(d).__name__}", value=d)
    for key in ("robot", "waypoints"):
        if key not in d:
            raise InvalidInput(f"scene is missing {key!r}", value=sorted(d))
    rname = str(d["robot"])
    if base is not None and (rname.endswith(".urdf") and not Path(rname).is_absolute()):
        rname = str(base / rname)
    robot = Robot.load(rname)
    n = robot.nq
    wps = d["waypoints"]
    if not isinstance(wps, list) or len(wps) < 2:
        raise InvalidInput("scene needs at least two waypoints", value=wps)
    W, names = [], []
    prev = None
    for i, w in enumerate(wps):
        if not isinstance(w, dict):
            w = {"q": w}
        name = str(w.get("name", f"waypoint {i}"))
        if "q" in w:
            q = _vector(w["q"], n, f"waypoint {name!r} q")
        elif "q_deg" in w:
            q = np.radians(_vector(w["q_deg"], n, f"waypoint {name!r} q_deg"))
        elif "pose" in w:
            p: Any = w["pose"]
            if not isinstance(p, dict):
                raise InvalidInput(f"waypoint {name!r} pose must be a mapping {{xyz: [m], rpy_deg: [deg]}}, got {p!r}",
                                   value=p)
            T = np.eye(4)
            T[:3, 3] = _vector(p.get("xyz"), 3, f"waypoint {name!r} pose.xyz")  # type: ignore[arg-type]
            if "rpy_deg" in p:
                T[:3, :3] = rpy_to_matrix(np.radians(_vector(p["rpy_deg"], 3, f"waypoint {name!r} pose.rpy_deg")))
            elif "rpy" in p:
                T[:3, :3] = rpy_to_matrix(_vector(p["rpy"], 3, f"waypoint {name!r} pose.rpy"))
            try:
                sols = robot.ik(T, q_ref=prev) if robot.has_closed_form_ik else [robot.ik_numeric(T, q0=prev)]
            except IKFailure as exc:
                raise InvalidInput(f"waypoint {name!r} is unreachable: {exc}", value=w) from None
            if not sols:
                raise InvalidInput(f"waypoint {name!r} is unreachable: no IK solution within the joint limits", value=w)
            q = np.asarray(sols[0], float)
        else:
            raise InvalidInput(f"waypoint {name!r} needs q, q_deg or pose", value=w)
        tol = 1e-9
        bad = np.flatnonzero((q < robot.lower - tol) | (q > robot.upper + tol))
        if bad.size:
            j = int(bad[0])
            raise LimitViolation(f"waypoint {name!r}: {robot.joint_names[j]} = {np.degrees(q[j]):.2f} deg is outside "
                                 f"its limits [{np.degrees(robot.lower[j]):.1f}, {np.degrees(robot.upper[j]):.1f}] deg",
                                 value=q)
        W.append(q)
        names.append(name)
        prev = q
    Wa = np.array(W)
    nseg = len(Wa) - 1
    steps_in = d.get("steps", 19)
    items = [steps_in] * nseg if not isinstance(steps_in, list) else steps_in
    if any(not isinstance(s, int) or isinstance(s, bool) for s in items):
        raise InvalidInput(f"steps must be an integer or a list of {nseg} integers (steps per segment), got "
                           f"{steps_in!r}", value=steps_in)
    steps = [int(s) for s in items]
    if len(steps) != nseg or any(s < 2 for s in steps):
        raise InvalidInput(f"steps must give {nseg} segment lengths >= 2, got {steps}", value=steps)
    if "dt" in d:
        dt = _num(d, "dt", positive=True)
    elif "operational_time" in d:
        dt = _num(d, "operational_time", positive=True) / sum(steps)
    else:
        raise InvalidInput("scene needs dt or operational_time", value=sorted(d))
    lim = d.get("limits") or {}
    for key in ("limits", "weights", "planner"):
        if not isinstance(d.get(key) or {}, dict):
            raise InvalidInput(f"scene key {key!r} must be a mapping, got {d.get(key)!r}", value=d.get(key))
    if not isinstance(d.get("obstacles") or [], list):
        raise InvalidInput(f"scene key 'obstacles' must be a list, got {d.get('obstacles')!r}",
                           value=d.get("obstacles"))
    if "velocity" in lim:
        vmax = _vector(lim["velocity"], n, "limits.velocity")
    else:
        vmax = robot.velocity_limit * _num(lim, "velocity_scale", 1.0)
    if "acceleration" in lim:
        amax = _vector(lim["acceleration"], n, "limits.acceleration")
    else:
        amax = robot.acceleration_limit * _num(lim, "acceleration_scale", 1.0)
    if np.any(vmax <= 0) or np.any(amax <= 0):
        raise LimitViolation(f"impossible limits: velocity and acceleration limits must be positive "
                             f"(got velocity {vmax}, acceleration {amax})", value=(vmax, amax))
    obstacles = []
    for k, o in enumerate(d.get("obstacles") or []):
        try:
            obstacles.append(obstacle_from_dict(o))
        except RobointelError as exc:
            raise InvalidInput(f"obstacle {k}: {exc}", value=o) from None
    table = d.get("table", True)
    if not isinstance(table, bool):
        raise InvalidInput(f"scene key 'table' must be true or false, got {table!r}", value=table)
    if table:
        obstacles += table_obstacles()
    weights = {"w1": 1.0, "w2": 0.02, "w3": 1.0, "w4": 1.0}
    for k in d.get("weights") or {}:
        if k not in weights:
            raise InvalidInput(f"unknown weight {k!r}; use w1, w2, w3, w4", value=k)
        weights[k] = _num(d["weights"], k)
        if weights[k] < 0:
            raise InvalidInput(f"weight {k} must be >= 0", value=weights[k])
    planner = dict(d.get("planner") or {})
    known = set(PlannerSettings.__dataclass_fields__)
    unknown = set(planner) - known
    if unknown:
        raise InvalidInput(f"unknown planner settings {sorted(unknown)}; known: {sorted(known)}", value=planner)
    return Scene(name=str(d.get("name", "scene")), robot=robot, waypoints=Wa, waypoint_names=names, steps=steps,
                 dt=dt, obstacles=obstacles, vmax=np.asarray(vmax, float), amax=np.asarray(amax, float),
                 d_min=_num(d, "d_min", 0.05, positive=True), weights=weights, planner=planner,
                 description=str(d.get("description", "")), table=table)


def load_scene(path_or_name: str | Path) -> Scene:
    """Read a scene YAML file, or a built-in scene by name (``"table71"``)."""
    p = Path(path_or_name)
    if not p.exists():
        cand = SCENES / f"{path_or_name}.yaml"
        if cand.exists():
            p = cand
        else:
            raise InvalidInput(f"scene {str(path_or_name)!r} is neither a file nor a built-in scene "
                               f"({', '.join(builtin_scenes())})", value=str(path_or_name))
    s = scene_from_dict(read_scene_file(p), base=p.parent)
    s.source = p
    return s
