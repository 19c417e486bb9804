"""Robot-core speed: FK + Jacobians of all collision spheres, closed-form and numeric IK.

Prints medians (µs) of ours beside a plain per-point Pinocchio loop (the way one would write it
with Pinocchio's Python API alone) and MuJoCo's mj_kinematics + mj_jac on the same robot, in one run.

Numeric IK: on random reachable poses (the FK of a uniform configuration within the limits) of the
UR5, the Panda, the Fetch's arm_with_torso group (MotionBenchMaker files) and the LR Mate, ours
(``Robot.ik_numeric``) beside TRAC-IK (``pytracik``, Speed mode, 5 ms timeout, eps 1e-5) and
Pinocchio's plain damped least squares (the textbook loop with clipping and random restarts), each
judged alike: a solution counts when it is within the limits and its FK matches the pose to 1e-5.

    python benchmarks/robot_core.py [--json] [--ik-poses 1000]
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin

from _timing import median_us

#: a solution counts when max |fk(q) - T| (4x4 entries: m and rotation) is below this
IK_TOL = 1e-5


def _mbm_dir(robot: str) -> Path:
    env = os.environ.get("ROBOINTEL_DATA")
    root = Path(env) if env else Path(__file__).resolve().parents[1].parent / "shared" / "data"
    if not (root / "mbm" / robot).is_dir():
        root = Path("/work/shared/data")
    return root / "mbm" / robot


def ik_robots():
    """(name, robot, base link, URDF path) of the arms the numeric IK is measured on."""
    from robointel.errors import DescriptionWarning
    from robointel.robot import Robot
    from robointel.robot.catalogue import example_robot_urdf

    d = _mbm_dir("fetch")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DescriptionWarning)
        fetch = Robot.load(d / "fetch.urdf", srdf=d / "fetch.srdf", group="arm_with_torso")
    lrmate = Robot.load("lrmate200id7l")
    return [("ur5", Robot.load("ur5"), "base_link", example_robot_urdf("ur5")),
            ("panda", Robot.load("panda", joints=[f"panda_joint{i}" for i in range(1, 8)]), "panda_link0",
             example_robot_urdf("panda")),
            ("fetch", fetch, "base_link", d / "fetch.urdf"),
            ("lrmate200id7l", lrmate, "base_link", lrmate.urdf_path)]


@contextlib.contextmanager
def _stdout_to_stderr():
    """Send what C code prints on file descriptor 1 to stderr (the JSON on stdout stays clean)."""
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def _ok(robot, q, T) -> bool:
    return q is not None and bool(np.all(q >= robot.lower - 1e-9) and np.all(q <= robot.upper + 1e-9)
                                  and np.abs(robot.fk(q) - T).max() < IK_TOL)


def pinocchio_dls(robot, T, rng, *, iters: int = 300, restarts: int = 20, damping: float = 1e-6):
    """Pinocchio's plain damped least squares (log6 error, local Jacobian, clipped), random restarts."""
    model, data = robot.model.copy(), None
    data = model.createData()
    fid = robot.frame_id(robot.flange_frame)
    target = pin.SE3(T[:3, :3].copy(), T[:3, 3].copy())
    for r in range(restarts + 1):
        q = 0.5 * (robot.lower + robot.upper) if r == 0 else rng.uniform(robot.lower, robot.upper)
        for _ in range(iters):
            pin.framesForwardKinematics(model, data, q)
            dM = data.oMf[fid].actInv(target)
            err = pin.log6(dM).vector
            if np.linalg.norm(err) < 1e-10:
                return q
            J = -pin.Jlog6(dM) @ pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
            q = np.clip(q - J.T @ np.linalg.solve(J @ J.T + damping * np.eye(6), err), robot.lower, robot.upper)
    return None


def ik_figures(n: int, seed: int = 2024) -> dict:
    """Success and time (ms) of ours, TRAC-IK and Pinocchio's DLS on ``n`` reachable poses per robot."""
    try:
        from trac_ik import TracIK
    except ImportError as exc:
        TracIK, tracik_error = None, f"pytracik not installed: {exc}"
    else:
        tracik_error = None
    out: dict = {"ik_poses": n, "ik_tol": IK_TOL, "ik_numeric_success": {}, "ik_numeric_ms": {},
                 "tracik_success": {}, "tracik_ms": {}, "pinocchio_dls_success": {}, "pinocchio_dls_ms": {},
                 "tracik_error": tracik_error}
    for name, robot, base, urdf in ik_robots():
        rng = np.random.default_rng(seed)
        poses = [robot.fk(q) for q in robot.random_configuration(rng, n)]
        robot.ik_numeric(poses[0])  # compile / load the kernel outside the timing
        ok, ms = 0, []
        for k, T in enumerate(poses):
            t0 = time.perf_counter()
            try:
                q = robot.ik_numeric(T, rng=k)
            except Exception:  # IKFailure: counted as a miss
                q = None
            ms.append((time.perf_counter() - t0) * 1e3)
            ok += _ok(robot, q, T)
        out["ik_numeric_success"][name] = ok / n
        out["ik_numeric_ms"][name] = {"median": float(np.median(ms)), "p95": float(np.percentile(ms, 95))}
        if TracIK is not None:
            tip = robot.flange_frame
            with _stdout_to_stderr():  # KDL prints its warnings on the C stdout
                solver = TracIK(base, tip, str(urdf), timeout=0.005, epsilon=1e-5, solver_type="Speed")
            if robot.description.continuous or not np.allclose(solver.joint_limits[0], robot.lower):
                solver.joint_limits = (robot.lower, robot.upper)  # the same limits as ours
            seed_q = 0.5 * (robot.lower + robot.upper)
            ok, ms = 0, []
            for T in poses:
                Tf = T @ np.linalg.inv(robot.tool)
                t0 = time.perf_counter()
                q = solver.ik(Tf[:3, 3], Tf[:3, :3], seed_q)
                ms.append((time.perf_counter() - t0) * 1e3)
                ok += _ok(robot, None if q is None else np.asarray(q, float), T)
            out["tracik_success"][name] = ok / n
            out["tracik_ms"][name] = {"median": float(np.median(ms)), "p95": float(np.percentile(ms, 95))}
        m = max(20, n // 10)  # the plain loop is slow: a tenth of the poses
        ok, ms = 0, []
        for T in poses[:m]:
            t0 = time.perf_counter()
            q = pinocchio_dls(robot, T, rng)
            ms.append((time.perf_counter() - t0) * 1e3)
            ok += _ok(robot, q, T)
        out["pinocchio_dls_success"][name] = ok / m
        out["pinocchio_dls_ms"][name] = {"median": float(np.median(ms)), "p95": float(np.percentile(ms, 95)),
                                         "poses": m}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--ik-poses", type=int, default=1000, help="reachable poses per robot for the numeric IK")
    args = ap.parse_args()
    load = os.getloadavg()[0]

    from robointel.robot import Robot

    robot = Robot.load("lrmate200id7l")
    rng = np.random.default_rng(0)
    Q = robot.random_configuration(rng, 64)
    Ts = [robot.fk(q) for q in Q]
    sp = robot.spheres
    it = iter(range(10**9))

    def ours_spheres():
        sp.kinematics(Q[next(it) % 64])

    # peer 1: Pinocchio, one frame per sphere, getFrameJacobian per sphere (the plain API route)
    model = robot.model.copy()
    fids = []
    for i, (link, c) in enumerate(zip(sp.links, sp.centers)):
        parent = model.frames[model.getFrameId(link)]
        pl = parent.placement * pin.SE3(np.eye(3), c)
        fids.append(model.addFrame(pin.Frame(f"s{i}", parent.parentJoint, model.getFrameId(link), pl,
                                             pin.FrameType.OP_FRAME)))
    data = model.createData()

    def pin_loop():
        q = Q[next(it) % 64]
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        for f in fids:
            _ = data.oMf[f].translation
            pin.getFrameJacobian(model, data, f, pin.LOCAL_WORLD_ALIGNED)

    # peer 2: MuJoCo from the same URDF, mj_kinematics + mj_comPos + mj_jac per sphere
    import mujoco

    mj = mujoco.MjModel.from_xml_string(robot.urdf)
    md = mujoco.MjData(mj)
    body_of = [mj.body(link).id if link != "base_link" else 0 for link in sp.links]
    jacp = np.zeros((3, mj.nv))

    def mujoco_loop():
        md.qpos[:] = Q[next(it) % 64]
        mujoco.mj_kinematics(mj, md)
        mujoco.mj_comPos(mj, md)
        for b, c in zip(body_of, sp.centers):
            p = md.xpos[b] + md.xmat[b].reshape(3, 3) @ c
            mujoco.mj_jac(mj, md, jacp, None, p, b)

    def ours_ik():
        robot.ik(Ts[next(it) % 64])

    out = {
        "n_spheres": len(sp),
        "fk_jacobians_all_spheres_us": median_us(ours_spheres),
        "pinocchio_per_frame_loop_us": median_us(pin_loop, 400),
        "mujoco_mj_jac_loop_us": median_us(mujoco_loop, 400),
        "ik_closed_form_us": median_us(ours_ik),
        "fk_us": median_us(lambda: robot.fk(Q[next(it) % 64])),
        "mass_matrix_us": median_us(lambda: robot.mass_matrix(Q[next(it) % 64])),
        "targets": {"fk_jacobians_all_spheres_us": 20, "ik_closed_form_us": 50, "ik_numeric_success": 0.999,
                    "ik_numeric_ms_median": 1.0},
    }
    out["speedup_vs_pinocchio_loop"] = out["pinocchio_per_frame_loop_us"] / out["fk_jacobians_all_spheres_us"]
    out["speedup_vs_mujoco_loop"] = out["mujoco_mj_jac_loop_us"] / out["fk_jacobians_all_spheres_us"]
    out.update(ik_figures(args.ik_poses))
    out["load_average_1min"] = [load, os.getloadavg()[0]]
    if args.json:
        print(json.dumps(out))
    else:
        for k, v in out.items():
            print(f"{k:32s} {v:.2f}" if isinstance(v, float) else f"{k:32s} {v}")  # dicts as they are


if __name__ == "__main__":
    main()
