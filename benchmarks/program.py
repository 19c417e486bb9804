"""Task programs end to end, through the batch runner (``robointel.batch``: in-process, or Ray with ``--workers``).

``example`` (default, the built-in example cell): the LR Mate with its gripper perceives a generated long
part at a random placement (the seed), classifies it, transfers a taught grasp, picks it, carries it around
two fixtures on a planned motion, sets it down at the target, goes home, then inserts a peg with the learned
skill (``peg.skill.h5``) at the insertion station (a 0.1 mm fit, start error +-0.5 mm, <= 0.25 deg: the
example's error budget). ``example_ycb``: the same with the YCB scan of a flat screwdriver as the part
(needs ../shared/data). ``pick_place``: the same without the insertion.
``pick_place_success`` counts the runs whose steps up to the insertion all succeeded (the part rests within
3 cm of the target and the arm is home). ``moves``: move/path/wait/set_io on the Table 7.1 cell, over cells
randomised by the seed (fixtures moved by up to +/-2 cm, waypoints turned by up to +/-2 deg).

    python benchmarks/program.py [--json] [--program example|example_ycb|pick_place|moves] [--runs 50] [--seed 4000]
                                 [--workers 2]

Prints ``runs``, ``success``, per-step success and median step time, ``cycle_time_s`` (median planned
motion time of a successful run for ``moves``; simulated time of a successful run otherwise),
``check_ms`` (median pre-run check). Seeds 4000.. were never used while writing or tuning the program module
(seeds 1000-1049 and 3000-3049 were studied, 2000-2099 used in development).
With ``--workers N`` > 1 the trials run on a local Ray inside a loopback-only network namespace
(``unshare --net``, root).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
import time
from collections import defaultdict

import numpy as np

from _netns import reexec_in_loopback_netns
from robointel.batch import TaskSpec, run_batch
from robointel.batch.store import ResultStore
from robointel.geometry import obstacle_from_dict
from robointel.program import ProgramRejected, SimCell, check_program, load_program, run_program


def randomised_moves(seed: int):
    prog = load_program("moves")
    rng = np.random.default_rng(seed)
    obs = []
    for o in prog.scene.obstacles:
        d = o.to_dict()
        if d.get("name") not in ("table", "floor"):
            d["center"] = (np.asarray(d["center"]) + np.r_[rng.uniform(-0.02, 0.02, 2), 0.0]).tolist()
        obs.append(obstacle_from_dict(d))
    prog.scene.obstacles[:] = obs
    for k in list(prog.waypoints):
        q = prog.waypoints[k] + np.radians(rng.uniform(-2, 2, prog.robot.nq))
        prog.waypoints[k] = np.clip(q, prog.robot.lower, prog.robot.upper)
    return prog


def moves_runs(runs: int, seed: int) -> dict:
    ok, refused, check_ms, cycle, reasons = 0, 0, [], [], []
    step_ok: dict[str, list[bool]] = defaultdict(list)
    step_s: dict[str, list[float]] = defaultdict(list)
    for s in range(seed, seed + runs):
        prog = randomised_moves(s)
        q0 = prog.initial_configuration()
        try:
            chk = check_program(prog, q0)
        except ProgramRejected as exc:
            refused += 1
            reasons.append(f"seed {s}: refused: {exc}")
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
    return {"runs": runs, "success": ok, "success_rate": ok / runs, "refused": refused,
            "per_step_success": {k: f"{sum(v)}/{len(v)}" for k, v in step_ok.items()},
            "per_step_median_ms": {k: round(1e3 * float(np.median(v)), 2) for k, v in step_s.items()},
            "cycle_time_s": float(np.median(cycle)) if cycle else None,
            "check_ms": float(np.median(check_ms)) if check_ms else None, "failures": reasons[:10]}


def batch_runs(program: str, runs: int, seed: int, workers: int) -> dict:
    specs = [TaskSpec("program", s, {"program": program}) for s in range(seed, seed + runs)]
    with tempfile.TemporaryDirectory() as d:
        if workers > 1:
            run_batch(specs, d, engine="ray", workers=workers, progress=sys.stderr.isatty())
        else:
            run_batch(specs, d, progress=sys.stderr.isatty())
        rows = ResultStore(d).rows()
    ok = sum(bool(r["success"]) for r in rows)
    steps: dict[str, list[float]] = defaultdict(list)
    times: dict[str, list[float]] = defaultdict(list)
    for r in rows:
        for k, v in (r["figures"] or {}).items():
            m = re.fullmatch(r"step_(\d+)_(.+)_ok", k)
            if m:
                steps[m.group(2)].append(v)
        for k, v in (r["timings"] or {}).items():
            m = re.fullmatch(r"step_(\d+)_(.+)", k)
            if m:
                times[m.group(2)].append(v)
    succ = [r for r in rows if r["success"]]
    prog = load_program(program)
    before = [f"step_{i}_{st.name}_ok" for i, st in enumerate(prog.steps) if st.kind not in ("insert", "grind")]
    pp_rows = [r for r in rows if all((r["figures"] or {}).get(k, 0.0) == 1.0 for k in before)]
    pp = len(pp_rows)
    return {"runs": len(rows), "success": ok, "success_rate": ok / max(1, len(rows)),
            "pick_place_success": pp, "pick_place_success_rate": pp / max(1, len(rows)),
            "pick_place_cycle_time_s": (float(np.median([r["figures"]["cell_time_s"] for r in pp_rows]))
                                        if pp_rows else None),
            "failures_before_skill": [f"seed {r['seed']}: {r['reason']}: {r['detail']}" for r in rows
                                      if r not in pp_rows],
            "per_step_success": {k: f"{int(sum(v))}/{len(v)}" for k, v in steps.items()},
            "per_step_median_ms": {k: round(1e3 * float(np.median(v)), 1) for k, v in times.items()},
            "cycle_time_s": float(np.median([r["figures"]["cycle_time_s"] for r in succ])) if succ else None,
            "check_ms": float(np.median([r["figures"]["check_ms"] for r in rows if "check_ms" in r["figures"]])),
            "failures": [f"seed {r['seed']}: {r['reason']}: {r['detail']}" for r in rows if not r["success"]][:10]}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--program", default="example", choices=["example", "example_ycb", "pick_place", "moves"])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--seed", type=int, default=4000)
    ap.add_argument("--workers", type=int, default=1, help="> 1: Ray workers (in a loopback-only namespace)")
    a = ap.parse_args()
    if a.workers > 1:
        reexec_in_loopback_netns()
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    out = {"program": a.program}
    out.update(moves_runs(a.runs, a.seed) if a.program == "moves"
               else batch_runs(a.program, a.runs, a.seed, a.workers))
    out.update({"seeds": [a.seed, a.seed + a.runs - 1], "wall_s": time.perf_counter() - t0, "load_avg_start": load0,
                "workers": a.workers,
                "cycle_time_note": "median over successful runs; moves: planned motion time; example/pick_place: "
                                   "simulated time of the whole run (perception, grasp, carry, place, home, "
                                   "insertion)"})
    if a.json:
        json.dump(out, sys.stdout, indent=1)
        print()
    else:
        for k, v in out.items():
            print(f"{k}: {v}")


if __name__ == "__main__":
    main()
