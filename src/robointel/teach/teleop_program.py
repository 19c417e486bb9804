"""Teleoperated programs as files.

The waypoints recorded on the teleoperation page are saved as a YAML planning scene (robot,
obstacles, stop-by waypoints) that ``robointel plan`` loads, and read back.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robointel._validate import as_array
from robointel.errors import InvalidInput

if TYPE_CHECKING:  # pragma: no cover
    from robointel.robot import Robot

__all__ = ["PROGRAM_FORMAT", "load_program", "save_program", "shape_to_dict"]

PROGRAM_FORMAT = "robointel-scene/1"


# ----------------------------------------------------------------------------- program files
def shape_to_dict(shape: Any) -> dict[str, Any]:
    """Return the scene-file dict of an obstacle (``robointel.geometry`` shapes use their own ``to_dict``).

    Args:
        shape: The obstacle.

    Returns:
        Plain data with ``type`` and ``name``.
    """
    if hasattr(shape, "to_dict"):  # robointel.geometry obstacles: the scene format's own dict
        return shape.to_dict()
    kind = type(shape).__name__.lower()
    d: dict[str, Any] = {"type": kind, "name": getattr(shape, "name", None) or kind}
    for key in ("center", "radius", "a", "b", "size"):
        if hasattr(shape, key):
            v = getattr(shape, key)
            d[key] = float(v) if np.ndim(v) == 0 else np.asarray(v, float).tolist()
    if kind == "box" and hasattr(shape, "rotation"):
        d["rotation"] = np.asarray(shape.rotation, float).tolist()
    return d


def save_program(path: str | Path, robot: Robot, waypoints: Sequence[npt.ArrayLike], *, obstacles: Sequence[Any] = (),
                 name: str = "teleop_program", speed_scale: float = 0.3, steps: int = 19) -> Path:
    """Write a teleoperated program as a planning scene (``robointel.io.scene`` YAML, loadable by ``robointel plan``).

    The file holds ``robot``, ``obstacles`` (robointel.geometry dicts), stop-by ``waypoints``
    (each ``{name, q [rad], tcp: {position [m], quaternion [w, x, y, z]}}``, the TCP pose from FK),
    ``steps`` per segment, ``limits`` (``speed_scale`` of the robot's), and an ``operational_time``
    long enough for the largest joint move of each segment at that speed.

    Args:
        path: the YAML file to write.
        robot: the robot the waypoints belong to.
        waypoints: m >= 2 joint positions, each (n,), rad.
        obstacles: robointel.geometry shapes of the scene.
        name: the program's name.
        speed_scale: share of the robot's velocity and acceleration limits the program plans with.
        steps: planning steps per segment.

    Returns:
        The path written.

    Raises:
        InvalidInput: fewer than 2 waypoints, or a waypoint of the wrong size / outside the limits.
    """
    import yaml
    from scipy.spatial.transform import Rotation

    if len(waypoints) < 2:
        raise InvalidInput(f"the program has {len(waypoints)} waypoint(s); record at least 2 (start and goal) "
                           "for a plannable program")
    wps = []
    for i, q in enumerate(waypoints):
        q = robot.check_q(q, f"waypoints[{i}]", limits=True)
        T = robot.fk(q)
        x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
        wps.append({"name": f"wp{i}", "q": [float(v) for v in q],
                    "tcp": {"position": [float(v) for v in T[:3, 3]],
                            "quaternion": [float(w), float(x), float(y), float(z)]}})
    W = np.array([w["q"] for w in wps])
    seg = [max(1.0, 2.0 * float(np.max(np.abs(b - a) / (speed_scale * robot.velocity_limit))))
           for a, b in zip(W[:-1], W[1:])]
    doc = {"name": name, "description": f"taught by browser teleoperation ({PROGRAM_FORMAT})",
           "robot": robot.name, "operational_time": round(float(sum(seg)), 3), "steps": int(steps),
           "d_min": 0.05, "limits": {"velocity_scale": speed_scale, "acceleration_scale": speed_scale},
           "obstacles": [shape_to_dict(o) for o in obstacles], "waypoints": wps}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))
    return path


def load_program(path: str | Path) -> dict[str, Any]:
    """Read the waypoints of a program written by :func:`save_program` (or of any scene whose waypoints give ``q``).

    ``robointel.planning.scene.load_scene`` reads the full scene.

    Args:
        path: the YAML file.

    Returns:
        A dict with ``robot``, ``obstacles`` (dicts), ``waypoints`` (an (m, n) array of joint
        positions, rad) and ``names``.

    Raises:
        InvalidInput: not a program/scene file or malformed waypoints.
    """
    import yaml

    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise InvalidInput(f"cannot read program {path}: {exc}", value=str(path)) from None
    if not isinstance(doc, dict) or "waypoints" not in doc:
        raise InvalidInput(f"{path} has no 'waypoints'", value=str(path))
    try:
        W = np.array([w["q"] for w in doc["waypoints"]], dtype=float)
    except (KeyError, TypeError, ValueError):
        raise InvalidInput(f"{path}: every waypoint needs a numeric 'q' list", value=str(path)) from None
    W = as_array(W, "waypoints", (None, None))
    return {"robot": doc.get("robot", "lrmate200id7l"), "obstacles": doc.get("obstacles", []), "waypoints": W,
            "names": [w.get("name", f"wp{i}") for i, w in enumerate(doc["waypoints"])]}
