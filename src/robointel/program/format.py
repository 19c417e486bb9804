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
      - set_io: {gripper: 1}      # outputs (on a FANUC controller: numeric registers, {"R[10]": 1})
      - grasp: {category: cup}    # perceive, classify, transfer a taught grasp, approach, close, lift, verify
      - place: {at: [0.45, -0.30]}   # carry the held object (planned around the scene), set it down there
    objects:                      # objects on the table of the simulated cell (generated instances)
      - {category: cup, seed: 3}                        # at a random placement (the run's seed) ...
      - {category: ball, seed: 1, at: [0.5, 0.1], yaw_deg: 30}   # ... or at a given one (m, deg)
      - {category: long_tool, ycb: 044_flat_screwdriver}       # a YCB scan (../shared/data/objects/ycb)

      - insert: {skill: peg.skill.h5, time_limit: 10}   # a learned insertion skill (skill file, s) at a
                                  # station: clearance_mm (the fit), lateral_error_mm, tilt_error_deg (start
                                  # error bounds); defaults 0.02, 2, 5 (the learning benchmark's task)
      - grind: {skill: grind.skill.h5, tolerance: 0.15}  # a learned grinding skill (force RMS / peak allowed)
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
from robointel.planning.scene import Scene, load_scene, scene_from_dict
from robointel.program.step import (
    OBJECT_CATEGORIES,
    SKILL_KINDS,
    STEP_KINDS,
    Step,
    TableObject,
    Target,
    parse_object,
    parse_step,
    parse_target,
)
from robointel.robot import Robot

__all__ = ["EXAMPLES", "FORMAT", "OBJECT_CATEGORIES", "SKILL_KINDS", "STEP_KINDS", "Program", "Step", "TableObject",
           "Target", "builtin_programs", "load_program", "parse_object", "parse_step", "parse_target",
           "program_from_dict"]

FORMAT = "robointel.program/1"
EXAMPLES = Path(__file__).resolve().parent / "examples"


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
