"""Robot-core speed: FK + Jacobians of all collision spheres, closed-form and numeric IK.

Prints medians (µs) of ours beside a plain per-point Pinocchio loop (the way one would write it
with Pinocchio's Python API alone) and MuJoCo's mj_kinematics + mj_jac on the same robot, in one run.

    python benchmarks/robot_core.py [--json]
"""
from __future__ import annotations

import argparse
import json

import numpy as np
import pinocchio as pin

from _timing import median_us


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()

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

    ur5 = Robot.load("ur5")
    Tu = [ur5.fk(q) for q in ur5.random_configuration(1, 8)]

    def ours_ik_numeric():
        ur5.ik_numeric(Tu[next(it) % 8], q0=None)

    out = {
        "n_spheres": len(sp),
        "fk_jacobians_all_spheres_us": median_us(ours_spheres),
        "pinocchio_per_frame_loop_us": median_us(pin_loop, 400),
        "mujoco_mj_jac_loop_us": median_us(mujoco_loop, 400),
        "ik_closed_form_us": median_us(ours_ik),
        "fk_us": median_us(lambda: robot.fk(Q[next(it) % 64])),
        "mass_matrix_us": median_us(lambda: robot.mass_matrix(Q[next(it) % 64])),
        "ik_numeric_ur5_ms": median_us(ours_ik_numeric, 20, 1) / 1e3,
        "targets": {"fk_jacobians_all_spheres_us": 20, "ik_closed_form_us": 50},
    }
    out["speedup_vs_pinocchio_loop"] = out["pinocchio_per_frame_loop_us"] / out["fk_jacobians_all_spheres_us"]
    out["speedup_vs_mujoco_loop"] = out["mujoco_mj_jac_loop_us"] / out["fk_jacobians_all_spheres_us"]
    if args.json:
        print(json.dumps(out))
    else:
        for k, v in out.items():
            print(f"{k:32s} {v:.2f}" if isinstance(v, float) else f"{k:32s} {v}")


if __name__ == "__main__":
    main()
