"""Chapter 5 (RLTT) headline figures, measured in one run.

DTW speed and agreement against dtaidistance (length 1000, 6-D, window 100), action-decomposition
boundary errors on 40 unlabelled demonstrations (20 labelled), GMR against the gmr package on the
same mixture, GMR reproduction of the 26 LASA shapes, SVM accuracy on the UCI F/T failures,
simulated peg-in-hole insertion with the LR Mate (skill model on the torque-level impedance
controller vs the same controller with a constant push vs position-only, same randomised starts), interference trials, grinding force tracking and the 60-demonstration pipeline time.

    python benchmarks/rltt.py [--json] [--trials 50] [--demos 60]
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--trials", type=int, default=50)
    ap.add_argument("--demos", type=int, default=60)
    ap.add_argument("--labelled", type=int, default=20)
    ap.add_argument("--interference-trials", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--insertion-gains", default="{}",
                    help='JSON of ImpedanceGains fields for the impedance trials, e.g. \'{"rot_stiffness": 300}\'')
    args = ap.parse_args()

    from robointel.learning import grinding as G
    from robointel.learning import insertion as I
    from robointel.learning.rltt import dtw_speed, ft_svm_accuracy, gmr_agreement, lasa_rmse, learn_insertion

    out: dict = {}
    t_all = time.perf_counter()
    out.update(dtw_speed())
    out["dtw_speedup"] = out["dtaidistance_ms"] / out["dtw_ms"]

    task = I.PegHole()
    out["clearance_um"] = task.clearance * 1e6
    rng = np.random.default_rng(args.seed)
    scene = I.HDDScene(task)
    t0 = time.perf_counter()
    demos = [I.demonstrate(task, rng, scene=scene, name=f"demo_{i:02d}") for i in range(args.demos)]
    out["demonstrations"] = len(demos)
    out["demonstrations_seated"] = int(sum(d.meta["seated"] for d in demos))
    out["demonstration_sim_s"] = time.perf_counter() - t0

    learned = learn_insertion(demos, n_labelled=args.labelled)
    out["pipeline_s"] = learned.timings["total"]
    out["pipeline_timings_s"] = learned.timings
    e = learned.boundary_errors[np.isfinite(learned.boundary_errors)] * 1e3
    out["segmentation_boundary_error_ms"] = {"median": float(np.median(e)), "p95": float(np.percentile(e, 95)),
                                             "n": int(e.size)}
    Xs = learned.skill.X_
    Xt = (Xs - learned.skill.x_mean_) / learned.skill.x_scale_
    out["gmr_max_abs_diff_vs_gmr"] = gmr_agreement(learned.skill.gmr, Xt[:: max(1, len(Xt) // 500)])

    cell = I.RobotPegHole(task)
    gains = I.ImpedanceGains(**json.loads(args.insertion_gains))
    out["insertion_controller"] = ("torque-level Cartesian impedance (tau = J^T W + h(q, qd) + friction), "
                                   "hole axis probed by touching the top face at 3 points, then the skill "
                                   "(GMR wrench -> tool twist) moves the lateral equilibrium and sets the axial speed")
    out["insertion_gains"] = json.loads(args.insertion_gains)
    starts = I.random_start_errors(np.random.default_rng(args.seed + 1), args.trials)
    res_skill, res_pos, res_imp = [], [], []
    for k, (lat, tilt) in enumerate(starts):
        T0 = cell.start_pose(lat, tilt)
        res_skill.append(cell.run_impedance(learned.skill.predict, T0, seed=k, gains=gains))
        res_imp.append(cell.run_impedance(None, T0, seed=k, gains=gains))
        res_pos.append(cell.run(None, T0, seed=k))
    out["insertion_trials"] = len(starts)
    out["insertion_success"] = int(sum(r.success for r in res_skill))
    out["insertion_success_position_only"] = int(sum(r.success for r in res_pos))
    out["insertion_success_impedance_no_skill"] = int(sum(r.success for r in res_imp))
    ok_imp = [r for r in res_imp if r.success]
    out["insertion_time_s_median_impedance_no_skill"] = float(np.median([r.time for r in ok_imp])) if ok_imp else None
    ok = [r for r in res_skill if r.success]
    out["insertion_time_s_median"] = float(np.median([r.time for r in ok])) if ok else None
    out["insertion_max_penetration_um"] = float(max(r.max_penetration for r in res_skill) * 1e6)
    tilts = np.degrees([s[1][1] for s in starts])
    def by_tilt(res):
        return {f"{lo:.0f}-{hi:.0f}deg": f"{sum(r.success for r, t in zip(res, tilts) if lo <= t < hi)}/"
                                         f"{sum(1 for t in tilts if lo <= t < hi)}" for lo, hi in ((0, 1), (1, 2), (2, 3.01))}

    out["insertion_success_by_tilt"] = by_tilt(res_skill)
    out["insertion_success_position_only_by_tilt"] = by_tilt(res_pos)
    out["insertion_failure_reasons"] = sorted({r.reason for r in res_skill if not r.success})

    # a peg 20 um larger than the hole: the skill-driven robot and the hand press test
    bad = I.RobotPegHole(task, interference=20e-6)
    inserted = 0
    for k, (lat, tilt) in enumerate(starts[: args.interference_trials]):
        inserted += bool(bad.run_impedance(learned.skill.predict, bad.start_pose(lat, tilt), seed=k,
                                           gains=gains).seated)
    for force in (50.0, 150.0, 300.0):
        inserted += bool(I.press_test(task, interference=20e-6, force=force).inserted)
    out["interference_trials"] = args.interference_trials + 3
    out["interference_inserted"] = inserted

    plate = G.Plate()
    gscene = I.HDDScene(plate, plate.tool())
    gdemos = [G.demonstrate_grinding(plate, rng, scene=gscene) for _ in range(4)]
    gskill = G.GrindingSkill(plate).fit(gdemos)
    gres = G.reproduce_grinding(plate, gskill)
    out["grinding_force_rms_rel"] = gres.rms_rel
    out["grinding_force_rms_rel_to_setpoint"] = gres.rms_rel_setpoint

    out["lasa_rmse"] = lasa_rmse()
    try:
        out["ft_svm_accuracy"] = ft_svm_accuracy()
    except Exception as exc:  # reference data missing
        out["ft_svm_accuracy"] = f"unavailable: {exc}"
    out["benchmark_s"] = time.perf_counter() - t_all
    out["paper"] = {"insertion_success": "48/50 (96%), clearance < 30 um, 60 demonstrations (20 labelled)"}
    if args.json:
        print(json.dumps(out, default=float))
    else:
        for k, v in out.items():
            print(f"{k:40s} {v}")


if __name__ == "__main__":
    main()
