"""Use an installed robointel as a user would: every file it ships, and a motion planned for an arm from its URDF.

Run by ``tools/wheel_check.py`` with the interpreter of a fresh virtual environment that holds only the wheel
and its dependencies, from a folder outside the repository. It prints one JSON object and exits 0 when
everything loaded and the motion was planned:

- ``robointel_file``: where ``robointel`` was imported from (must be inside that environment);
- ``robots``, ``scenes``, ``programs``, ``skills``: every built-in robot description, planning scene, task
  program and skill file, loaded through the public API (the files the package reads at run time);
- ``plan``: a URDF copied out of the package, loaded by path, and a start-to-goal motion around a box
  (the first quickstart): success, duration and minimum clearance;
- ``seconds``: the time each of the two took (the first run in an environment compiles the numba kernels).

Usage: ``python wheel_smoke.py`` (no arguments).
"""

from __future__ import annotations

import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np


def packaged_files() -> dict[str, Any]:
    """Load every built-in robot, scene, program and skill file of the installed package.

    Returns:
        The names loaded per kind.
    """
    from robointel.planning.scene import builtin_scenes, load_scene
    from robointel.program.format import EXAMPLES, builtin_programs, load_program
    from robointel.program.skill_file import load_skill
    from robointel.robot import Robot
    from robointel.robot.catalogue import builtin_names

    robots = {name: Robot.load(name).nq for name in builtin_names()}
    scenes = {name: len(load_scene(name).waypoints) for name in builtin_scenes()}
    programs = {name: len(load_program(name).steps) for name in builtin_programs()}
    skills = {p.name: type(load_skill(p)).__name__ for p in sorted(EXAMPLES.glob("*.skill.h5"))}
    return {"robots": robots, "scenes": scenes, "programs": programs, "skills": skills}


def plan_from_urdf(workdir: Path) -> dict[str, Any]:
    """Plan a motion for an arm given by its URDF file, around a box on the table.

    Args:
        workdir: where the URDF is copied to (a user's own file, outside the package).

    Returns:
        ``success``, ``duration_s``, ``min_clearance_m`` and ``waypoints`` of the plan, and the clearance
        at the middle of the straight joint-space line (negative: the box is in the way).
    """
    from robointel import Environment, MotionSettings, Robot, plan_motion
    from robointel.geometry import Box
    from robointel.robot.catalogue import DESCRIPTIONS

    urdf = workdir / "my_arm.urdf"
    shutil.copyfile(DESCRIPTIONS / "lrmate200id7l.urdf", urdf)
    robot = Robot.load(urdf)
    box = Box(center=np.array([0.55, 0.0, 0.30]), size=np.array([0.12, 0.30, 0.60]), name="box")
    env = Environment(robot, [box])
    start = np.radians([60.0, 30.0, 0.0, 0.0, -60.0, 0.0])
    goal = np.radians([-60.0, 30.0, 0.0, 0.0, -60.0, 0.0])
    blocked = env.clearance(0.5 * (start + goal), cap=1.0)  # the straight line passes through the box
    plan = plan_motion(robot, env, start, goal, settings=MotionSettings(d_min=0.01, seed=0))
    traj = plan.trajectory
    return {"success": bool(plan.success), "reason": plan.reason, "straight_line_clearance_m": float(blocked),
            "duration_s": None if traj is None else float(traj.t[-1] - traj.t[0]),
            "min_clearance_m": float(plan.min_clearance_m), "waypoints": None if plan.path is None else len(plan.path)}


def main() -> int:
    """Run both checks and print their JSON.

    Returns:
        0 when every file loaded and the plan succeeded, else 1.
    """
    import robointel

    out: dict[str, Any] = {"robointel_file": robointel.__file__, "version": robointel.__version__,
                           "python": sys.executable}
    t0 = time.perf_counter()
    out.update(packaged_files())
    t1 = time.perf_counter()
    out["plan"] = plan_from_urdf(Path.cwd())
    out["seconds"] = {"packaged_files": round(t1 - t0, 2), "plan": round(time.perf_counter() - t1, 2)}
    print(json.dumps(out))
    return 0 if out["plan"]["success"] else 1


if __name__ == "__main__":
    sys.exit(main())
