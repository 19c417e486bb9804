"""The steps of a task program and their arguments: parsing and validation (see :mod:`robointel.program.format`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robointel.errors import InvalidInput
from robointel.geometry.rotations import rpy_to_matrix

STEP_KINDS = ("move", "path", "wait", "set_io", "grasp", "place", "insert", "grind", "guide")
SKILL_KINDS = {"insert": "insertion", "grind": "grinding"}  # step kind -> the skill file's kind
#: ``insert`` options and defaults: time limit (s; None: the skill file's, 15 s for the felt skill, 10 s for the
#: GMR skill), the station's diametral fit clearance (mm), the start pose error bounds of the part at the station
#: (lateral per axis, mm; tilt, deg). The defaults are the learning benchmark's task (20 um, +-2 mm, 5 deg), not a
#: calibrated cell's.
INSERT_OPTIONS: dict[str, float | None] = {"time_limit": None, "clearance_mm": 0.02, "lateral_error_mm": 2.0,
                                           "tilt_error_deg": 5.0}
OBJECT_CATEGORIES = ("cup", "can", "box", "ball", "long_tool")
#: ``set_io`` outputs that take 0 or 1 only, and what the values mean.
DIGITAL_OUTPUTS = {"gripper": "1 closes the fingers, 0 opens them"}

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
            body = {k: (str(v) if k == "skill" else v) for k, v in self.args.items() if v is not None}
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
        ycb: Name of a YCB scan (``../shared/data/objects/ycb/<name>``) to place instead of a generated
            instance, or None.
    """

    category: str
    seed: int = 0
    at: tuple[float, float] | None = None
    yaw: float | None = None
    ycb: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the YAML file."""
        d: dict[str, Any] = {"category": self.category, "seed": self.seed}
        if self.at is not None:
            d["at"] = list(self.at)
        if self.yaw is not None:
            d["yaw_deg"] = float(np.degrees(self.yaw))
        if self.ycb is not None:
            d["ycb"] = self.ycb
        return d


def parse_object(d: Any, i: int) -> TableObject:
    """Read one ``objects`` entry (see the module docstring).

    Raises:
        InvalidInput: Unknown category or key, ill-typed position.
    """
    where = f"object {i}"
    if not isinstance(d, Mapping) or "category" not in d:
        raise InvalidInput(f"{where} must be a mapping with a category ({', '.join(OBJECT_CATEGORIES)})", value=d)
    unknown = set(d) - {"category", "seed", "at", "yaw_deg", "ycb"}
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
    ycb = d.get("ycb")
    if ycb is not None and (not isinstance(ycb, str) or not ycb or "/" in ycb or ycb.startswith(".")):
        raise InvalidInput(f"{where}: ycb must be the name of a YCB scan folder (e.g. 044_flat_screwdriver), "
                           f"got {ycb!r}", value=ycb)
    return TableObject(cat, int(seed), at, yaw, ycb)  # type: ignore[arg-type]



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
        opt: dict[str, float | None] = INSERT_OPTIONS if kind == "insert" else {"tolerance": 0.15, "speed": 0.03}
        if not isinstance(v, Mapping) or "skill" not in v or not isinstance(v["skill"], str):
            raise InvalidInput(f"{where}: {kind} needs {{skill: FILE}} (a skill file written by `robointel learn "
                               f"{SKILL_KINDS[kind]} --skill-out FILE`)", value=v)
        unknown = set(v) - {"skill", *opt}
        if unknown:
            raise InvalidInput(f"{where}: unknown {kind} keys {sorted(map(str, unknown))}", value=v)
        args: dict[str, Any] = {"skill": str(v["skill"])}
        for k, default in opt.items():
            given = v.get(k, default)
            args[k] = None if given is None else _number(given, f"{where}: {kind} {k}", strict="error" not in k)
        if kind == "insert" and args["clearance_mm"] >= 2.0:
            raise InvalidInput(f"{where}: insert clearance_mm must be below 2 mm, got {args['clearance_mm']!r}",
                               value=args["clearance_mm"])
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
            if str(k) in DIGITAL_OUTPUTS and outs[str(k)] not in (0.0, 1.0):
                raise InvalidInput(f"{where}: output {k!r} is digital ({DIGITAL_OUTPUTS[str(k)]}): give 0 or 1, "
                                   f"got {x!r}", value=x)
        return Step("set_io", name, {"outputs": outs})
    raise InvalidInput(f"{where}: unknown step kind {kind!r}; use one of {', '.join(STEP_KINDS)}", value=kind)
