"""The task-program file: a YAML list of steps over a scene (the robot, its obstacles and limits).

A program joins what robointel teaches, learns and plans into one job. The format
(``format: robointel.program/1``)::

    format: robointel.program/1
    name: pick-and-inspect
    scene: table71                # a scene file or built-in scene name, or an inline scene mapping
                                  # (robot, obstacles, limits, d_min, planner, weights: see planning/scene.py);
                                  # the scene's waypoints become named waypoints of the program
    waypoints:                    # more named targets: q (rad), q_deg (deg) or pose {xyz, rpy_deg}
      above_pick: {q_deg: [35, 40, -15, 0, -30, 0]}
    steps:
      - move: home                # a named waypoint ...
      - move: {q_deg: [0, 10, -20, 0, -60, 0]}          # ... a joint configuration ...
        name: clear               # every step may carry a name (default: "<index>:<kind>")
      - move: {pose: {xyz: [0.45, 0.2, 0.3], rpy_deg: [0, 90, 0]}}   # ... or a TCP pose (IK)
      - path: {points: [[0.45, 0.2, 0.3], [0.45, -0.1, 0.3]], speed: 0.1}   # TCP path via key points
      - wait: 0.5                 # s
      - set_io: {gripper: 1}      # digital outputs
      - grasp: {category: cup}    # perceive, classify, transfer a taught grasp, approach, close, lift, verify
      - place: {at: [0.45, -0.30]}   # carry the held object (planned around the scene), set it down there
    objects:                      # objects on the table of the simulated cell (generated instances)
      - {category: cup, seed: 3}                        # at a random placement (the run's seed) ...
      - {category: ball, seed: 1, at: [0.5, 0.1], yaw_deg: 30}   # ... or at a given one (m, deg)

      - insert: {skill: peg.skill.h5, time_limit: 10}   # a learned insertion skill (skill file, s)
      - grind: {skill: grind.skill.h5, tolerance: 0.25}  # a learned grinding skill (force RMS / peak allowed)
      - guide: {timeout: 60}      # lead-through with collision avoidance until the operator presses continue

Unknown step kinds, unknown keys and ill-typed values raise :class:`robointel.errors.InvalidInput`
naming the step. Skill files are resolved against the program file's folder. ``grasp`` and ``place``
need a cell with the gripper and the objects (:class:`robointel.program.GraspCell`); ``guide`` a cell
with an F/T sensor (:class:`robointel.program.SimCell`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from robointel.errors import InvalidInput, RobointelError
from robointel.geometry.rotations import rpy_to_matrix
from robointel.planning.scene import Scene, load_scene, scene_from_dict
from robointel.robot import Robot

FORMAT = "robointel.program/1"
EXAMPLES = Path(__file__).resolve().parent / "examples"
STEP_KINDS = ("move", "path", "wait", "set_io", "grasp", "place", "insert", "grind", "guide")
SKILL_KINDS = {"insert": "insertion", "grind": "grinding"}  # step kind -> the skill file's kind
OBJECT_CATEGORIES = ("cup", "can", "box", "ball", "long_tool")


@dataclass(frozen=True)
class Target:
    """Where a ``move`` goes: a named waypoint, a joint configuration or a TCP pose.

    Attributes:
        waypoint: Name of a program waypoint, or None.
        q: (n,) joint configuration in rad, or None.
        pose: (4, 4) homogeneous TCP pose in the robot's base frame (m), or None.
    """

    waypoint: str | None = None
    q: np.ndarray | None = None
    pose: np.ndarray | None = None

    def to_dict(self) -> Any:
        """Plain data, inverse of :func:`parse_target`."""
        if self.waypoint is not None:
            return self.waypoint
        if self.q is not None:
            return {"q_deg": np.degrees(self.q).round(6).tolist()}
        assert self.pose is not None
        return {"pose": {"matrix": np.asarray(self.pose).round(9).tolist()}}


@dataclass(frozen=True)
class Step:
    """One step of a program.

    Attributes:
        kind: One of :data:`STEP_KINDS`.
        name: Unique name of the step (used by ``--from`` and in error messages).
        args: The kind's arguments (validated at load time).
    """

    kind: str
    name: str
    args: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the YAML file."""
        if self.kind == "move":
            body: Any = self.args["target"].to_dict()
        elif self.kind == "path":
            body = {"points": np.asarray(self.args["points"]).round(9).tolist(), "speed": self.args["speed"],
                    "tolerance": self.args["tolerance"]}
        elif self.kind == "wait":
            body = self.args["seconds"]
        elif self.kind == "grasp":
            body = {"category": self.args["category"]}
        elif self.kind == "place":
            body = {"at": list(self.args["at"])}
        elif self.kind in SKILL_KINDS:
            body = {k: (str(v) if k == "skill" else v) for k, v in self.args.items()}
        elif self.kind == "guide":
            body = {"timeout": self.args["timeout"]}
        else:
            body = dict(self.args["outputs"])
        return {self.kind: body, "name": self.name}


@dataclass(frozen=True)
class TableObject:
    """An object on the table of the simulated cell: a generated instance of a category.

    Attributes:
        category: One of :data:`OBJECT_CATEGORIES`.
        seed: Seed of the generated instance (its shape and size).
        at: (x, y) position on the table in m, or None for a random placement drawn by the run's seed.
        yaw: Heading in rad (None: random).
    """

    category: str
    seed: int = 0
    at: tuple[float, float] | None = None
    yaw: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the YAML file."""
        d: dict[str, Any] = {"category": self.category, "seed": self.seed}
        if self.at is not None:
            d["at"] = list(self.at)
        if self.yaw is not None:
            d["yaw_deg"] = float(np.degrees(self.yaw))
        return d


def parse_object(d: Any, i: int) -> TableObject:
    """Read one ``objects`` entry (see the module docstring).

    Raises:
        InvalidInput: Unknown category or key, ill-typed position.
    """
    where = f"object {i}"
    if not isinstance(d, Mapping) or "category" not in d:
        raise InvalidInput(f"{where} must be a mapping with a category ({', '.join(OBJECT_CATEGORIES)})", value=d)
    unknown = set(d) - {"category", "seed", "at", "yaw_deg"}
    if unknown:
        raise InvalidInput(f"{where}: unknown keys {sorted(map(str, unknown))}", value=d)
    cat = str(d["category"])
    if cat not in OBJECT_CATEGORIES:
        raise InvalidInput(f"{where}: unknown category {cat!r}; use one of {', '.join(OBJECT_CATEGORIES)}", value=cat)
    seed = d.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise InvalidInput(f"{where}: seed must be an integer, got {seed!r}", value=seed)
    at = None if d.get("at") is None else tuple(float(x) for x in _vec(d["at"], 2, f"{where}.at"))
    yaw = None if d.get("yaw_deg") is None else float(np.radians(_number(d["yaw_deg"], f"{where}.yaw_deg",
                                                                          minimum=-np.inf)))
    return TableObject(cat, int(seed), at, yaw)  # type: ignore[arg-type]


@dataclass
class Program:
    """A task program: a scene, named waypoints and the steps to run.

    Attributes:
        name: Program name.
        scene: The :class:`robointel.planning.scene.Scene` it runs in (robot, obstacles, limits, d_min).
        waypoints: Named joint configurations (rad), each (n,).
        steps: The steps in order.
        objects: Objects on the table of the simulated cell (for ``grasp`` and ``place`` steps).
        source: The file it was read from, if any.
        scene_ref: How the scene was given (a name/path string or an inline mapping), for saving.
    """

    name: str
    scene: Scene
    waypoints: dict[str, np.ndarray]
    steps: list[Step]
    objects: list[TableObject] = field(default_factory=list)
    source: Path | None = None
    scene_ref: Any = None

    @property
    def robot(self) -> Robot:
        """The robot the program drives."""
        return self.scene.robot  # type: ignore[no-any-return]

    def index(self, step: str | int) -> int:
        """Return the index of a step given by name or index.

        Raises:
            InvalidInput: No such step.
        """
        if isinstance(step, int) or (isinstance(step, str) and step.isdigit()):
            i = int(step)
            if not 0 <= i < len(self.steps):
                raise InvalidInput(f"step index {i} outside 0..{len(self.steps) - 1}", value=step)
            return i
        for i, s in enumerate(self.steps):
            if s.name == step:
                return i
        raise InvalidInput(f"no step named {step!r}; steps: {[s.name for s in self.steps]}", value=step)

    def initial_configuration(self, start: int = 0) -> np.ndarray:
        """Return where a simulated robot starts a run from step ``start``.

        That is the first joint-space move target at or after it (a named waypoint or a configuration),
        else the program's first waypoint.

        Raises:
            InvalidInput: The program names no joint configuration to start from.
        """
        for s in self.steps[start:]:
            if s.kind == "move":
                t = s.args["target"]
                if t.waypoint is not None and t.waypoint in self.waypoints:
                    return np.asarray(self.waypoints[t.waypoint], float).copy()
                if t.q is not None:
                    return np.asarray(t.q, float).copy()
        if self.waypoints:
            return np.asarray(next(iter(self.waypoints.values())), float).copy()
        raise InvalidInput("the program names no joint configuration to start a simulated robot at", value=self.name)

    def to_dict(self) -> dict[str, Any]:
        """Plain data, inverse of :func:`program_from_dict`."""
        scene = self.scene_ref if self.scene_ref is not None else _scene_dict(self.scene)
        return {"format": FORMAT, "name": self.name, "scene": scene,
                "waypoints": {k: {"q_deg": np.degrees(v).round(6).tolist()} for k, v in self.waypoints.items()},
                "steps": [s.to_dict() for s in self.steps],
                **({"objects": [o.to_dict() for o in self.objects]} if self.objects else {})}

    def save(self, path: str | Path) -> Path:
        """Write the program as YAML and return the path."""
        p = Path(path)
        p.write_text(yaml.safe_dump(self.to_dict(), sort_keys=False))
        return p


def _scene_dict(scene: Scene) -> dict[str, Any]:
    d = scene.to_dict()
    d.pop("waypoints", None)
    d.pop("steps", None)
    d.pop("dt", None)
    return d


def _vec(v: Any, n: int, what: str) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInput(f"{what} must be a list of {n} numbers, got {v!r}", value=v) from None
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise InvalidInput(f"{what} must be {n} finite numbers, got {v!r}", value=v)
    return a


def _pose(p: Any, what: str) -> np.ndarray:
    if not isinstance(p, Mapping):
        raise InvalidInput(f"{what} must be a mapping with xyz and rpy_deg (or matrix), got {p!r}", value=p)
    if "matrix" in p:
        T = np.asarray(p["matrix"], dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise InvalidInput(f"{what}.matrix must be a finite 4x4 matrix", value=p["matrix"])
        return T
    T = np.eye(4)
    T[:3, 3] = _vec(p.get("xyz"), 3, f"{what}.xyz")
    if "rpy_deg" in p:
        T[:3, :3] = rpy_to_matrix(np.radians(_vec(p["rpy_deg"], 3, f"{what}.rpy_deg")))
    elif "rpy" in p:
        T[:3, :3] = rpy_to_matrix(_vec(p["rpy"], 3, f"{what}.rpy"))
    unknown = set(p) - {"xyz", "rpy_deg", "rpy"}
    if unknown:
        raise InvalidInput(f"{what}: unknown keys {sorted(unknown)}", value=p)
    return T


def parse_target(v: Any, n: int, what: str) -> Target:
    """Read a move target: a waypoint name, ``{q: ...}``, ``{q_deg: ...}`` or ``{pose: ...}``.

    Args:
        v: The parsed YAML value.
        n: Number of robot joints.
        what: Where it came from, for error messages.

    Returns:
        The :class:`Target`.

    Raises:
        InvalidInput: Anything else.
    """
    if isinstance(v, str):
        return Target(waypoint=v)
    if isinstance(v, Mapping):
        keys = set(v)
        if keys == {"q"}:
            return Target(q=_vec(v["q"], n, f"{what}.q"))
        if keys == {"q_deg"}:
            return Target(q=np.radians(_vec(v["q_deg"], n, f"{what}.q_deg")))
        if keys == {"pose"}:
            return Target(pose=_pose(v["pose"], f"{what}.pose"))
    raise InvalidInput(f"{what} must be a waypoint name or one of {{q: [...]}}, {{q_deg: [...]}}, "
                       f"{{pose: {{xyz, rpy_deg}}}}; got {v!r}", value=v)


def _number(v: Any, what: str, *, minimum: float = 0.0, strict: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise InvalidInput(f"{what} must be a finite number, got {v!r}", value=v)
    if v < minimum or (strict and v == minimum):
        raise InvalidInput(f"{what} must be {'>' if strict else '>='} {minimum}, got {v!r}", value=v)
    return float(v)


def parse_step(d: Any, i: int, n: int) -> Step:
    """Read one step mapping (see the module docstring).

    Args:
        d: The parsed YAML mapping of the step.
        i: Its index in the program.
        n: Number of robot joints.

    Returns:
        The validated :class:`Step`.

    Raises:
        InvalidInput: Unknown kind or key, ill-typed argument (the message names the step).
    """
    if not isinstance(d, Mapping):
        raise InvalidInput(f"step {i} must be a mapping like {{move: home}}, got {d!r}", value=d)
    kinds = [k for k in d if k != "name"]
    if len(kinds) != 1:
        raise InvalidInput(f"step {i} must have exactly one kind ({', '.join(STEP_KINDS)}) besides its name, "
                           f"got {sorted(map(str, d))}", value=d)
    kind = str(kinds[0])
    name = str(d.get("name", f"{i}:{kind}"))
    where = f"step {i} ({name!r})"
    v = d[kind]
    if kind in SKILL_KINDS:
        opt = {"insert": {"time_limit": 10.0}, "grind": {"tolerance": 0.25, "speed": 0.03}}[kind]
        if not isinstance(v, Mapping) or "skill" not in v or not isinstance(v["skill"], str):
            raise InvalidInput(f"{where}: {kind} needs {{skill: FILE}} (a skill file written by `robointel learn "
                               f"{SKILL_KINDS[kind]} --skill-out FILE`)", value=v)
        unknown = set(v) - {"skill", *opt}
        if unknown:
            raise InvalidInput(f"{where}: unknown {kind} keys {sorted(map(str, unknown))}", value=v)
        args: dict[str, Any] = {"skill": str(v["skill"])}
        for k, default in opt.items():
            args[k] = _number(v.get(k, default), f"{where}: {kind} {k}", strict=True)
        return Step(kind, name, args)
    if kind == "guide":
        if v is None:
            v = {}
        if not isinstance(v, Mapping) or set(v) - {"timeout"}:
            raise InvalidInput(f"{where}: guide takes {{timeout: SECONDS}} (how long the operator may guide)", value=v)
        return Step("guide", name, {"timeout": _number(v.get("timeout", 60.0), f"{where}: guide timeout",
                                                       strict=True)})
    if kind == "move":
        return Step("move", name, {"target": parse_target(v, n, where)})
    if kind == "path":
        if not isinstance(v, Mapping) or "points" not in v:
            raise InvalidInput(f"{where}: path needs {{points: [[x, y, z], ...]}}", value=v)
        unknown = set(v) - {"points", "speed", "tolerance"}
        if unknown:
            raise InvalidInput(f"{where}: unknown path keys {sorted(unknown)}", value=v)
        try:
            P = np.asarray(v["points"], dtype=float)
        except (TypeError, ValueError):
            raise InvalidInput(f"{where}: path points must be [[x, y, z], ...] in m", value=v["points"]) from None
        if P.ndim != 2 or P.shape[1] != 3 or len(P) < 2 or not np.all(np.isfinite(P)):
            raise InvalidInput(f"{where}: path points must be >= 2 finite [x, y, z] rows in m, got shape "
                               f"{P.shape}", value=v["points"])
        speed = _number(v.get("speed", 0.1), f"{where}: path speed", strict=True)
        tol = _number(v.get("tolerance", 0.005), f"{where}: path tolerance", strict=True)
        return Step("path", name, {"points": P, "speed": speed, "tolerance": tol})
    if kind == "wait":
        return Step("wait", name, {"seconds": _number(v, f"{where}: wait seconds")})
    if kind == "grasp":
        if not isinstance(v, Mapping) or set(v) != {"category"} or str(v["category"]) not in OBJECT_CATEGORIES:
            raise InvalidInput(f"{where}: grasp needs {{category: C}} with C one of {', '.join(OBJECT_CATEGORIES)}",
                               value=v)
        return Step("grasp", name, {"category": str(v["category"])})
    if kind == "place":
        if not isinstance(v, Mapping) or set(v) != {"at"}:
            raise InvalidInput(f"{where}: place needs {{at: [x, y]}} (m, on the table)", value=v)
        return Step("place", name, {"at": tuple(float(x) for x in _vec(v["at"], 2, f"{where}: place at"))})
    if kind == "set_io":
        if not isinstance(v, Mapping) or not v:
            raise InvalidInput(f"{where}: set_io needs a mapping of output names to values", value=v)
        outs: dict[str, float] = {}
        for k, x in v.items():
            outs[str(k)] = _number(float(x) if isinstance(x, bool) else x, f"{where}: output {k!r}",
                                   minimum=-np.inf)
        return Step("set_io", name, {"outputs": outs})
    raise InvalidInput(f"{where}: unknown step kind {kind!r}; use one of {', '.join(STEP_KINDS)}", value=kind)


def _load_scene(ref: Any, base: Path | None) -> Scene:
    if isinstance(ref, str):
        p = Path(ref)
        if base is not None and not p.is_absolute() and (base / p).exists():
            p = base / p
        return load_scene(p if p.exists() else ref)
    if isinstance(ref, Mapping):
        d = dict(ref)
        if "robot" not in d:
            raise InvalidInput("the program's inline scene needs a robot", value=sorted(d))
        if "waypoints" not in d:
            robot = Robot.load(str(d["robot"]))
            mid = np.clip(np.zeros(robot.nq), robot.lower, robot.upper)
            d["waypoints"] = [{"name": "_a", "q": mid.tolist()}, {"name": "_b", "q": mid.tolist()}]
        d.setdefault("steps", 2)
        if "dt" not in d and "operational_time" not in d:
            d["dt"] = 0.1
        return scene_from_dict(d, base=base)
    raise InvalidInput(f"program scene must be a scene name, a file or a mapping, got {ref!r}", value=ref)


def program_from_dict(d: Any, *, base: Path | None = None) -> Program:
    """Build a :class:`Program` from parsed YAML (see the module docstring).

    Args:
        d: The parsed mapping.
        base: Folder that relative scene paths are resolved against.

    Returns:
        The validated program (targets are resolved to joints only by :func:`robointel.program.check_program`).

    Raises:
        InvalidInput: A missing or ill-typed key; the message names the step or waypoint.
    """
    if not isinstance(d, Mapping):
        raise InvalidInput(f"a program must be a mapping, got {type(d).__name__}", value=d)
    fmt = d.get("format", FORMAT)
    if fmt != FORMAT:
        raise InvalidInput(f"unknown program format {fmt!r}; this robointel reads {FORMAT!r}", value=fmt)
    unknown = set(d) - {"format", "name", "scene", "waypoints", "steps", "description", "objects"}
    if unknown:
        raise InvalidInput(f"unknown program keys {sorted(map(str, unknown))}", value=sorted(map(str, unknown)))
    if "scene" not in d:
        raise InvalidInput("a program needs a scene (a scene name, file or mapping)", value=sorted(d))
    try:
        scene = _load_scene(d["scene"], base)
    except RobointelError as exc:
        raise InvalidInput(f"program scene: {exc}", value=d["scene"]) from None
    n = scene.robot.nq
    waypoints: dict[str, np.ndarray] = {}
    if not (len(scene.waypoint_names) == 2 and scene.waypoint_names[0] == "_a"):
        waypoints.update({nm: q for nm, q in zip(scene.waypoint_names, scene.waypoints)})
    wps = d.get("waypoints") or {}
    if not isinstance(wps, Mapping):
        raise InvalidInput("program waypoints must be a mapping name -> {q | q_deg | pose}", value=wps)
    poses: dict[str, np.ndarray] = {}
    for k, v in wps.items():
        t = parse_target(v, n, f"waypoint {k!r}")
        if t.waypoint is not None:
            raise InvalidInput(f"waypoint {k!r} must be a configuration or pose, not another name", value=v)
        if t.q is not None:
            waypoints[str(k)] = t.q
        else:
            assert t.pose is not None
            poses[str(k)] = t.pose
    raw = d.get("steps")
    if not isinstance(raw, list) or not raw:
        raise InvalidInput("a program needs a non-empty list of steps", value=raw)
    steps = [parse_step(s, i, n) for i, s in enumerate(raw)]
    names = [s.name for s in steps]
    dup = sorted({x for x in names if names.count(x) > 1})
    if dup:
        raise InvalidInput(f"step names must be unique; repeated: {dup}", value=dup)
    # a pose waypoint becomes a pose target wherever it is used
    steps = [Step(s.kind, s.name, {"target": Target(pose=poses[s.args["target"].waypoint])})
             if s.kind == "move" and s.args["target"].waypoint in poses else s for s in steps]
    objs = d.get("objects") or []
    if not isinstance(objs, list):
        raise InvalidInput("program objects must be a list of {category, seed, at, yaw_deg}", value=objs)
    objects = [parse_object(o, i) for i, o in enumerate(objs)]
    for s in steps:
        if s.kind == "grasp" and s.args["category"] not in {o.category for o in objects}:
            raise InvalidInput(f"step {s.name!r}: no object of category {s.args['category']!r} in the program's "
                               f"objects ({sorted({o.category for o in objects})})", value=s.args["category"])
    return Program(name=str(d.get("name", "program")), scene=scene, waypoints=waypoints, steps=steps,
                   objects=objects, scene_ref=d["scene"])


def builtin_programs() -> list[str]:
    """Names of the programs shipped with robointel (``robointel run NAME``)."""
    return sorted(p.stem for p in EXAMPLES.glob("*.yaml"))


def load_program(path: str | Path) -> Program:
    """Read a program YAML file.

    Args:
        path: The file, or the name of a built-in program (:func:`builtin_programs`).

    Returns:
        The validated :class:`Program`.

    Raises:
        InvalidInput: The file is missing, not YAML, or not a valid program.
    """
    p = Path(path)
    builtin = EXAMPLES / f"{path}.yaml"
    if not p.is_file() and builtin.is_file():
        p = builtin
    if not p.is_file():
        raise InvalidInput(f"program file {str(path)!r} not found (built-in programs: {', '.join(builtin_programs())})",
                           value=str(path))
    try:
        d = yaml.safe_load(p.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise InvalidInput(f"{p}: not a valid YAML program: {exc}", value=str(p)) from None
    prog = program_from_dict(d, base=p.parent)
    prog.source = p
    return prog
