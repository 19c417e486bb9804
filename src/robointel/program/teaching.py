"""Teaching writes programs: teleoperated waypoints become ``move`` steps, a guided path a ``path`` step.

* The teleoperation page saves its recorded waypoints as a planning scene
  (:func:`robointel.teach.teleop_program.save_program`); :func:`program_from_teleop` turns that
  file into a task program whose scene is the file (its obstacles and limits) and whose steps move through
  the waypoints in order.
* A path guided by hand (the ``guide`` step, lead-through) becomes a ``path`` step through its key points
  (:func:`robointel.teach.keypoints.extract_keypoints`: start, end, dwells, direction changes):
  :func:`path_step_from_guided`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput
from robointel.program.format import Program, program_from_dict
from robointel.program.step import Step
from robointel.robot import Robot
from robointel.teach.keypoints import extract_keypoints
from robointel.teach.teleop_program import load_program as load_teleop


def program_from_teleop(path: str | Path, *, name: str | None = None) -> Program:
    """A task program from a teleoperated program file: one ``move`` per recorded waypoint, in order.

    Args:
        path: The YAML file the teleoperation page saved (a planning scene with stop-by waypoints).
        name: The program's name (default: the file's stem).

    Returns:
        The program (scene = the file; its waypoints ``wp0``, ``wp1``, ... are the program's waypoints).

    Raises:
        InvalidInput: Not a teleoperated program / scene file with waypoints.
    """
    p = Path(path)
    doc = load_teleop(p)
    steps = [{"move": str(n), "name": f"to_{n}"} for n in doc["names"]]
    prog = program_from_dict({"name": name or p.stem, "scene": p.name, "steps": steps}, base=p.parent)
    prog.scene_ref = str(p.resolve())
    missing = [n for n in doc["names"] if n not in prog.waypoints]
    if missing:
        raise InvalidInput(f"{p}: waypoints {missing} did not load as program waypoints", value=missing)
    return prog


def path_step_from_guided(robot: Robot, t: npt.ArrayLike, q: npt.ArrayLike, *, name: str = "taught_path",
                          tolerance: float = 0.005, speed: float = 0.1) -> Step:
    """A ``path`` step through the key points of a guided joint path.

    Args:
        robot: The robot that was guided.
        t: (N,) time of each sample, s (strictly increasing).
        q: (N, n) guided joint positions, rad.
        name: The step's name.
        tolerance: How far (m) the reproduced TCP path may stray from the guided one (RDP tolerance).
        speed: TCP speed of the reproduction, m/s.

    Returns:
        The ``path`` step; its points (K, 3) are TCP positions in m, the first and last included.

    Raises:
        InvalidInput: Fewer than 2 samples, mismatched shapes, or a path that did not move.
    """
    T = np.asarray(t, float)
    Q = np.asarray(q, float)
    if Q.ndim != 2 or len(Q) != len(T) or len(T) < 2:
        raise InvalidInput(f"a guided path needs (N,) times and (N, n) joints with N >= 2, got {T.shape} and "
                           f"{Q.shape}", value=Q.shape)
    P = np.array([robot.fk(x)[:3, 3] for x in Q])
    if float(np.max(np.linalg.norm(P - P[0], axis=1))) < 1e-3:
        raise InvalidInput("the guided path did not move the TCP (less than 1 mm)", value=P[0])
    keep = np.r_[True, np.diff(T) > 0]
    idx = extract_keypoints(T[keep], P[keep], tolerance=tolerance)
    points = P[keep][idx]
    return Step("path", name, {"points": points, "speed": float(speed), "tolerance": float(tolerance)})
