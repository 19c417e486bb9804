"""MotionBenchMaker problems (UR5, Fetch): robointel's start-to-goal planner beside OMPL and VAMP, one core.

Ours: ``robointel.planning.plan_motion`` (global search, smoothing, time parametrisation) on the
problem read by ``robointel.io.mbm``. Peers, in the same run on the same problems and limits:
OMPL RRT-Connect + simplification + TOPP-RA (exact Pinocchio/coal state checks) and VAMP
RRT-Connect + simplification + TOPP-RA (VAMP's own UR5 spheres). Every trajectory is judged by
``_mbm_checker`` (exact coal mesh distances on a 1 ms resample; it shares no code with the planner).

Limits: the URDF's joint velocity limits (0.5 rad/s on this UR5) and accelerations of 3x the
velocity limit (1.5 rad/s^2, robointel's default ``Robot.acceleration_limit``) for all three.

    python benchmarks/mbm.py --json [--robot ur5|fetch] [--spheres file|auto] [--all | --per-family N]
                             [--families cage box] [--peers ompl vamp] [--frmp] [--jsonl rows.jsonl [--resume]]
                             [--time-budget S] [--budget-clock wall|cpu]

``--robot`` picks the folder under ``../shared/data/mbm`` (its URDF, SRDF and ``problems.json``; the planned
joints are the file's ``joints``, the others held); ``--spheres auto`` plans with the spheres robointel fits
to the meshes instead of the folder's ``<robot>_spherized.urdf``. ``refused_free_starts`` counts the
problems whose start or goal we refused although the checker finds it >= 1 mm clear.

``--budget-clock cpu`` counts our time budget in the process's CPU time instead of wall time (the default):
on a machine shared with other busy processes a 1 s wall budget buys only the process's share of a core, so
success rates under load then approximate an idle machine's; ``plan_ms`` stays wall time, ``plan_cpu_ms`` is
the CPU time, and the JSON names the clock (``ours_settings.budget_clock``).

``--all`` runs every valid problem (689); ``--jsonl`` appends one line per planner and problem as soon as
it is judged, so a long run loses nothing, and ``--resume`` skips the problems already in that file
(the summary is then computed over all rows of the file).

Prints one JSON object (``--json``) or a table; a progress bar goes to stderr. Beside the summary keys it prints
the stage profile of ours (``stage_ms`` and ``stage_cpu_ms``: median, p95 and sum per stage, wall and process CPU
time), each peer's stages (``vamp_stage_ms``: search, simplification, TOPP-RA) and, with VAMP,
``plan_ms_ratio_vs_vamp_median`` (our median plan_ms over VAMP + simplification + TOPP-RA's, same run), and the
same ratio of process CPU times (``plan_cpu_ratio_vs_vamp_median``).
cuRobo's figures are the published ones (RTX 6000 Ada GPU), not run here.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import trimesh
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _mbm_checker import MBMChecker  # noqa: E402
from _mbm_peers import OMPLPeer, VAMPPeer  # noqa: E402

CUROBO_PUBLISHED = {"source": "cuRobo (Sundaralingam et al. 2023), published on MotionBenchMaker, RTX 6000 Ada GPU",
                    "run_here": False, "success": 1.0, "plan_ms_median": 31.0, "plan_ms_p98": 161.0,
                    "duration_s_median": 1.33}
TARGETS = {"success": 0.999, "collisions_independent": 0, "plan_ms_median": 20.0, "plan_ms_p95": 30.0,
           "plan_ms_ratio_vs_vamp_median": 0.4,
           "pointcloud_update_ms": 20.0, "frmp_speedup_vs_sqp": 100.0}
SEED0 = 7919  # planner seeds: SEED0 + problem index (never used for tuning)


def data_dir(robot: str = "ur5") -> Path:
    env = os.environ.get("ROBOINTEL_DATA")
    root = Path(env) if env else Path(__file__).resolve().parents[1].parent / "shared" / "data"
    if not (root / "mbm" / robot).is_dir():
        root = Path("/work/shared/data")
    return root / "mbm" / robot


def robot_files(d: Path) -> tuple[Path, Path, Path]:
    """(URDF, SRDF, sphere URDF) of an MBM robot folder: ``<robot>.urdf``, ``.srdf`` and ``_spherized.urdf``."""
    name = d.name
    return d / f"{name}.urdf", d / f"{name}.srdf", d / f"{name}_spherized.urdf"


def refused_free(row: dict, start_mm: float, goals_mm: list[float]) -> bool:
    """Whether our planner refused a start or goal (``CollisionAtStart``) that the checker finds >= 1 mm clear."""
    reason = row.get("reason") or ""
    if not reason.startswith("CollisionAtStart"):
        return False
    if "start configuration" in reason:
        return start_mm >= 1.0
    return max(goals_mm, default=-1.0) >= 1.0


def _busy(cpus: set[int], wait_s: float = 0.3) -> dict[int, float]:
    """Each CPU's busy share (0..1) over ``wait_s`` seconds, from /proc/stat (empty where unreadable)."""
    def sample() -> dict[int, tuple[int, int]]:
        out = {}
        with open("/proc/stat") as f:
            for line in f:
                name, *v = line.split()
                if name.startswith("cpu") and name[3:].isdigit() and int(name[3:]) in cpus:
                    n = [int(x) for x in v]
                    out[int(name[3:])] = (n[3] + n[4], sum(n[:8]))  # idle + iowait, total
        return out

    try:
        a = sample()
        time.sleep(wait_s)
        b = sample()
    except OSError:
        return {}
    return {c: 1.0 - (b[c][0] - a[c][0]) / max(b[c][1] - a[c][1], 1) for c in b if c in a}


def one_core() -> None:
    """Pin the process to one CPU (the least busy one it may run on) and its thread pools to one thread.

    ``ROBOINTEL_BENCH_CPU`` names the CPU instead. The least busy one, so that two benchmarks started
    on a shared machine do not take turns on the same core while another idles.
    """
    try:
        allowed = os.sched_getaffinity(0)
        want = os.environ.get("ROBOINTEL_BENCH_CPU")
        if want is not None and int(want) in allowed:
            cpu = int(want)
        else:
            busy = _busy(set(allowed))
            cpu = min(allowed, key=lambda c: (busy.get(c, 0.0), c))
        os.sched_setaffinity(0, {cpu})
    except (AttributeError, OSError, ValueError):
        pass
    threadpool_limits(1)
    try:
        import numba

        numba.set_num_threads(1)
    except (ImportError, ValueError):
        pass


def stats(ms: list[float]) -> dict:
    if not ms:
        return {"median": None, "p95": None, "p98": None, "max": None}
    a = np.asarray(ms, float)
    return {"median": float(np.median(a)), "p95": float(np.percentile(a, 95)), "p98": float(np.percentile(a, 98)),
            "max": float(a.max())}


def surface_cloud(raw: dict, n: int, seed: int) -> np.ndarray:
    """``n`` points sampled uniformly (by area) from the surfaces of a raw problem's obstacles."""
    meshes = []
    for o in raw["sphere"]:
        meshes.append(trimesh.creation.icosphere(subdivisions=3, radius=o["radius"]).apply_translation(o["position"]))
    for kind in ("box", "cylinder"):
        for o in raw[kind]:
            x, y, z, w = o["orientation_quat_xyzw"]
            T = trimesh.transformations.quaternion_matrix([w, x, y, z])
            T[:3, 3] = o["position"]
            if kind == "box":
                meshes.append(trimesh.creation.box(extents=2.0 * np.asarray(o["half_extents"]), transform=T))
            else:
                meshes.append(trimesh.creation.cylinder(radius=o["radius"], height=o["length"], sections=32,
                                                        transform=T))
    mesh = trimesh.util.concatenate(meshes)
    pts, _ = trimesh.sample.sample_surface(mesh, n, seed=seed)
    return np.ascontiguousarray(pts, dtype=float)


class Ours:
    """robointel.planning.plan_motion on the robot of the MBM folder (its planned joints those of problems.json)."""

    def __init__(self, urdf: Path, srdf: Path, d_min: float, budget: float, *, joints: list[str] | None = None,
                 spheres: Path | None = None, clock: str = "wall") -> None:
        from robointel.planning import Environment, MotionSettings, plan_motion
        from robointel.robot import Robot

        self.Environment, self.MotionSettings, self.plan_motion = Environment, MotionSettings, plan_motion
        self.robot = Robot.load(urdf, srdf=srdf, joints=joints)
        self.srdf = srdf
        self.d_min, self.budget, self.clock = d_min, budget, clock
        # spheres: the decomposition shipped with the problems, or None for the automatic model
        self.env_kw = {"srdf": srdf, "spheres": spheres} if spheres is not None else {"srdf": srdf}
        #: process CPU time of the last :meth:`solve`'s ``plan_motion``, ms (on a shared machine the wall
        #: time counts the other processes' turns too)
        self.last_cpu_ms = float("nan")

    def solve(self, problem, seed: int):
        from robointel.errors import RobointelError

        t0 = time.perf_counter()
        try:
            env = self.Environment(self.robot, problem.obstacles, **self.env_kw)
        except RobointelError as exc:
            return None, (time.perf_counter() - t0) * 1e3, 0.0, f"{type(exc).__name__}: {exc}"
        t1, c1 = time.perf_counter(), time.process_time()
        self.last_cpu_ms = float("nan")
        try:
            plan = self.plan_motion(self.robot, env, problem.start, problem.goals,
                                    settings=self.MotionSettings(d_min=self.d_min, seed=seed, time_budget_s=self.budget,
                                                                 budget_clock=self.clock))
        except RobointelError as exc:
            return None, (t1 - t0) * 1e3, (time.perf_counter() - t1) * 1e3, f"{type(exc).__name__}: {exc}"
        self.last_cpu_ms = (time.process_time() - c1) * 1e3
        return plan, (t1 - t0) * 1e3, (time.perf_counter() - t1) * 1e3, plan.reason

    def pointcloud_update_ms(self, raws: list[dict], reps: int = 3) -> list[float]:
        env = self.Environment(self.robot, [], **self.env_kw)
        out = []
        for k, raw in enumerate(raws):
            pts = surface_cloud(raw, 100_000, seed=k)
            env.update_pointcloud(pts)  # first call: allocation, compilation
            for r in range(reps):
                pts = surface_cloud(raw, 100_000, seed=1000 * k + r + 1)
                t0 = time.perf_counter()
                env.update_pointcloud(pts)
                out.append((time.perf_counter() - t0) * 1e3)
        return out


def frmp_speedup(root: Path) -> tuple[float | None, str]:
    """``speedup_vs_sqp`` of ``benchmarks/frmp.py --json --quick`` run in a subprocess."""
    env = dict(os.environ, PYTHONPATH=str(root / "src"))
    try:
        out = subprocess.run([sys.executable, str(root / "benchmarks" / "frmp.py"), "--json", "--quick"],
                             capture_output=True, text=True, env=env, timeout=1800, check=True)
        return float(json.loads(out.stdout)["speedup_vs_sqp"]), "benchmarks/frmp.py --json --quick"
    except (subprocess.SubprocessError, ValueError, KeyError) as exc:
        return None, f"benchmarks/frmp.py failed: {exc}"


def stream(sink, planner: str, row: dict) -> None:
    """Append one judged row to the JSONL sink (flushed at once)."""
    if sink is not None:
        sink.write(json.dumps(dict(row, planner=planner), default=_jsonable) + "\n")
        sink.flush()


def _jsonable(v):
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    return str(v)


def load_rows(path: Path, rows: dict[str, list[dict]]) -> set[tuple[str, int]]:
    """Rows of an earlier run from ``path`` into ``rows``; the problems every planner has done."""
    if not path.exists():
        return set()
    seen: dict[str, set[tuple[str, int]]] = {k: set() for k in rows}
    for line in path.read_text().splitlines():
        try:
            r = json.loads(line)
        except json.JSONDecodeError:  # a line cut by an interrupted run
            continue
        name = r.pop("planner", None)
        if name in rows and (r["family"], r["index"]) not in seen[name]:
            rows[name].append(r)
            seen[name].add((r["family"], r["index"]))
    sets = list(seen.values())
    both = set.intersection(*sets) if sets else set()
    for name in rows:  # a problem only some planners finished is run again for all
        rows[name] = [r for r in rows[name] if (r["family"], r["index"]) in both]
    return both


def summarise(prefix: str, rows: list[dict], families: list[str]) -> dict:
    ok = [r for r in rows if r["success"]]
    fam = {f: {"problems": sum(r["family"] == f for r in rows), "success": sum(r["success"] and r["family"] == f
                                                                              for r in rows)} for f in families}
    return {f"{prefix}problems": len(rows), f"{prefix}success": (len(ok) / len(rows)) if rows else None,
            f"{prefix}success_count": len(ok),
            f"{prefix}collisions_independent": sum(r["collision"] and r["solved"] for r in rows),
            f"{prefix}plan_ms": stats([r["plan_ms"] for r in rows]),
            f"{prefix}plan_ms_solved": stats([r["plan_ms"] for r in rows if r["solved"]]),
            f"{prefix}duration_s": stats([r["duration_s"] for r in ok]),
            f"{prefix}min_clearance_mm": stats([1e3 * r["min_clearance"] for r in rows if r["solved"]]),
            f"{prefix}limit_violations": sum(r["limit"] is not None for r in rows),
            f"{prefix}success_ignoring_limits": sum(r["solved"] and not r["collision"] and r.get("reaches", True)
                                                    for r in rows),
            f"{prefix}failures": {f"{r['family']}/{r['index']}": r["reason"] for r in rows if not r["success"]},
            f"{prefix}per_family": fam}


def stage_profile(rows: list[dict]) -> dict:
    """Per-stage wall and process-CPU time over the problems: ``stage_ms`` and ``stage_cpu_ms``.

    Each is {stage: {median, p95, sum}} in ms over every problem that reached the planner (a stage a
    problem did not run counts 0 there); with ``plan_cpu_to_wall_median``, the median over problems
    of the plan's CPU time over its wall time (below 1: the process waited for a core).
    """
    out: dict = {}
    for key, name in (("stages_ms", "stage_ms"), ("stages_cpu_ms", "stage_cpu_ms")):
        have = [r[key] for r in rows if key in r]
        stages = sorted({k for r in have for k in r})
        out[name] = {k: {"median": float(np.median(v)), "p95": float(np.percentile(v, 95)), "sum": float(np.sum(v))}
                     for k in stages for v in [[r.get(k, 0.0) for r in have]]}
    ratio = [r["plan_cpu_ms"] / r["plan_ms"] for r in rows
             if r.get("plan_cpu_ms", float("nan")) == r.get("plan_cpu_ms") and r.get("plan_ms", 0) > 0]
    if ratio:
        out["plan_cpu_to_wall_median"] = float(np.median(ratio))
    return out


def vamp_ratio(out: dict) -> dict:
    """``plan_ms_ratio_vs_vamp_median``: our median plan_ms over VAMP + simplification + TOPP-RA's, same run."""
    ours, vamp = (out.get("plan_ms") or {}).get("median"), (out.get("vamp_plan_ms") or {}).get("median")
    cpu, vcpu = (out.get("plan_cpu_ms") or {}).get("median"), (out.get("vamp_plan_cpu_ms") or {}).get("median")
    return {"plan_ms_ratio_vs_vamp_median": ours / vamp if ours is not None and vamp else None,
            "plan_cpu_ratio_vs_vamp_median": cpu / vcpu if cpu is not None and vcpu else None,
            "plan_ms_ratio_vs_vamp_note": "median plan_ms of ours over the median of VAMP RRT-Connect + simplify + "
                                          "TOPP-RA on the same problems, one process, one core; "
                                          "plan_cpu_ratio_vs_vamp_median: the same with process CPU time (on a "
                                          "loaded machine the wall times count the other processes' turns)"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--all", action="store_true", help="every valid problem (the default without --per-family)")
    ap.add_argument("--per-family", type=int, default=None, help="first N valid problems of each family")
    ap.add_argument("--jsonl", type=Path, default=None, help="append each judged row to this JSONL file")
    ap.add_argument("--interleave", action="store_true",
                    help="run the families in turn (problem k of every family, then k + 1), so a cut-short run "
                         "covers every family")
    ap.add_argument("--resume", action="store_true", help="skip the problems already in --jsonl")
    ap.add_argument("--summary-only", action="store_true",
                    help="with --jsonl: summarise the rows of that file (problems not in it are left out)")
    ap.add_argument("--families", nargs="*", default=None)
    ap.add_argument("--peers", nargs="*", default=["ompl", "vamp"], choices=["ompl", "vamp"],
                    help="peers to run beside ours (default both); a bare --peers runs none")
    ap.add_argument("--no-ours", action="store_true", help="run the peers and the checker only")
    ap.add_argument("--ompl-timeout", type=float, default=10.0, help="OMPL time limit per problem, s")
    ap.add_argument("--check-polylines", action="store_true",
                    help="also judge the peers' geometric paths (before TOPP-RA) at constant joint speed")
    ap.add_argument("--d-min", type=float, default=0.001,
                    help="our clearance, m (plan_motion's dense check accepts d_min - 1 mm, i.e. contact)")
    ap.add_argument("--time-budget", type=float, default=1.0, help="our search budget per problem, s")
    ap.add_argument("--budget-clock", default="wall", choices=["wall", "cpu"],
                    help="the clock our budget is counted on: wall time (default), or the process's CPU time, so "
                         "that on a loaded machine the budget buys the work it buys on an idle one")
    ap.add_argument("--frmp", action="store_true", help="also run benchmarks/frmp.py --quick for the SQP speed-up")
    ap.add_argument("--robot", default="ur5", help="the robot folder under ../shared/data/mbm (ur5, fetch)")
    ap.add_argument("--spheres", default="file", choices=["file", "auto"],
                    help="our collision spheres: the folder's <robot>_spherized.urdf, or fitted to the meshes (auto)")
    args = ap.parse_args()
    one_core()
    load = os.getloadavg()[0]

    from robointel.io.mbm import load_mbm_problems

    d = data_dir(args.robot)
    if not d.is_dir():
        ap.error(f"no MBM robot folder {d}")
    urdf, srdf, sphere_urdf = robot_files(d)
    pset = load_mbm_problems(d / "problems.json")
    raw_all = json.loads((d / "problems.json").read_text())["problems"]
    if args.all and args.per_family is not None:
        ap.error("--all and --per-family exclude each other")
    problems = pset.select(families=args.families, per_family=None if args.all else args.per_family)
    families = list(dict.fromkeys(p.family for p in problems))
    if args.interleave:
        rank: dict[str, int] = {}
        keyed = []
        for p in problems:
            rank[p.family] = rank.get(p.family, -1) + 1
            keyed.append(((rank[p.family], families.index(p.family)), p))
        problems = [p for _, p in sorted(keyed, key=lambda kp: kp[0])]
    checker = MBMChecker(urdf, srdf, joints=list(pset.joint_names))
    vmax = checker.vmax.copy()
    amax = 3.0 * vmax
    peers = {}
    vamp_error = None
    if "ompl" in args.peers:
        peers["ompl"] = OMPLPeer(checker)
    if "vamp" in args.peers:
        try:
            peers["vamp"] = VAMPPeer(args.robot)
        except (ImportError, AttributeError) as exc:
            vamp_error = f"VAMP has no {args.robot!r} here: {exc}"
    ours = None
    ours_error = None
    if not args.no_ours:
        try:
            ours = Ours(urdf, srdf, args.d_min, args.time_budget, joints=list(pset.joint_names),
                        spheres=sphere_urdf if args.spheres == "file" else None, clock=args.budget_clock)
        except ImportError as exc:
            ours_error = f"robointel.planning.plan_motion not available in this tree: {exc}"
    rows: dict[str, list[dict]] = {k: [] for k in (["ours"] if ours else []) + list(peers)}
    done = load_rows(args.jsonl, rows) if (args.jsonl is not None and args.resume) else set()
    if args.summary_only:
        if args.jsonl is None:
            ap.error("--summary-only needs --jsonl")
        done = load_rows(args.jsonl, rows)
        problems = [p for p in problems if (p.family, p.index) in done]
        families = list(dict.fromkeys(p.family for p in problems))
    sink = args.jsonl.open("a") if args.jsonl is not None and not args.summary_only else None
    endpoints_free = endpoints = 0
    raw_by_key = {(f, p["index"]): p for f, ps in raw_all.items() for p in ps}
    if "vamp" in peers and problems:  # warm-up outside the figures (first-call allocations)
        peers["vamp"].solve(raw_by_key[(problems[0].family, problems[0].index)], vmax, amax)
    if ours is not None and problems:  # warm-up: compiled kernels (numba) are built on the first call
        ours.solve(problems[0], SEED0)
    console = Console(stderr=True)
    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                  TimeElapsedColumn(), console=console) as bar:
        task = bar.add_task("MBM problems", total=len(problems))
        for p in problems:
            if (p.family, p.index) in done:
                bar.advance(task)
                continue
            raw = raw_by_key[(p.family, p.index)]
            ends = [checker.check_configuration(np.asarray(q, float), raw) for q in [raw["start"], *raw["goals"]]]
            endpoints += len(ends)
            endpoints_free += sum(not v.collision for v in ends)
            end_mm = [1e3 * v.min_clearance for v in ends]
            base = {"family": p.family, "index": p.index}
            if ours is not None:
                plan, env_ms, plan_ms, reason = ours.solve(p, SEED0 + p.index)
                row = dict(base, solved=False, success=False, collision=False, limit=None, plan_ms=plan_ms,
                           plan_cpu_ms=ours.last_cpu_ms, env_ms=env_ms, duration_s=None,
                           min_clearance=float("nan"), reason=reason)
                if plan is not None and plan.trajectory is not None:
                    tr = plan.trajectory
                    v = checker.check_trajectory(tr.t, tr.q, raw, qd=tr.qd, amax=amax)
                    row.update(solved=bool(plan.success), collision=v.collision, limit=v.limit_violation,
                               reaches=v.reaches_goal,
                               min_clearance=v.min_clearance, duration_s=float(tr.t[-1] - tr.t[0]),
                               planner_clearance=plan.min_clearance_m, pair=v.pair, stages_ms=plan.timings,
                               stages_cpu_ms=plan.cpu_timings,
                               timing=tr.meta.get("timing", ""))
                    row["success"] = bool(plan.success) and v.ok
                    if plan.success and not v.ok:
                        row["reason"] = (f"checker: collision {v.pair}" if v.collision else
                                         v.limit_violation or "does not reach the goal")
                row["refused_free_start"] = refused_free(row, end_mm[0], end_mm[1:])
                rows["ours"].append(row)
                stream(sink, "ours", row)
            for name, peer in peers.items():
                bar.update(task, description=f"{p.name} {name}")
                c_peer = time.process_time()
                if name == "ompl":
                    r = peer.solve(raw, vmax, amax, timeout=args.ompl_timeout, seed=SEED0 + p.index)
                else:
                    r = peer.solve(raw, vmax, amax, seed=p.index)
                c_peer = (time.process_time() - c_peer) * 1e3
                row = dict(base, solved=r.solved, success=False, collision=False, limit=None, plan_ms=r.total_ms,
                           plan_cpu_ms=c_peer, duration_s=None, min_clearance=float("nan"), reason=r.reason,
                           stages_ms={"plan": r.plan_ms, "simplify": r.simplify_ms, "toppra": r.toppra_ms})
                if r.solved:
                    v = checker.check_trajectory(r.t, r.q, raw, qd=r.qd, amax=amax)
                    row.update(success=v.ok, collision=v.collision, limit=v.limit_violation, reaches=v.reaches_goal,
                               min_clearance=v.min_clearance, duration_s=r.duration, pair=v.pair)
                    if not v.ok:
                        row["reason"] = (f"checker: collision {v.pair}" if v.collision else
                                         v.limit_violation or "does not reach the goal")
                if args.check_polylines and r.solved:
                    L = np.abs(np.diff(r.path, axis=0)).max(1)
                    T = np.concatenate([[0.0], np.cumsum(L / vmax.min())])
                    pv = checker.check_trajectory(T, r.path, raw)
                    row["polyline_collision"] = pv.collision
                rows[name].append(row)
                stream(sink, name, row)
            bar.advance(task)
            if not console.is_terminal:  # a log line per problem when stderr is a file
                print(f"{p.name} done", file=sys.stderr, flush=True)
    if sink is not None:
        sink.close()
    order = {(p.family, p.index): k for k, p in enumerate(problems)}
    for name in rows:  # resumed rows first in the file: back to problem order, problems of this selection only
        rows[name] = sorted((r for r in rows[name] if (r["family"], r["index"]) in order),
                            key=lambda r: order[(r["family"], r["index"])])
    out: dict = {"benchmark": f"MotionBenchMaker {args.robot} (problems.json of vamp-planner 0.6.4)",
                 "robot": args.robot, "spheres": args.spheres, "vamp_error": vamp_error,
                 "ours_settings": {"d_min_m": args.d_min, "time_budget_s": args.time_budget,
                                   "budget_clock": args.budget_clock,
                                   "seeds": f"{SEED0} + problem index"},
                 "problems": len(problems), "families": families, "one_core": True,
                 "cpu": sorted(os.sched_getaffinity(0)), "load_average_1min": load,
                 "load_average_1min_end": os.getloadavg()[0],
                 "warmup": "once per process, untimed: the first problem is solved once before the run (numba "
                           "kernels loaded from the disk cache or compiled, the collision meshes and their hulls "
                           "loaded, VAMP's first-call allocations); every figure below is a later call",
                 "limits": {"velocity_rad_s": vmax.tolist(), "acceleration_rad_s2": amax.tolist()},
                 "checker": {"what": "coal exact mesh distances, 1 ms resample, SRDF-disabled pairs removed",
                             "valid_endpoints_collision_free": endpoints_free, "valid_endpoints": endpoints}}
    if ours is not None:
        out.update(summarise("", rows["ours"], families))
        out["refused_free_starts"] = sum(bool(r.get("refused_free_start")) for r in rows["ours"])
        out["env_build_ms"] = stats([r["env_ms"] for r in rows["ours"]])
        stages = sorted({k for r in rows["ours"] for k in r.get("stages_ms", {})})
        out["stage_ms_median"] = {k: float(np.median([r["stages_ms"].get(k, 0.0) for r in rows["ours"]
                                                      if "stages_ms" in r])) for k in stages}
        out.update(stage_profile(rows["ours"]))
        out["plan_ms_note"] = "plan_motion wall time (search + smoothing + time parametrisation + its dense check)"
        cpu = [r.get("plan_cpu_ms", float("nan")) for r in rows["ours"]]  # rows resumed from older runs lack it
        out["plan_cpu_ms"] = stats([c for c in cpu if c == c])
        out["plan_cpu_ms_note"] = "the same calls' process CPU time (the wall time less the other processes' turns)"
        with console.status("point-cloud updates (100k points)"):
            pc = ours.pointcloud_update_ms([raw_by_key[(p.family, p.index)] for p in problems[:: max(1, len(
                problems) // 7)][:7]])
        out["pointcloud_update_ms"] = stats(pc)
    else:
        out.update({"success": None, "collisions_independent": None, "plan_ms": None, "duration_s": None,
                    "pointcloud_update_ms": None, "ours_error": ours_error or "--no-ours"})
    for name in peers:
        out.update(summarise(f"{name}_", rows[name], families))
        if args.check_polylines:
            out[f"{name}_polyline_collisions_independent"] = sum(r.get("polyline_collision", False)
                                                                 for r in rows[name])
    for name in peers:
        out[f"{name}_stage_ms"] = stage_profile(rows[name])["stage_ms"]
        out[f"{name}_plan_cpu_ms"] = stats([r["plan_cpu_ms"] for r in rows[name] if "plan_cpu_ms" in r])
    if ours is not None and "vamp" in peers:
        out.update(vamp_ratio(out))
        common = [(a["duration_s"], b["duration_s"]) for a, b in zip(rows["ours"], rows["vamp"])
                  if a["success"] and b["success"]]
        out["duration_ratio_vs_vamp_median"] = float(np.median([a / b for a, b in common])) if common else None
    if args.frmp:
        out["frmp_speedup_vs_sqp"], out["frmp_source"] = frmp_speedup(Path(__file__).resolve().parents[1])
    else:
        out["frmp_speedup_vs_sqp"] = None
        out["frmp_source"] = "not run (pass --frmp; benchmarks/frmp.py exposes no function, only its JSON)"
    out["curobo_published"] = CUROBO_PUBLISHED
    out["targets"] = TARGETS
    if args.json:
        print(json.dumps(out, default=float))
        return
    for k, v in out.items():
        if not k.endswith("failures"):
            print(f"{k}: {v}")


if __name__ == "__main__":
    main()
