"""Task programs end to end: the built-in example program, checked then run in the MuJoCo cell, over
randomised cells (each seed moves the two fixtures by up to +/-2 cm and turns each named waypoint's
joints by up to +/-2 deg), so every run plans and checks its own motions.

    python benchmarks/program.py [--json] [--runs 50] [--seed 1000]

Prints ``runs``, ``success`` (checked and run end to end, every step ok), ``refused`` (the pre-run check
refused the program: nothing moved), per-step success and median step time, ``cycle_time_s`` (median
motion time of a whole run), ``check_ms`` (median pre-run check). The seeds (1000..) were never used
while writing the program module.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections import defaultdict

import numpy as np
from rich.progress import Progress

from robointel.geometry import obstacle_from_dict
from robointel.program import ProgramRejected, SimCell, check_program, load_program, run_program


def randomised(seed: int):
    prog = load_program("example")
    rng = np.random.default_rng(seed)
    obs = []
    for o in prog.scene.obstacles:
        d = o.to_dict()
        d["center"] = (np.asarray(d["center"]) + np.r_[rng.uniform(-0.02, 0.02, 2), 0.0]).tolist()
        obs.append(obstacle_from_dict(d))
    prog.scene.obstacles[:] = obs
    for k in list(prog.waypoints):
        q = prog.waypoints[k] + np.radians(rng.uniform(-2, 2, prog.robot.nq))
        prog.waypoints[k] = np.clip(q, prog.robot.lower, prog.robot.upper)
    return prog


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--seed", type=int, default=1000)
    a = ap.parse_args()
    ok, refused, check_ms, cycle = 0, 0, [], []
    step_ok: dict[str, list[bool]] = defaultdict(list)
    step_s: dict[str, list[float]] = defaultdict(list)
    reasons: list[str] = []
    load0 = os.getloadavg()[0]
    t_all = time.perf_counter()
    with Progress(transient=True) as bar:
        task = bar.add_task("program runs", total=a.runs)
        for s in range(a.seed, a.seed + a.runs):
            prog = randomised(s)
            q0 = prog.initial_configuration()
            try:
                chk = check_program(prog, q0)
            except ProgramRejected as exc:
                refused += 1
                reasons.append(f"seed {s}: refused: {exc}")
                bar.advance(task)
                continue
            check_ms.append(chk.check_ms)
            run = run_program(prog, SimCell(prog, q0), check=chk)
            ok += int(run.success)
            if not run.success:
                reasons.append(f"seed {s}: {run.outcome.detail}")
            for r in run.steps:
                step_ok[r.name].append(r.outcome.success)
                step_s[r.name].append(r.seconds)
            cycle.append(sum(p.trajectory.duration for p in chk.plans if p.trajectory is not None))
            bar.advance(task)
    out = {"runs": a.runs, "success": ok, "success_rate": ok / a.runs, "refused": refused,
           "per_step_success": {k: f"{sum(v)}/{len(v)}" for k, v in step_ok.items()},
           "per_step_median_ms": {k: round(1e3 * float(np.median(v)), 2) for k, v in step_s.items()},
           "cycle_time_s": float(np.median(cycle)) if cycle else None,
           "check_ms": float(np.median(check_ms)) if check_ms else None,
           "check_ms_first_run_with_jit": check_ms[0] if check_ms else None,
           "failures": reasons[:10], "seeds": [a.seed, a.seed + a.runs - 1], "wall_s": time.perf_counter() - t_all,
           "load_avg_start": load0,
           "note": "the example program of this version: move/path/wait/set_io on the Table 7.1 cell (no grasp or "
                   "insertion step yet)"}
    if a.json:
        json.dump(out, sys.stdout, indent=1)
        print()
    else:
        for k, v in out.items():
            print(f"{k}: {v}")


if __name__ == "__main__":
    main()
