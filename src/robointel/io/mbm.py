"""MotionBenchMaker (MBM) planning problems: read ``problems.json`` into typed dataclasses.

The format (as published with the VAMP planner): ``{"robot": str, "joints": [str, ...],
"problems": {family: [problem, ...]}}``; each problem is ``{"index", "problem", "valid", "start",
"goals", "sphere", "box", "cylinder"}`` with obstacles in the robot's URDF frame (metres, radians):

* sphere: ``{name, position, radius}``;
* box: ``{name, position, half_extents, orientation_euler_xyz, orientation_quat_xyzw}``;
* cylinder: ``{name, position, length, radius, orientation_...}``, axis along the local z axis,
  centred on ``position``.

Obstacles become :mod:`robointel.geometry` shapes: a box's ``size`` is twice the half extents and
its rotation comes from the quaternion (the Euler angles, ``Rz Ry Rx``, must agree with it); a
cylinder becomes the end points ``position -/+ (length / 2) z_axis``.
"""
from __future__ import annotations

import json
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput
from robointel.geometry.obstacles import Box, Cylinder, Obstacle, Sphere
from robointel.geometry.rotations import quat_to_matrix, rpy_to_matrix

__all__ = ["MBMProblem", "MBMProblemSet", "load_mbm_problems", "MBM_FAMILIES"]

MBM_FAMILIES: tuple[str, ...] = ("table_pick", "table_under_pick", "box", "bookshelf_small", "bookshelf_tall",
                                 "bookshelf_thin", "cage")
_TOP_KEYS = frozenset({"robot", "joints", "problems"})
_PROBLEM_KEYS = frozenset({"index", "problem", "valid", "start", "goals", "sphere", "box", "cylinder"})
_ORIENT = frozenset({"orientation_euler_xyz", "orientation_quat_xyzw"})
_OBSTACLE_KEYS: dict[str, tuple[frozenset[str], frozenset[str]]] = {
    # kind: (required keys, optional keys)
    "sphere": (frozenset({"position", "radius"}), frozenset({"name"}) | _ORIENT),
    "box": (frozenset({"position", "half_extents"}), frozenset({"name"}) | _ORIENT),
    "cylinder": (frozenset({"position", "length", "radius"}), frozenset({"name"}) | _ORIENT),
}
_ROT_TOL = 1e-6


@dataclass(frozen=True)
class MBMProblem:
    """One MBM problem.

    Attributes:
        family: scene family, e.g. ``"cage"``.
        index: the problem's index within its family (1-based in the published files).
        valid: the published flag: start and goals are collision-free and the problem is solvable.
        start: start configuration (n,) rad.
        goals: goal configurations (k, n) rad; reaching any one of them solves the problem.
        obstacles: the scene's obstacles, in the robot's URDF frame.
        joint_names: the n joint names the configurations refer to.
    """

    family: str
    index: int
    valid: bool
    start: npt.NDArray[np.float64]
    goals: npt.NDArray[np.float64]
    obstacles: tuple[Obstacle, ...]
    joint_names: tuple[str, ...]

    @property
    def goal(self) -> npt.NDArray[np.float64]:
        """The first goal configuration (n,) rad."""
        return self.goals[0]

    @property
    def name(self) -> str:
        """``"family/index"``, for messages and tables."""
        return f"{self.family}/{self.index}"


@dataclass(frozen=True)
class MBMProblemSet:
    """All problems of one ``problems.json``.

    Attributes:
        path: the file read.
        robot: the robot's name in the file (e.g. ``"ur5"``).
        joint_names: the joint names of every configuration.
        problems: every problem, family by family in file order.
    """

    path: Path
    robot: str
    joint_names: tuple[str, ...]
    problems: tuple[MBMProblem, ...]

    @property
    def families(self) -> tuple[str, ...]:
        """The families present, in file order."""
        return tuple(dict.fromkeys(p.family for p in self.problems))

    def select(self, *, families: Sequence[str] | None = None, valid_only: bool = True,
               per_family: int | None = None, index: int | None = None) -> list[MBMProblem]:
        """Problems filtered by family, validity, index, and at most ``per_family`` of each family.

        Args:
            families: family names to keep (None: all).
            valid_only: keep only problems flagged valid.
            per_family: keep the first this many (after the other filters) of each family.
            index: keep only the problem with this index.

        Returns:
            The selected problems in file order.

        Raises:
            InvalidInput: an unknown family name, or ``per_family`` < 1.
        """
        if families is not None:
            unknown = [f for f in families if f not in self.families]
            if unknown:
                raise InvalidInput(f"{self.path}: unknown family {unknown[0]!r}; the file has "
                                   f"{', '.join(self.families)}", value=unknown[0])
        if per_family is not None and per_family < 1:
            raise InvalidInput(f"per_family must be >= 1, got {per_family}", value=per_family)
        out: list[MBMProblem] = []
        count: dict[str, int] = {}
        for p in self.problems:
            if families is not None and p.family not in families:
                continue
            if valid_only and not p.valid:
                continue
            if index is not None and p.index != index:
                continue
            if per_family is not None and count.get(p.family, 0) >= per_family:
                continue
            count[p.family] = count.get(p.family, 0) + 1
            out.append(p)
        return out

    def __iter__(self) -> Iterator[MBMProblem]:
        return iter(self.problems)

    def __len__(self) -> int:
        return len(self.problems)


def _fail(path: Path, key: str, what: str, value: Any = None) -> InvalidInput:
    return InvalidInput(f"{path}: {key}: {what}", value=value)


def _vector(path: Path, key: str, x: Any, n: int | None) -> npt.NDArray[np.float64]:
    if not isinstance(x, list) or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in x):
        raise _fail(path, key, f"must be a list of numbers, got {x!r}", x)
    a = np.asarray(x, dtype=float)
    if n is not None and a.shape != (n,):
        raise _fail(path, key, f"must have {n} numbers, got {len(x)}", x)
    if not np.all(np.isfinite(a)):
        raise _fail(path, key, f"contains NaN or inf: {x!r}", x)
    return a


def _number(path: Path, key: str, x: Any, *, positive: bool = False) -> float:
    if not isinstance(x, int | float) or isinstance(x, bool) or not math.isfinite(x):
        raise _fail(path, key, f"must be a finite number, got {x!r}", x)
    if positive and not x > 0:
        raise _fail(path, key, f"must be positive (metres), got {x!r}", x)
    return float(x)


def _check_keys(path: Path, key: str, d: Any, required: frozenset[str], optional: frozenset[str]) -> None:
    if not isinstance(d, Mapping):
        raise _fail(path, key, f"must be a JSON object, got {type(d).__name__}", d)
    unknown = sorted(set(d) - required - optional)
    if unknown:
        raise _fail(path, f"{key}.{unknown[0]}", f"unknown key (expected {', '.join(sorted(required | optional))})",
                    unknown[0])
    missing = sorted(required - set(d))
    if missing:
        raise _fail(path, f"{key}.{missing[0]}", "missing key", missing[0])


def _rotation(path: Path, key: str, d: Mapping[str, Any]) -> npt.NDArray[np.float64]:
    R_quat = R_euler = None
    if "orientation_quat_xyzw" in d:
        x, y, z, w = _vector(path, f"{key}.orientation_quat_xyzw", d["orientation_quat_xyzw"], 4)
        nrm = math.sqrt(x * x + y * y + z * z + w * w)
        if abs(nrm - 1.0) > 1e-3:
            raise _fail(path, f"{key}.orientation_quat_xyzw", f"is not a unit quaternion (norm {nrm:.6g})",
                        d["orientation_quat_xyzw"])
        R_quat = quat_to_matrix(np.array([w, x, y, z]) / nrm)
    if "orientation_euler_xyz" in d:
        R_euler = rpy_to_matrix(_vector(path, f"{key}.orientation_euler_xyz", d["orientation_euler_xyz"], 3))
    if R_quat is not None and R_euler is not None and np.abs(R_quat - R_euler).max() > _ROT_TOL:
        raise _fail(path, f"{key}.orientation_euler_xyz", "disagrees with orientation_quat_xyzw",
                    d["orientation_euler_xyz"])
    R = R_quat if R_quat is not None else R_euler
    return np.eye(3) if R is None else np.asarray(R, dtype=float)


def _obstacle(path: Path, key: str, kind: str, d: Any) -> Obstacle:
    required, optional = _OBSTACLE_KEYS[kind]
    _check_keys(path, key, d, required, optional)
    name = d.get("name")
    if name is not None and not isinstance(name, str):
        raise _fail(path, f"{key}.name", f"must be a string, got {name!r}", name)
    p = _vector(path, f"{key}.position", d["position"], 3)
    R = _rotation(path, key, d)
    if kind == "sphere":
        return Sphere(p, _number(path, f"{key}.radius", d["radius"], positive=True), name=name)
    if kind == "box":
        half = _vector(path, f"{key}.half_extents", d["half_extents"], 3)
        if not np.all(half > 0):
            raise _fail(path, f"{key}.half_extents", f"must be positive (metres), got {half.tolist()}", half)
        return Box(p, 2.0 * half, R, name=name)
    length = _number(path, f"{key}.length", d["length"], positive=True)
    radius = _number(path, f"{key}.radius", d["radius"], positive=True)
    axis = R[:, 2] * (length / 2.0)
    return Cylinder(p - axis, p + axis, radius, name=name)


def _problem(path: Path, family: str, i: int, d: Any, joints: tuple[str, ...]) -> MBMProblem:
    key = f"problems.{family}[{i}]"
    _check_keys(path, key, d, _PROBLEM_KEYS - {"problem"}, frozenset({"problem"}))
    if "problem" in d and d["problem"] != family:
        raise _fail(path, f"{key}.problem", f"names family {d['problem']!r} inside family {family!r}", d["problem"])
    index = d["index"]
    if not isinstance(index, int) or isinstance(index, bool):
        raise _fail(path, f"{key}.index", f"must be an integer, got {index!r}", index)
    valid = d["valid"]
    if not isinstance(valid, bool):
        raise _fail(path, f"{key}.valid", f"must be true or false, got {valid!r}", valid)
    n = len(joints)
    start = _vector(path, f"{key}.start", d["start"], n)
    goals_raw = d["goals"]
    if not isinstance(goals_raw, list) or not goals_raw:
        raise _fail(path, f"{key}.goals", f"must be a non-empty list of configurations, got {goals_raw!r}", goals_raw)
    goals = np.stack([_vector(path, f"{key}.goals[{k}]", g, n) for k, g in enumerate(goals_raw)])
    obstacles: list[Obstacle] = []
    for kind in ("sphere", "box", "cylinder"):
        items = d[kind]
        if not isinstance(items, list):
            raise _fail(path, f"{key}.{kind}", f"must be a list, got {type(items).__name__}", items)
        obstacles += [_obstacle(path, f"{key}.{kind}[{k}]", kind, o) for k, o in enumerate(items)]
    start.flags.writeable = False
    goals.flags.writeable = False
    return MBMProblem(family=family, index=index, valid=valid, start=start, goals=goals,
                      obstacles=tuple(obstacles), joint_names=joints)


def load_mbm_problems(path: str | Path) -> MBMProblemSet:
    """Read an MBM ``problems.json`` (the VAMP / MotionBenchMaker export).

    Args:
        path: the JSON file.

    Returns:
        The problem set, every obstacle a :mod:`robointel.geometry` shape in the robot's URDF frame.

    Raises:
        InvalidInput: the file is missing or not JSON, or a key is unknown, missing or malformed
            (wrong type, wrong length, NaN/inf, non-positive size, inconsistent orientation); the
            message names the file and the key path, e.g. ``problems.cage[3].box[0].half_extents``.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidInput(f"{p}: cannot read the MBM problem file: {exc}", value=str(p)) from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InvalidInput(f"{p}: not valid JSON (line {exc.lineno}, column {exc.colno}): {exc.msg}",
                           value=str(p)) from None
    _check_keys(p, "<top>", data, _TOP_KEYS, frozenset())
    robot = data["robot"]
    if not isinstance(robot, str):
        raise _fail(p, "robot", f"must be a string, got {robot!r}", robot)
    joints_raw = data["joints"]
    if not isinstance(joints_raw, list) or not joints_raw or not all(isinstance(j, str) for j in joints_raw):
        raise _fail(p, "joints", f"must be a non-empty list of joint names, got {joints_raw!r}", joints_raw)
    joints = tuple(joints_raw)
    fams = data["problems"]
    if not isinstance(fams, Mapping):
        raise _fail(p, "problems", f"must map family names to lists, got {type(fams).__name__}", fams)
    problems: list[MBMProblem] = []
    for family, items in fams.items():
        if not isinstance(items, list):
            raise _fail(p, f"problems.{family}", f"must be a list of problems, got {type(items).__name__}", items)
        problems += [_problem(p, family, i, d, joints) for i, d in enumerate(items)]
    return MBMProblemSet(path=p, robot=robot, joint_names=joints, problems=tuple(problems))
