"""Batch evaluation on Ray against in-process: throughput, scaling, per-task overhead, and that a
killed worker loses and duplicates nothing.

    python benchmarks/batch.py [--json] [--insertion 12] [--grasp 2] [--no-netns]

A fixed set of real trials (``--insertion`` peg-in-hole trials with the LR Mate under impedance
control, ~1.5 s each on an idle core, and ``--grasp`` lift-and-shake grasp trials, ~6-17 s each)
runs in one process, each run into a fresh result folder:

* in-process (the default engine), after one warm-up trial of each kind (per-process caches:
  the insertion cell, the grasp planner);
* Ray with 1 worker (``ray.init(num_cpus=1)``) and Ray with 2 workers, each after a warm-up round;
  ``throughput_*`` = tasks / wall time of the run; ``speedup_2_workers`` = 2-worker over 1-worker
  throughput; ``overhead_per_task_ms`` = (Ray 1-worker wall - in-process wall) / tasks on these
  trials, the median over ``--repeats`` such pairs (each pair run back to back, so the shared
  machine's drift mostly cancels; every repeat is printed), and ``overhead_per_task_ms_empty_tasks``
  the same on ``--empty`` zero-work synthetic tasks (Ray's dispatch and the store alone, without
  the trials' noise on a shared machine); ``overhead_between_tasks_ms`` and ``overhead_inside_tasks_ms``
  split it (medians over the pairs): the run's wall outside the tasks' own time inside ``execute``
  (dispatch, transfer, store writes), and the tasks' own time, Ray worker against driver;
  ``per_task_repeats`` gives each pair's per-task medians by kind (wall and CPU seconds);
  ``cores_used_*`` = the tasks' CPU seconds over the run's wall time (what the run actually got of
  the 2 cores while other jobs ran);
* Ray with 2 workers on the insertion trials again, with the worker of one task killed (SIGKILL)
  0.3 s into its first attempt: ``lost`` = keys missing from the Parquet files, ``duplicated`` =
  extra rows over all files (no store deduplication counted), and whether the outcomes equal the
  in-process run.

Ray runs inside a loopback-only network namespace: the script re-executes itself under
``unshare --net`` (root) unless ``--no-netns``. The machine is shared: the load average is reported.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from _netns import reexec_in_loopback_netns
from robointel.batch import Fault, ResultStore, TaskSpec, run_batch

GRASP_CATEGORIES = ("cup", "can", "box", "ball", "long_tool")


def tasks(n_ins: int, n_grasp: int, offset: int = 0) -> list[TaskSpec]:
    out = [TaskSpec("insertion", 1000 + offset + s, {"controller": "impedance"}) for s in range(n_ins)]
    out += [TaskSpec("grasp", 2000 + offset + s, {"category": GRASP_CATEGORIES[s % len(GRASP_CATEGORIES)]})
            for s in range(n_grasp)]
    return out


def warmup(n_grasp: int, copies: int) -> list[TaskSpec]:
    """Warm-up specs (other seeds than the timed ones): one insertion and one grasp per copy."""
    return tasks(copies, copies if n_grasp else 0, offset=500)


def outcomes(folder) -> dict:
    return {(r["spec_hash"], r["seed"]): (r["success"], r["reason"], r["detail"], r["figures"])
            for r in ResultStore(folder).rows()}


def raw_counts(folder) -> Counter:
    c: Counter = Counter()
    for f in Path(folder).glob("part-*.parquet"):
        t = pq.read_table(f, columns=["spec_hash", "seed"])
        c.update(zip(t.column("spec_hash").to_pylist(), t.column("seed").to_pylist()))
    return c


def timed(specs, folder, **kw):
    r = run_batch(specs, folder, progress=False, **kw)
    return r.wall_s, r


def cores_used(folder, wall: float) -> float:
    """CPU seconds the tasks got over the run's wall time: the cores the run effectively had."""
    return sum(r["cpu_s"] for r in ResultStore(folder).rows()) / wall


def per_task(folder, wall: float) -> dict:
    """Where a run's time went, per task: the medians by kind of the task's wall and CPU time inside
    ``execute`` (in the driver, or in the Ray worker), and ``between_ms`` = (run wall - the tasks' summed
    wall) / tasks: dispatch, result transfer and store writes (meaningful for one worker at a time)."""
    rows = ResultStore(folder).rows()
    busy = sum(r["wall_s"] for r in rows)
    out: dict = {"between_ms": (wall - busy) / len(rows) * 1e3, "tasks_wall_s": busy}
    for kind in sorted({r["kind"] for r in rows}):
        mine = [r for r in rows if r["kind"] == kind]
        out[kind] = {"wall_s_median": float(np.median([r["wall_s"] for r in mine])),
                     "cpu_s_median": float(np.median([r["cpu_s"] for r in mine]))}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--insertion", type=int, default=12)
    ap.add_argument("--grasp", type=int, default=2)
    ap.add_argument("--empty", type=int, default=200, help="empty synthetic tasks for the pure dispatch overhead")
    ap.add_argument("--repeats", type=int, default=3,
                    help="in-process / Ray 1-worker pairs for overhead_per_task_ms (their median)")
    ap.add_argument("--worker-niceness", type=int, default=0, help="niceness of the local Ray's workers")
    ap.add_argument("--no-netns", action="store_true", help="do not re-execute inside unshare --net")
    args = ap.parse_args()
    if not args.no_netns:
        reexec_in_loopback_netns(hint="pass --no-netns")

    json_fd = None
    if args.json:  # Ray's driver prints notices (a worker died) on stdout: keep it for the one JSON object
        sys.stdout.flush()
        json_fd = os.dup(1)
        os.dup2(2, 1)

    import ray

    from robointel.batch.ray_engine import start_ray

    root = Path(tempfile.mkdtemp(prefix="robointel-batch-bench-"))
    specs = tasks(args.insertion, args.grasp)
    n = len(specs)
    out: dict = {"tasks": n, "insertion_trials": args.insertion, "grasp_trials": args.grasp,
                 "load_average_start": os.getloadavg()[0], "cpus": os.cpu_count()}
    t_all = time.perf_counter()

    # in-process, warm
    timed(warmup(args.grasp, 1), root / "warm-inproc")
    t_in, r_in = timed(specs, root / "inproc")
    trial_s = [r["timings"].get("trial_s", np.nan) for r in ResultStore(root / "inproc").rows()]
    out["throughput_inprocess"] = n / t_in
    out["cores_used_inprocess"] = cores_used(root / "inproc", t_in)
    out["trial_s_median"] = float(np.nanmedian(trial_s))
    out["successes_inprocess"] = n - r_in.counts.failed
    splits: list[tuple[dict, dict]] = [(per_task(root / "inproc", t_in), {})]  # (in-process, Ray 1 worker) per repeat
    empty = [TaskSpec("synthetic", s, {"work_s": 0.0}) for s in range(args.empty)]
    t_empty_in, _ = timed(empty, root / "empty-inproc")

    pairs: list[float] = []  # (Ray 1 worker - in-process) wall per task, ms, for each repeat
    for w in (1, 2):
        t0 = time.perf_counter()
        start_ray(workers=w, address=None, worker_niceness=args.worker_niceness)
        out[f"ray_start_s_{w}_workers"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        timed(warmup(args.grasp, w), root / f"warm-ray{w}", engine="ray", workers=w)
        out[f"warmup_s_{w}_workers"] = time.perf_counter() - t0
        t, r = timed(specs, root / f"ray{w}", engine="ray", workers=w)
        if w == 1:
            pairs.append((t - t_in) / n * 1e3)
            splits[0][1].update(per_task(root / "ray1", t))
            for k in range(1, args.repeats):  # the same pair again, in-process first: the machine's drift cancels
                t_in_k, _ = timed(specs, root / f"inproc-{k}")
                t_ray_k, _ = timed(specs, root / f"ray1-{k}", engine="ray", workers=1)
                pairs.append((t_ray_k - t_in_k) / n * 1e3)
                splits.append((per_task(root / f"inproc-{k}", t_in_k), per_task(root / f"ray1-{k}", t_ray_k)))
            timed(empty[:10], root / "empty-warm", engine="ray", workers=1)
            t_empty_ray, _ = timed(empty, root / "empty-ray1", engine="ray", workers=1)
            out["overhead_per_task_ms_empty_tasks"] = (t_empty_ray - t_empty_in) / len(empty) * 1e3
        out[f"throughput_{w}_worker" + ("s" if w > 1 else "")] = n / t
        out[f"cores_used_{w}_worker" + ("s" if w > 1 else "")] = cores_used(root / f"ray{w}", t)
        out[f"identical_to_inprocess_{w}_workers"] = outcomes(root / f"ray{w}") == outcomes(root / "inproc")
        if w == 2:  # a worker killed during the run
            ins = [s for s in specs if s.kind == "insertion"]
            victim = ins[len(ins) // 2]
            markers = root / "markers"
            markers.mkdir()
            fault = Fault((f"{victim.spec_hash}:{victim.seed}",), str(markers), after_s=0.3)
            t, r = timed(ins, root / "kill", engine="ray", workers=2, max_retries=3, fault=fault)
            counts = raw_counts(root / "kill")
            want = {s.key for s in ins}
            out["kill_run_tasks"] = len(ins)
            out["worker_killed"] = (markers / f"{victim.spec_hash}_{victim.seed}").exists()
            out["lost"] = len(want - set(counts))
            out["duplicated"] = sum(v - 1 for v in counts.values())
            out["kill_run_fault_rows"] = r.counts.errors
            inproc = {k: v for k, v in outcomes(root / "inproc").items() if k in want}
            out["kill_run_identical_to_inprocess"] = outcomes(root / "kill") == inproc
            out["kill_run_s"] = t
        ray.shutdown()

    out["speedup_2_workers"] = out["throughput_2_workers"] / out["throughput_1_worker"]
    out["overhead_per_task_ms"] = float(np.median(pairs))
    out["overhead_per_task_ms_repeats"] = pairs
    # the overhead split: between tasks (dispatch, transfer, store) and inside them (the trials' own time)
    out["overhead_between_tasks_ms"] = float(np.median([r["between_ms"] - i["between_ms"] for i, r in splits]))
    out["overhead_inside_tasks_ms"] = float(np.median([(r["tasks_wall_s"] - i["tasks_wall_s"]) / n * 1e3
                                                       for i, r in splits]))
    out["per_task_repeats"] = [{"inprocess": i, "ray_1_worker": r} for i, r in splits]
    out["worker_niceness"] = args.worker_niceness
    out["overhead_fraction_of_1s_trial"] = out["overhead_per_task_ms"] / 1e3
    out["targets"] = {"lost": 0, "duplicated": 0, "speedup_2_workers": ">= 1.8", "overhead_per_task_ms": "<= 50"}
    out["load_average_end"] = os.getloadavg()[0]
    out["wall_s"] = time.perf_counter() - t_all
    shutil.rmtree(root, ignore_errors=True)
    if json_fd is not None:
        sys.stdout.flush()
        os.dup2(json_fd, 1)
        print(json.dumps(out), flush=True)
    else:
        for k, v in out.items():
            print(f"{k:36s} {v}")


if __name__ == "__main__":
    main()
