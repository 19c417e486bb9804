"""The Ray checks of tests/batch/test_ray.py, run as a script inside a loopback-only network namespace.

    unshare --net sh -c 'ip link set lo up && python tests/batch/ray_scenarios.py OUT_DIR'

Prints one JSON object with what the test asserts.
"""
import json
import sys
from collections import Counter
from pathlib import Path

import psutil
import pyarrow.parquet as pq
import ray

from robointel.batch import Fault, ResultStore, TaskSpec, run_batch
from robointel.batch.ray_engine import start_ray
from robointel.errors import InvalidInput


def outcomes(folder):
    return {f"{r['spec_hash']}:{r['seed']}": [r["success"], r["reason"], r["detail"], r["figures"], r["category"]]
            for r in ResultStore(folder).rows()}


def raw_key_counts(folder):
    """Rows per key over every Parquet file, without the store's deduplication."""
    c = Counter()
    for f in Path(folder).glob("part-*.parquet"):
        t = pq.read_table(f, columns=["spec_hash", "seed"])
        c.update(f"{h}:{s}" for h, s in zip(t.column("spec_hash").to_pylist(), t.column("seed").to_pylist()))
    return c


def main(root: Path) -> None:
    out = {}
    start_ray(workers=2, address=None)
    out["node_ip"] = ray.util.get_node_ip_address()

    # 0. a task past its budget is interrupted inside its worker and stored as a timeout; the workers run
    #    at niceness 0, not Ray's 15
    slow = [TaskSpec("synthetic", s, {"work_s": 30.0 if s == 1 else 0.0, "p_success": 1.0}) for s in range(3)]
    rt = run_batch(slow, root / "timeout", engine="ray", workers=2, progress=False, timeout_s=1.0)
    rows_t = {r["seed"]: r for r in ResultStore(root / "timeout").rows()}
    out["timeout"] = {"reasons": [rows_t[s]["reason"] for s in range(3)], "wall_s": rt.wall_s,
                      "slow_wall_s": rows_t[1]["wall_s"]}
    out["worker_nice"] = sorted({p.nice() for p in psutil.process_iter(["cmdline"])
                                 if any("default_worker.py" in a or a.startswith("ray::IDLE")
                                        for a in (p.info["cmdline"] or []))})

    # 1. a worker killed mid-task: Ray re-runs the task, every result is stored exactly once
    specs = [TaskSpec("synthetic", s, {"work_s": 0.4}) for s in range(8)]
    victim = specs[3]
    key = f"{victim.spec_hash}:{victim.seed}"
    markers = root / "markers"
    markers.mkdir()
    run = run_batch(specs, root / "kill", engine="ray", workers=2, max_retries=2, progress=False,
                    fault=Fault((key,), str(markers), after_s=0.15), flush_rows=1)
    killed_pid = int((markers / key.replace(":", "_")).read_text())
    rows = {f"{r['spec_hash']}:{r['seed']}": r for r in ResultStore(root / "kill").rows()}
    out["kill"] = {"done": run.counts.done, "errors": run.counts.errors, "raw_counts": raw_key_counts(root / "kill"),
                   "expected_keys": sorted(f"{s.spec_hash}:{s.seed}" for s in specs), "killed_pid": killed_pid,
                   "victim_worker": rows[key]["worker"], "victim_reason": rows[key]["reason"]}
    inproc = root / "kill-inprocess"
    run_batch(specs, inproc, progress=False)
    out["kill"]["same_as_inprocess"] = outcomes(root / "kill") == outcomes(inproc)

    # 1b. no retries left: the task becomes a "fault" row with Ray's error, the others are unaffected
    few = [TaskSpec("synthetic", s, {"work_s": 0.4, "p_success": 1.0}) for s in range(3)]
    (root / "markers0").mkdir()
    fk = f"{few[1].spec_hash}:{few[1].seed}"
    r0 = run_batch(few, root / "noretry", engine="ray", workers=2, max_retries=0, progress=False,
                   fault=Fault((fk,), str(root / "markers0"), after_s=0.15))
    rows0 = {f"{r['spec_hash']}:{r['seed']}": r for r in ResultStore(root / "noretry").rows()}
    out["no_retry"] = {"errors": r0.counts.errors, "n": len(rows0), "victim_reason": rows0[fk]["reason"],
                       "victim_traceback": rows0[fk]["traceback"][:300],
                       "others": sorted(r["reason"] for k, r in rows0.items() if k != fk)}

    try:
        run_batch(few, root / "toobig", engine="ray", cpus_per_task=3.0, progress=False)
        out["too_many_cpus"] = "no error"
    except InvalidInput as exc:
        out["too_many_cpus"] = str(exc)

    # 2. the same outcomes in-process and on Ray, real trials included (the grasp trial runs first in a Ray
    #    worker, longest first, and last in the driver, after the insertion trials: another process history)
    mixed = [TaskSpec("synthetic", s, {"p_success": 0.5}) for s in range(6)]
    mixed += [TaskSpec("insertion", s, {"controller": "impedance"}) for s in (0, 1)]
    mixed += [TaskSpec("synthetic", 0, {"raise_on": [0]})]  # an error row on both engines
    mixed += [TaskSpec("grasp", 2001, {"category": "can"})]  # bit-identical figures, whichever process ran it
    run_batch(mixed, root / "ray", engine="ray", workers=2, progress=False)
    run_batch(mixed, root / "inproc", progress=False)
    a, b = outcomes(root / "ray"), outcomes(root / "inproc")
    out["identical"] = {"n_ray": len(a), "n_inprocess": len(b), "equal": a == b,
                        "differ": sorted(k for k in a if a.get(k) != b.get(k)),
                        "engines": sorted({r["engine"] for r in ResultStore(root / "ray").rows()})}

    # 3. the Ray driver interrupted, then resumed: the same dataset as an uninterrupted run
    sweep = [TaskSpec("synthetic", s, {"work_s": 0.05, "p_success": 0.6}) for s in range(24)]
    seen = []

    def stop(row):
        seen.append(row)
        if len(seen) == 7:
            raise KeyboardInterrupt

    try:
        run_batch(sweep, root / "cut", engine="ray", workers=2, progress=False, on_row=stop, flush_s=100.0)
        interrupted = False
    except KeyboardInterrupt:
        interrupted = True
    stored = len(ResultStore(root / "cut"))
    resumed = run_batch(sweep, root / "cut", engine="ray", workers=2, progress=False)
    run_batch(sweep, root / "whole", progress=False)
    out["resume"] = {"interrupted": interrupted, "stored_at_interrupt": stored, "skipped": resumed.counts.skipped,
                     "done": resumed.counts.done, "equal": outcomes(root / "cut") == outcomes(root / "whole"),
                     "n": len(outcomes(root / "cut")), "max_raw_count": max(raw_key_counts(root / "cut").values())}
    ray.shutdown()
    print("RESULT " + json.dumps(out))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
