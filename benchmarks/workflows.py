"""The operator's workflows measured at size, each through the `robointel` command as the docs give it.

    python benchmarks/workflows.py [--json] [--only insertion,plan,programs,jog] [--trials 10] [--scenes 20]

- ``cli_insertion_success``: ``robointel learn insertion --trials 0`` (the felt skill from 10 demonstrations,
  seed 0) writes a skill file; ``robointel skill insert --skill FILE --trials 10 --seed 7`` runs it at the
  benchmark's task (20 um, chamferless, starts up to +-2 mm and 5 deg; start seed 7, never used in tuning).
  Target >= 9 of 10.
- ``cli_plan_execute_agree``: random scenes, half the MotionBenchMaker UR5 (its URDF from the reference
  data; two clear configurations whose straight joint-space line passes through self-collision, topped up
  with box scenes when the draw holds too few such pairs), half the LR Mate (two clear configurations and
  a box across the straight line between them); CFS constrains self-collision in every scene.
  ``robointel plan scene S`` prints the verdict ``--execute`` will give (exit 0 accepted, 1 refused);
  ``robointel plan scene S --execute`` then runs it in the MuJoCo workcell (exit 0 executed without
  touching anything, 2 refused before moving, 1 touched something). Agreement: accepted and executed, or
  refused and not executed. Target 20 of 20.
- ``programs_refused_before_motion``: 10 malformed or impossible programs (a part off the table, inside a
  fixture, out of reach, a place spot off the table and inside a fixture, a pose outside the workspace,
  a joint target beyond the limits, an unknown key, an unknown step kind, a missing skill file):
  ``robointel run P`` must exit 2 with one line naming the step before anything moves (no report
  written). Target 10 of 10.
- ``jog_dropped``: targets the streaming server dropped in a 500-target jog (``robointel jog`` through
  ``robointel teleop``'s streaming interface) on a host with two busy loops beside them
  (:mod:`benchmarks._jog`, with the jog's other figures). Target 0.
"""
from __future__ import annotations

import argparse
import copy
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from robointel.errors import TargetInCollision
from robointel.geometry import obstacle_from_dict
from robointel.geometry.table import table_obstacles
from robointel.io.reference import data_path
from robointel.planning.segment import self_clearances
from robointel.program.format import EXAMPLES
from robointel.robot import Robot
from robointel.teach.collision_guard import CollisionGuard

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _jog import jog_dropped  # noqa: E402


def robointel(*args: str, timeout: float = 1800.0) -> subprocess.CompletedProcess[str]:
    """Run ``robointel ARGS`` (the console script beside this interpreter, else ``python -m robointel.cli``)."""
    exe = Path(sys.executable).with_name("robointel")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "robointel.cli"]
    env = dict(os.environ, COLUMNS="200", MPLBACKEND="Agg")
    return subprocess.run([*cmd, *args], capture_output=True, text=True, timeout=timeout, env=env)


# ------------------------------------------------------------------------------------------------ insertion
def cli_insertion(folder: Path, *, trials: int = 10, demos: int = 10, seed: int = 7) -> dict[str, Any]:
    """Learn the felt skill with ``learn insertion`` and run ``skill insert --skill FILE`` from ``trials`` starts."""
    skill = folder / "peg.skill.h5"
    t0 = time.perf_counter()
    learn = robointel("learn", "insertion", "--demos", str(demos), "--trials", "0", "--out", str(folder),
                      "--skill-out", str(skill))
    t1 = time.perf_counter()
    if learn.returncode != 0:
        return {"cli_insertion_success": 0, "cli_insertion_error": learn.stderr.strip()[-500:]}
    report = folder / "insert.json"
    run = robointel("skill", "insert", "--skill", str(skill), "--trials", str(trials), "--seed", str(seed),
                    "--json", str(report))
    t2 = time.perf_counter()
    if run.returncode != 0 or not report.is_file():
        return {"cli_insertion_success": 0, "cli_insertion_error": run.stderr.strip()[-500:]}
    r = json.loads(report.read_text())
    ok = [t for t in r["trials"] if t["success"]]
    return {"cli_insertion_success": int(r["seated"]), "cli_insertion_trials": len(r["trials"]),
            "cli_insertion_clearance_um": r["clearance_m"] * 1e6, "cli_insertion_time_limit_s": r["time_limit_s"],
            "cli_insertion_strategy": r["strategy"], "cli_insertion_start_seed": seed, "cli_insertion_demos": demos,
            "cli_insertion_time_s_median": float(np.median([t["time_s"] for t in ok])) if ok else None,
            "cli_insertion_failures": [t["reason"] for t in r["trials"] if not t["success"]],
            "cli_learn_wall_s": t1 - t0, "cli_insert_wall_s": t2 - t1}


# ------------------------------------------------------------------------------------------------ planning
def _clear_configs(robot: Robot, guard: CollisionGuard, rng: np.random.Generator, n: int) -> list[np.ndarray]:
    lo, hi = np.maximum(robot.lower, -np.pi) + 1e-3, np.minimum(robot.upper, np.pi) - 1e-3
    out: list[np.ndarray] = []
    for _ in range(200 * n):
        q = rng.uniform(lo, hi)
        try:
            guard.check(q)
        except TargetInCollision:
            continue
        out.append(q)
        if len(out) == n:
            break
    return out


def _scene(name: str, robot: str, a: np.ndarray, b: np.ndarray, vmax: np.ndarray,
           obstacles: list[dict[str, Any]]) -> dict[str, Any]:
    t_min = float(np.max(np.abs(b - a) / vmax))
    return {"name": name, "robot": robot, "steps": 40, "operational_time": round(max(6.0, 2.5 * t_min), 2),
            "d_min": 0.02, "table": True, "limits": {"velocity_scale": 1.0, "acceleration_scale": 1.0},
            "obstacles": obstacles,
            "waypoints": [{"name": "a", "q_deg": np.degrees(a).round(4).tolist()},
                          {"name": "b", "q_deg": np.degrees(b).round(4).tolist()}]}


def ur5_scenes(n: int, rng: np.random.Generator) -> list[dict[str, Any]]:
    """``n`` UR5 scenes: two clear configurations whose straight joint-space line passes through self-collision.

    When the draw holds fewer such pairs, the rest are :func:`box_scenes` of the UR5.

    Clear configurations (the collision guard: the table, the floor, the arm itself) are drawn uniformly within
    the joint limits (+-pi); pairs are taken in order, each configuration in four at most, when some pair of spheres on
    non-adjacent links comes 2 mm into each other on the line between them (large wrist turns, mostly).
    """
    urdf = data_path("mbm", "ur5", "ur5.urdf")
    robot = Robot.load(urdf)
    guard = CollisionGuard(robot, table_obstacles())
    pool = _clear_configs(robot, guard, rng, max(60, 6 * n))
    line = np.linspace(0.0, 1.0, 100)[:, None]
    out: list[dict[str, Any]] = []
    uses = np.zeros(len(pool), int)
    for i in range(len(pool)):
        for j in range(i + 1, len(pool)):
            if uses[i] >= 4 or uses[j] >= 4:  # each configuration in at most four scenes
                continue
            a, b = pool[i], pool[j]
            if self_clearances(robot, a + line * (b - a))[0].min() < -0.002:
                out.append(_scene(f"ur5_self_{len(out)}", str(urdf), a, b, robot.velocity_limit, []))
                uses[[i, j]] += 1
                if len(out) == n:
                    return out
    return out + box_scenes(str(urdf), n - len(out), rng, "ur5_box")


def box_scenes(robot_ref: str, n: int, rng: np.random.Generator, prefix: str) -> list[dict[str, Any]]:
    """``n`` scenes: two clear configurations 0.8-2.5 rad apart and an 8 cm box across the straight line."""
    robot = Robot.load(robot_ref)
    guard = CollisionGuard(robot, table_obstacles())
    out: list[dict[str, Any]] = []
    for _ in range(400 * n):
        if len(out) >= n:
            break
        a, b = _clear_configs(robot, guard, rng, 2)
        if not 0.8 <= np.max(np.abs(b - a)) <= 2.5:
            continue
        mid = robot.fk(0.5 * (a + b))[:3, 3]
        box = {"type": "box", "name": "box", "center": np.round(mid, 3).tolist(), "size": [0.08, 0.08, 0.08]}
        ends = CollisionGuard(robot, [*table_obstacles(), obstacle_from_dict(box)], clearance=0.03)
        try:
            ends.check(a)
            ends.check(b)
        except TargetInCollision:
            continue
        out.append(_scene(f"{prefix}_{len(out)}", robot_ref, a, b, robot.velocity_limit, [box]))
    return out


def lrmate_scenes(n: int, rng: np.random.Generator) -> list[dict[str, Any]]:
    """``n`` LR Mate scenes: :func:`box_scenes` (its straight lines between clear configurations do not self-collide:
    0 of 1,770 pairs of 60 random clear configurations)."""
    return box_scenes("lrmate200id7l", n, rng, "lrmate_box")


def _verdict(res: subprocess.CompletedProcess[str]) -> str:
    """'accepted', 'refused' or 'error' from ``plan scene`` (exit 0, 1, 2)."""
    return {0: "accepted", 1: "refused"}.get(res.returncode, "error")


def cli_plan_execute_agree(folder: Path, *, scenes: int = 20, seed: int = 11) -> dict[str, Any]:
    """``plan scene``'s verdict against ``plan scene --execute``'s outcome on random UR5 and LR Mate scenes."""
    rng = np.random.default_rng(seed)
    sc = ur5_scenes(scenes // 2, rng) + lrmate_scenes(scenes - scenes // 2, rng)
    rows = []
    for d in sc:
        path = folder / f"{d['name']}.yaml"
        path.write_text(yaml.safe_dump(d, sort_keys=False))
        t0 = time.perf_counter()
        plan = robointel("plan", "scene", str(path), "--no-plots", "--out", str(folder / f"{d['name']}.npz"))
        ex = robointel("plan", "scene", str(path), "--no-plots", "--execute", "--out",
                       str(folder / f"{d['name']}_x.npz"))
        verdict = _verdict(plan)
        executed = ex.returncode == 0
        agree = (verdict == "accepted" and executed) or (verdict != "accepted" and not executed)
        last = (plan.stdout.strip().splitlines() or [""])[-1] if verdict != "error" else plan.stderr.strip()
        rows.append({"scene": d["name"], "verdict": verdict, "execute_rc": ex.returncode, "agree": agree,
                     "plan_says": last[:240], "execute_says": (ex.stderr.strip() or ex.stdout.strip()[-240:])[:240],
                     "wall_s": time.perf_counter() - t0})
    by = {k: [r for r in rows if r["scene"].startswith(k)] for k in ("ur5_self", "ur5_box", "lrmate")}
    return {"cli_plan_execute_agree": int(sum(r["agree"] for r in rows)), "cli_plan_scenes": len(rows),
            "cli_plan_scene_seed": seed,
            "cli_plan_accepted": {k: sum(r["verdict"] == "accepted" for r in v) for k, v in by.items()},
            "cli_plan_refused": {k: sum(r["verdict"] == "refused" for r in v) for k, v in by.items()},
            "cli_plan_errors": {k: sum(r["verdict"] == "error" for r in v) for k, v in by.items()},
            "cli_plan_rows": rows}


# ------------------------------------------------------------------------------------------------ programs
def bad_programs() -> dict[str, tuple[dict[str, Any], str]]:
    """Ten malformed or impossible programs (name -> (program, the step name the refusal must carry))."""
    base = yaml.safe_load((EXAMPLES / "pick_place.yaml").read_text())
    base["objects"] = [{"category": "cup", "seed": 1, "at": [0.5, 0.1]}]
    base["steps"] = [{"move": "home", "name": "start"}, {"grasp": {"category": "cup"}, "name": "pick_part"},
                     {"place": {"at": [0.46, -0.36]}, "name": "place_part"}, {"move": "home", "name": "home_again"}]

    def v(edit: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
        d = copy.deepcopy(base)
        edit(d)
        return d

    far = {"move": {"pose": {"xyz": [1.6, 0.0, 0.4], "rpy_deg": [0, 90, 0]}}, "name": "reach_far"}
    return {
        "part_off_table": (v(lambda d: d["objects"][0].update(at=[1.2, 0.0])), "pick_part"),
        "part_in_fixture": (v(lambda d: d["objects"][0].update(at=[0.26, -0.24])), "pick_part"),
        "part_out_of_reach": (v(lambda d: d["objects"][0].update(at=[0.19, 0.05])), "pick_part"),
        "place_off_table": (v(lambda d: d["steps"][2].update({"place": {"at": [0.5, 0.9]}})), "place_part"),
        "place_in_fixture": (v(lambda d: d["steps"][2].update({"place": {"at": [0.66, -0.24]}})), "place_part"),
        "pose_outside_workspace": (v(lambda d: d["steps"].insert(1, far)), "reach_far"),
        "joint_beyond_limits": (v(lambda d: d["steps"].insert(1, {"move": {"q_deg": [200, 0, 0, 0, 0, 0]},
                                                                  "name": "spin"})), "spin"),
        "unknown_key": (v(lambda d: d["steps"][2].update({"place": {"at": [0.46, -0.36], "speed": 2}})),
                        "place_part"),
        "unknown_step_kind": (v(lambda d: d["steps"].insert(1, {"weld": {"seam": 1}, "name": "weld_seam"})),
                              "weld_seam"),
        "missing_skill_file": (v(lambda d: d["steps"].append({"insert": {"skill": "no_such.skill.h5"},
                                                              "name": "insert_peg"})), "insert_peg"),
    }


def programs_refused(folder: Path) -> dict[str, Any]:
    """Each bad program through ``robointel run``: exit 2, one line naming the step, no report (nothing ran)."""
    rows = []
    for name, (prog, step) in bad_programs().items():
        path = folder / f"{name}.yaml"
        path.write_text(yaml.safe_dump(prog, sort_keys=False))
        report = folder / f"{name}_report"
        t0 = time.perf_counter()
        res = robointel("run", str(path), "--report", str(report))
        lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
        ok = (res.returncode == 2 and len(lines) == 1 and (f"'{step}'" in lines[0] or f"({step!r})" in lines[0])
              and not report.exists() and "Traceback" not in res.stderr)
        rows.append({"program": name, "refused": ok, "rc": res.returncode, "message": (lines or [""])[-1][:300],
                     "wall_s": time.perf_counter() - t0})
    return {"programs_refused_before_motion": int(sum(r["refused"] for r in rows)), "programs_bad": len(rows),
            "programs_rows": rows}


# ------------------------------------------------------------------------------------------------ jogging
def jog(_folder: Path) -> dict[str, Any]:
    """``jog_dropped``: targets dropped in a 500-target CLI jog on a host with two busy loops (:mod:`_jog`)."""
    return jog_dropped()


MEASURES: dict[str, Callable[..., dict[str, Any]]] = {"insertion": cli_insertion, "plan": cli_plan_execute_agree,
                                                      "programs": programs_refused, "jog": jog}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--only", default=",".join(MEASURES), help="comma-separated subset of " + ", ".join(MEASURES))
    ap.add_argument("--trials", type=int, default=10, help="insertion starts")
    ap.add_argument("--scenes", type=int, default=20, help="planning scenes (half UR5, half LR Mate)")
    args = ap.parse_args()
    wanted = [w for w in args.only.split(",") if w]
    unknown = [w for w in wanted if w not in MEASURES]
    if unknown:
        ap.error(f"unknown --only {unknown}; choose from {list(MEASURES)}")
    out: dict[str, Any] = {"load_average_start": os.getloadavg()}
    t0 = time.perf_counter()
    folder = Path(tempfile.mkdtemp(prefix="robointel-workflows-"))
    try:
        for w in wanted:
            t = time.perf_counter()
            sub = folder / w
            sub.mkdir()
            if w == "insertion":
                out.update(cli_insertion(sub, trials=args.trials))
            elif w == "plan":
                out.update(cli_plan_execute_agree(sub, scenes=args.scenes))
            else:
                out.update(MEASURES[w](sub))
            out[f"{w}_wall_s"] = time.perf_counter() - t
            print(f"{w}: done in {time.perf_counter() - t:.0f} s", file=sys.stderr)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    out["load_average_end"] = os.getloadavg()
    out["benchmark_s"] = time.perf_counter() - t0
    out["targets"] = {"cli_insertion_success": ">= 9 of 10", "cli_plan_execute_agree": "20 of 20",
                      "programs_refused_before_motion": "10 of 10", "jog_dropped": "0"}
    if args.json:
        print(json.dumps(out, default=float))
    else:
        for k, v in out.items():
            print(f"{k:36s} {v}")


if __name__ == "__main__":
    main()
