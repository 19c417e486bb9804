"""Table 7.1 of the dissertation, measured: the FRMP on the Table 7.1 workcell beside the peers.

Ours: CFS trajectory planning per segment (7.1)-(7.3), temporal optimization by CFS (7.7)-(7.9),
the joined trajectory checked on a 1 ms resample and tracked in MuJoCo, receding-horizon replanning
with a moving obstacle. Peers, measured in the same run on the same scene: SLSQP (scipy) on the same
nonconvex segment problem (same cost, same exact distance constraints, same initial guess), OMPL
RRTConnect + simplification (same sphere collision checker and clearance) on the blocked segments,
and TOPP-RA (toppra) on the same geometric path with the same velocity/acceleration limits.

    python benchmarks/frmp.py [--json] [--quick] [--scene table71]

Times are wall-clock medians over repeats (CFS, temporal, OMPL) or single runs (SLSQP); ``*_cpu_ms``
are the process CPU times of the same calls (less sensitive to other jobs on a shared machine).
The machine is shared (2 cores): the load average at the start is reported with the figures.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

PAPER = {"cfs_s_blocked": [0.894, 0.840], "cfs_iterations_blocked": [2, 5], "sqp_s_blocked": [46.8, 48.9],
         "sqp_iterations_blocked": [94, 96], "temporal_ms": 31.0, "operational_time_fixed_s": 15.00,
         "operational_time_frmp_s": 6.63}


def median(x) -> float:
    return float(np.median(np.asarray(x, float)))


def toppra_duration(path: np.ndarray, vmax: np.ndarray, amax: np.ndarray, gridpoints: int = 400):
    """TOPP-RA on the geometric spline through ``path`` (uniform parameter, not-a-knot: the same
    curve the temporal optimization re-times), zero velocity at both ends."""
    import toppra
    import toppra.algorithm as algo
    import toppra.constraint as constraint

    ss = np.linspace(0, 1, len(path))
    p = toppra.SplineInterpolator(ss, path)
    inst = algo.TOPPRA([constraint.JointVelocityConstraint(np.stack([-vmax, vmax], 1)),
                        constraint.JointAccelerationConstraint(np.stack([-amax, amax], 1))], p,
                       parametrizer="ParametrizeConstAccel", gridpoints=np.linspace(0, 1, gridpoints))
    t0 = time.perf_counter()
    traj = inst.compute_trajectory(0, 0)
    ms = (time.perf_counter() - t0) * 1e3
    return (float(traj.duration) if traj is not None else float("nan")), ms


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--quick", action="store_true", help="fewer repeats")
    ap.add_argument("--scene", default="table71")
    args = ap.parse_args()
    load = os.getloadavg()[0]

    from robointel.geometry import Sphere
    from robointel.planning.frmp import execute, make_planners, plan_scene, planner_settings
    from robointel.planning.ompl_peer import rrtconnect
    from robointel.planning.replan import receding_horizon
    from robointel.planning.scene import load_scene
    from robointel.planning.sqp import slsqp_segment
    from robointel.planning.temporal import temporal_optimize

    reps = 3 if args.quick else 9
    scene = load_scene(args.scene)
    planners = make_planners(scene)
    res = plan_scene(scene, planners=planners)  # also warms up compiled kernels
    nseg = len(scene.steps)
    blocked = [bool(b) for b in res.blocked]

    # CFS per segment (cold QP start every repeat)
    cfs_ms = [[] for _ in range(nseg)]
    cfs_cpu = [[] for _ in range(nseg)]
    cfs_it = [0] * nseg
    for _ in range(reps):
        for i, N in enumerate(scene.steps):
            pl = planners[N]
            pl.reset_warm_start()
            t0, c0 = time.perf_counter(), time.process_time()
            seg = pl.plan_segment(scene.waypoints[i], scene.waypoints[i + 1])
            cfs_ms[i].append((time.perf_counter() - t0) * 1e3)
            cfs_cpu[i].append((time.process_time() - c0) * 1e3)
            cfs_it[i] = seg.iterations
    cfs_med = [median(c) for c in cfs_ms]
    cfs_cpu_med = [median(c) for c in cfs_cpu]

    # temporal optimization per segment
    tmp_ms = [[] for _ in range(nseg)]
    tmp_cpu = [[] for _ in range(nseg)]
    for _ in range(reps):
        for i, seg in enumerate(res.segments):
            t0, c0 = time.perf_counter(), time.process_time()
            temporal_optimize(seg.path, scene.vmax, scene.amax, dt=scene.dt, w3=scene.weights["w3"],
                              w4=scene.weights["w4"])
            tmp_ms[i].append((time.perf_counter() - t0) * 1e3)
            tmp_cpu[i].append((time.process_time() - c0) * 1e3)
    tmp_med = [median(c) for c in tmp_ms]
    tmp_cpu_med = [median(c) for c in tmp_cpu]

    # SLSQP on the same segment problems (single runs: seconds each)
    sqp_ms, sqp_it, sqp_ok, sqp_cost, cfs_cost, sqp_cpu = [], [], [], [], [], []
    for i, N in enumerate(scene.steps):
        pl = planners[N]
        c0 = time.process_time()
        X, sq = slsqp_segment(pl, scene.waypoints[i], scene.waypoints[i + 1], tol=1e-3, max_iter=300)
        sqp_cpu.append((time.process_time() - c0) * 1e3)
        sqp_ms.append(sq.seconds * 1e3)
        sqp_it.append(sq.iterations)
        Xr = np.linspace(scene.waypoints[i], scene.waypoints[i + 1], N + 1)
        ok = bool(sq.success and sq.max_violation < 1e-4)
        sqp_ok.append(ok)
        sqp_cost.append(pl._cost(X, Xr))
        cfs_cost.append(pl._cost(res.segments[i].path, Xr))
    bl = [i for i in range(nseg) if blocked[i]]
    speedup = (sum(sqp_ms[i] for i in bl) / sum(cfs_med[i] for i in bl)) if bl else float("nan")

    # OMPL RRTConnect + simplification on the blocked segments, same checker and clearance
    st = planner_settings(scene)
    clearance = st.d_min + st.safety
    ompl_ms, ompl_cpu, ompl_solved = [], [], []
    for i in bl:
        runs, cpus = [], []
        for s_ in range(reps):
            c0 = time.process_time()
            runs.append(rrtconnect(scene.robot, scene.obstacles, scene.waypoints[i], scene.waypoints[i + 1],
                                   clearance=clearance, seed=s_))
            cpus.append((time.process_time() - c0) * 1e3)
        ompl_ms.append(median([r.total_ms for r in runs]))
        ompl_cpu.append(median(cpus))
        ompl_solved.append(int(sum(r.solved for r in runs)))

    # TOPP-RA on the same geometric path and limits
    top_T, top_ms = [], []
    for seg in res.segments:
        T, ms = toppra_duration(seg.path, scene.vmax, scene.amax)
        top_T.append(T)
        top_ms.append(ms)
    toppra_time = float(sum(top_T))

    # MuJoCo execution
    ex = execute(res)

    # replanning: a hand comes down into the path of segment 1 and stays there
    stop, s0 = np.array([0.62, 0.16, 0.30]), np.array([0.62, 0.16, 0.75])
    hand = Sphere(s0, 0.06, name="hand")
    rst = planner_settings(scene)
    rst.max_iter = 10
    rp = receding_horizon(scene.robot, scene.obstacles, hand, lambda t: s0 + (stop - s0) * min(1.0, t / 1.5),
                          scene.waypoints[0], scene.waypoints[1], N=scene.steps[0], dt=scene.dt,
                          ticks=15 if args.quick else 30, settings=rst, vmax=scene.vmax, amax=scene.amax)

    out = {
        "scene": scene.name, "segments": nseg, "steps": scene.steps, "blocked": blocked,
        "cfs_ms": cfs_med, "cfs_cpu_ms": cfs_cpu_med, "cfs_iterations": cfs_it,
        "cfs_status": [s.status for s in res.segments],
        "cfs_total_ms": float(sum(cfs_med)),
        "cfs_blocked_max_ms": max(cfs_med[i] for i in bl) if bl else float("nan"),
        "sqp_ms": sqp_ms, "sqp_cpu_ms": sqp_cpu, "sqp_iterations": sqp_it, "sqp_success": sqp_ok,
        "sqp_cost": sqp_cost, "cfs_cost": cfs_cost,
        "speedup_vs_sqp": speedup,
        "temporal_ms": tmp_med, "temporal_cpu_ms": tmp_cpu_med, "temporal_stretch": [t.stretch for t in res.temporal],
        "temporal_cfs_iterations": [t.cfs.iterations for t in res.temporal],
        "operational_time_fixed_s": res.operational_time_fixed,
        "operational_time_frmp_s": res.operational_time_frmp,
        "toppra_time_s": toppra_time, "toppra_ms": top_ms,
        "duration_ratio_vs_toppra": res.operational_time_frmp / toppra_time,
        "ompl_ms": ompl_ms, "ompl_cpu_ms": ompl_cpu, "ompl_solved": ompl_solved,
        "cfs_faster_than_ompl": bool(all(cfs_med[i] < o for i, o in zip(bl, ompl_ms))),
        "cfs_faster_than_ompl_cpu": bool(all(cfs_cpu_med[i] < o for i, o in zip(bl, ompl_cpu))),
        "cfs_cpu_total_ms": float(sum(cfs_cpu_med)),
        "min_clearance_m": res.check.min_clearance, "d_min_m": scene.d_min,
        "limit_violations": res.check.limit_violations,
        "tracking_rms_rad": ex.rms_error_rad, "tracking_max_rad": ex.max_error_rad,
        "tracking_max_tcp_m": ex.max_tcp_error_m, "obstacle_contacts": ex.obstacle_contacts,
        "sim_min_distance_m": ex.min_distance_m,
        "replan_hz": rp.hz, "replan_ms_median": median(rp.times_ms), "replan_ms_max": float(np.max(rp.times_ms)),
        "replan_all_clear": bool(np.all(rp.feasible)), "replan_min_distance_m": float(np.min(rp.min_distance)),
        "repeats": reps, "load_average": load, "paper": PAPER,
    }
    if args.json:
        print(json.dumps(out))
        return
    print(f"scene {scene.name}: {nseg} segments {scene.steps}, blocked {blocked} (load {load:.1f} on 2 cores)")
    for i in range(nseg):
        print(f"  segment {i + 1}: CFS {cfs_med[i]:7.1f} ms / {cfs_it[i]:2d} it   SLSQP {sqp_ms[i]:8.1f} ms / "
              f"{sqp_it[i]:3d} it   temporal {tmp_med[i]:6.1f} ms   cost CFS {cfs_cost[i]:.4f} SLSQP {sqp_cost[i]:.4f}")
    print(f"  speed-up vs SLSQP (blocked): {speedup:.0f}x   OMPL (blocked) {ompl_ms} ms")
    print(f"  operational time {res.operational_time_fixed:.2f} s -> {res.operational_time_frmp:.2f} s "
          f"(TOPP-RA {toppra_time:.2f} s, ratio {res.operational_time_frmp / toppra_time:.3f})")
    print(f"  min clearance {res.check.min_clearance * 1000:.1f} mm, limit violations {res.check.limit_violations}, "
          f"MuJoCo RMS error {ex.rms_error_rad:.2e} rad, obstacle contacts {ex.obstacle_contacts}")
    print(f"  replanning {rp.hz:.0f} Hz (median {median(rp.times_ms):.1f} ms)")


if __name__ == "__main__":
    sys.exit(main())
