"""Where our MotionBenchMaker plan time goes: ``plan_motion`` on a tuning subset, one core, optional cProfile.

The subset is valid problems ``--start`` to ``--stop`` (positions in each family's list of valid problems,
0-based; the default 10-19 keeps clear of the first five that ``benchmarks/mbm.py --per-family 5`` reports),
seeds ``7919 + index`` as in ``mbm.py``. No independent checker and no peers: this measures the planner
alone, for before/after comparisons on the same problems.

    python benchmarks/mbm_profile.py --json [--start 10 --stop 20] [--families cage box] [--budget 10]
                                     [--profile out.prof] [--top 40] [--post-reps 5]

Prints one JSON object: per problem the plan wall time and its process CPU time (``plan_motion`` alone,
the environment build apart), the stage timings and the outcome; the median / p95 of plan_ms and of
CPU; stage medians; the load average at start and end. With ``--profile`` the calls are run under
cProfile (slower: compare profiled runs only with profiled runs) and the ``--top`` functions by
cumulative time go to stderr. With ``--post-reps N`` the stages after the search (shortcut, timing,
dense and mesh checks: ``motion._finish``) of every attempt are run N more times on the same path, with
no deadline, and each row gets ``post_cpu_ms``: the process CPU per stage of the plan's own call
(``first``) and the smallest over the N re-runs (``min``), keys ``shortcut``, ``topp``, ``dense``,
``mesh``, ``polyline``, ``total`` (the re-runs make plan_ms and cpu_ms meaningless in such a run).
"""
from __future__ import annotations

import argparse
import copy
import cProfile
import io
import json
import os
import pstats
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mbm import SEED0, Ours, data_dir, one_core, stage_profile, stats  # noqa: E402


class PostProbe:
    """Times the stages after the search (``motion._finish``) by process CPU, re-run ``reps`` times."""

    STAGES = {"topp": "topp_spline", "dense": "check_dense", "mesh": "_mesh_checks", "polyline": "polyline_timing"}

    def __init__(self, reps: int) -> None:
        import robointel.planning._time_shortcut as TS
        import robointel.planning.motion as M

        self.reps, self.acc, self.calls = reps, {}, []
        for key, name in self.STAGES.items():
            setattr(M, name, self._timed(key, getattr(M, name)))
        TS.shortcut_time = self._timed("shortcut", TS.shortcut_time)
        self.finish = M._finish
        self.M = M
        M._finish = self._finish

    def _timed(self, key, fn):
        def wrapped(*a, **k):
            c = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                self.acc[key] = self.acc.get(key, 0.0) + (time.process_time() - c) * 1e3
        return wrapped

    def _run(self, args):
        self.acc = {}
        c = time.process_time()
        out = self.finish(*args)
        self.acc["total"] = (time.process_time() - c) * 1e3
        return out, dict(self.acc)

    def _finish(self, *args):
        out, first = self._run(args)
        again = []
        for _ in range(self.reps):
            a = list(args)
            a[3], a[9] = float("inf"), self.M.StageTimes()  # no deadline, timings apart
            again.append(self._run(copy.copy(a))[1])
        keys = sorted({k for r in [first, *again] for k in r})
        self.calls.append({"first": first, "min": {k: min(r.get(k, 0.0) for r in again) for k in keys}
                           if again else {}})
        return out

    def take(self) -> list[dict]:
        calls, self.calls = self.calls, []
        return calls


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print one JSON object (the default prints it too)")
    ap.add_argument("--start", type=int, default=10, help="first valid-problem position of each family (0-based)")
    ap.add_argument("--stop", type=int, default=20, help="one past the last position")
    ap.add_argument("--families", nargs="*", default=None)
    ap.add_argument("--budget", type=float, default=10.0, help="time_budget_s per problem, s")
    ap.add_argument("--d-min", type=float, default=0.001)
    ap.add_argument("--profile", type=Path, default=None, help="write cProfile stats here")
    ap.add_argument("--top", type=int, default=40, help="functions printed to stderr with --profile")
    ap.add_argument("--post-reps", type=int, default=0,
                    help="re-run the stages after the search N times per attempt and report their CPU per stage")
    args = ap.parse_args()
    from robointel.io.mbm import load_mbm_problems

    one_core()
    root = data_dir()
    pset = load_mbm_problems(root / "problems.json")
    fams = args.families or list(pset.families)
    problems = [p for f in fams for p in pset.select(families=[f])[args.start:args.stop]]
    ours = Ours(root / "ur5.urdf", root / "ur5.srdf", args.d_min, args.budget)
    probe = PostProbe(args.post_reps) if args.post_reps > 0 else None
    ours.solve(problems[0], SEED0 + problems[0].index)  # warm-up: kernels, meshes (untimed)
    if probe is not None:
        probe.take()
    prof = cProfile.Profile() if args.profile else None
    load0 = os.getloadavg()[0]
    rows = []
    for p in problems:
        w0 = time.perf_counter()
        env = ours.Environment(ours.robot, p.obstacles, **ours.env_kw)
        settings = ours.MotionSettings(d_min=args.d_min, seed=SEED0 + p.index, time_budget_s=args.budget)
        env_ms = (time.perf_counter() - w0) * 1e3
        if prof is not None:
            prof.enable()
        c0, w1 = time.process_time(), time.perf_counter()
        plan = ours.plan_motion(ours.robot, env, p.start, p.goals, settings=settings)
        cpu_ms, plan_ms = (time.process_time() - c0) * 1e3, (time.perf_counter() - w1) * 1e3
        if prof is not None:
            prof.disable()
        rows.append({"problem": p.name, "success": plan.success, "plan_ms": plan_ms, "cpu_ms": cpu_ms,
                     "env_ms": env_ms, "reason": plan.reason, "timings": plan.timings,
                     "stages_ms": plan.timings, "stages_cpu_ms": plan.cpu_timings, "plan_cpu_ms": cpu_ms,
                     "duration_s": None if plan.trajectory is None else float(plan.trajectory.t[-1]),
                     "path_vertices": None if plan.path is None else len(plan.path),
                     "min_clearance_m": plan.min_clearance_m})
        if probe is not None:
            rows[-1]["post_cpu_ms"] = probe.take()
    ok = [r for r in rows if r["success"]]
    stage_names = sorted({k for r in rows for k in r["timings"]})
    out = {"problems": len(rows), "success_count": len(ok), "families": fams, "positions": [args.start, args.stop],
           "budget_s": args.budget, "profiled": prof is not None, "load_average_1min": load0,
           "load_average_1min_end": os.getloadavg()[0], "plan_ms": stats([r["plan_ms"] for r in rows]),
           "cpu_ms": stats([r["cpu_ms"] for r in rows]),
           "stage_ms_median": {k: float(np.median([r["timings"].get(k, 0.0) for r in rows])) for k in stage_names},
           **stage_profile(rows),
           "failures": {r["problem"]: r["reason"] for r in rows if not r["success"]}, "rows": rows}
    if probe is not None:  # per problem the sum over its attempts, then the median over problems
        for which in ("first", "min"):
            per = [{k: sum(c[which].get(k, 0.0) for c in r["post_cpu_ms"]) for k in ("shortcut", "topp", "dense",
                    "mesh", "polyline", "total")} for r in rows if r["post_cpu_ms"]]
            out[f"post_cpu_ms_{which}_median"] = {k: float(np.median([p[k] for p in per])) for k in per[0]}
            out[f"post_cpu_ms_{which}_sum"] = {k: float(np.sum([p[k] for p in per])) for k in per[0]}
    print(json.dumps(out, default=float))
    if prof is not None:
        prof.dump_stats(str(args.profile))
        s = io.StringIO()
        pstats.Stats(prof, stream=s).sort_stats("cumulative").print_stats(args.top)
        print(s.getvalue(), file=sys.stderr)


if __name__ == "__main__":
    main()
