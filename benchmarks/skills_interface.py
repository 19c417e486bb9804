"""Learned skills on the robot interface: insertion success and grinding force error in
the simulated cell, with the skill running over streamed joint positions (admittance, 8 ms period).

    python benchmarks/skills_interface.py --json [--trials 10] [--demos 4]

Insertion: the GMR skill learned from HDD demonstrations vs the compliant baseline without a skill
(``ConstantPush``: the same admittance, a constant axial speed), from the same random start errors
(lateral +-1.5 mm, tilt <= 3 deg; seed 7, never used while the runner was written). Grinding: the learned
force map as the set-point along the plate's diagonal; RMS(force - intended) / peak. ``per_cycle_us``:
robointel's own compute per period of the insertion runner (wrench, skill, admittance, gate) on a dry arm.
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np

from robointel.control.payload import PayloadCompensation
from robointel.interface.sim import SimRobot
from robointel.interface.wrench_source import StateWrench
from robointel.learning import grinding as gr
from robointel.learning import insertion as ins
from robointel.skills.cells import (
    R_DOWN,
    HoleTask,
    PegTool,
    PlateTask,
    ik_near,
    peg_hole_workcell,
    plate_workcell,
    stylus,
)
from robointel.skills.grinding import run_grinding
from robointel.skills.insertion import run_insertion


def insertion(trials: int, demos: int, clearance: float) -> dict:
    peg, hole = PegTool(), HoleTask(clearance=clearance)
    task = ins.PegHole()
    rng = np.random.default_rng(0)
    ds = ins.seated_demonstrations(task, rng, demos)
    skill = ins.InsertionSkill(4, centre=peg.centre).fit(ds)
    starts = np.random.default_rng(7)
    cases = [(starts.uniform(-1.5e-3, 1.5e-3, 2), (starts.uniform(0, 2 * np.pi), starts.uniform(0, np.radians(3))))
             for _ in range(trials)]
    out: dict = {}
    for name, policy in (("learned", skill.predict), ("constant_push", ins.ConstantPush(0.006))):
        wins, times, forces = 0, [], []
        for lat, tilt in cases:
            wc, robot = peg_hole_workcell(peg, hole)
            wc.reset(ik_near(robot, hole.start_tcp(peg, lateral=lat, tilt=tilt)))
            wc.hold(0.2)
            arm = SimRobot(wc)
            src = StateWrench(robot, PayloadCompensation(peg.mass, np.asarray(peg.payload().com)))
            res = run_insertion(arm, robot, policy, hole.advance(), source=src, time_limit=8.0)
            wins += res.success
            forces.append(res.outcome.figures["max_force_n"])
            if res.success:
                times.append(res.outcome.figures["time_s"])
        out[name] = {"success": wins, "trials": trials, "median_time_s": float(np.median(times)) if times else None,
                     "median_max_force_n": float(np.median(forces))}
    return out


def runner_cycle_us(n: int = 400) -> dict:
    """The insertion runner's compute per period without the physics: a dry arm that only accepts targets."""
    from robointel.interface.backend import Backend
    from robointel.interface.state import RobotMode, RobotState

    peg = PegTool()
    robot = peg.robot()
    q0 = ik_near(robot, HoleTask().start_tcp(peg))

    class Dry(Backend):
        def __init__(self):
            super().__init__(robot.joint_names, robot.lower, robot.upper, robot.velocity_limit, 0.008, paced=False,
                             stall_periods=None)
            self.q = q0.copy()

        def _send(self, q):
            self.q = q

        def _read(self):
            return RobotState(0.0, self.q, np.zeros(6), np.array([0.0, 0.0, -2.0, 0.0, 0.0, 0.0]),
                              RobotMode.STREAMING, q_cmd=self.q)

        def _hold(self):
            pass

        def _halt(self):
            pass

    task = ins.PegHole()
    skill = ins.InsertionSkill(4, centre=peg.centre).fit(ins.seated_demonstrations(task, np.random.default_rng(0), 1))
    arm = Dry()
    stamps = []
    t = [time.perf_counter()]

    def tick(k, st):
        now = time.perf_counter()
        stamps.append(now - t[0])
        t[0] = now

    run_insertion(arm, robot, skill.predict, 1.0, time_limit=n * 0.008, on_cycle=tick)
    us = np.array(stamps[1:]) * 1e6
    return {"median": float(np.median(us)), "p99": float(np.percentile(us, 99))}


def grinding(demos: int) -> dict:
    plate = gr.Plate()
    rng = np.random.default_rng(0)
    skill = gr.GrindingSkill(plate).fit([gr.demonstrate_grinding(plate, rng) for _ in range(demos)])
    tool = stylus()
    wc, robot = plate_workcell(PlateTask(plate.center, plate.top, plate.size), tool)
    c = np.array(plate.center)
    half = 0.5 * np.array(plate.size) - 0.02
    a, b = np.r_[c - half, plate.top + tool.radius + 5e-4], np.r_[c + half, plate.top + tool.radius]
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R_DOWN, a
    wc.reset(ik_near(robot, T))
    wc.hold(0.2)
    arm = SimRobot(wc)
    res = run_grinding(arm, robot, lambda p: float(skill.predict((p[:2] - c)[None])[0]), a, b,
                       source=StateWrench(robot, PayloadCompensation(tool.mass, np.asarray(tool.payload().com))))
    base = gr.reproduce_grinding(plate, skill)  # the 1 kHz joint-servo reproduction in the learning cell
    return {"rms_rel_intended": res.rms_rel(plate.force_profile(res.position[:, :2] - c)),
            "rms_rel_setpoint": res.rms_rel(), "ok": res.outcome.success,
            "peer_1khz_cell_rms_rel_intended": base.rms_rel}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--trials", type=int, default=10)
    ap.add_argument("--demos", type=int, default=4)
    ap.add_argument("--clearance", type=float, default=0.5e-3)
    args = ap.parse_args()
    out = {"insertion": insertion(args.trials, args.demos, args.clearance), "clearance_m": args.clearance,
           "insertion_runner_cycle_us": runner_cycle_us(), "grinding": grinding(max(2, args.demos // 2))}
    print(json.dumps(out) if args.json else json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
