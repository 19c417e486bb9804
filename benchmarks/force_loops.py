"""Force loops on the FANUC backend with and without the streaming process.

    python benchmarks/force_loops.py --json [--modes in_process,direct,queued] [--repeats 1]

Three ways the same loop reaches the controller emulator (``airo_fanuc.testing.FakeCRXController``,
strict conformance, 127.0.0.1, in its own process; its plant is a first-order lag of 125 ms):

- ``in_process``: ``FanucRobot(stream_process=False)``, the driver in the loop's process, each target
  submitted by the loop's thread;
- ``direct``: ``FanucRobot(stream_process=True)``; the loops ask ``arm.low_latency()``, so the
  streaming process submits each target as soon as it arrives (look-ahead 0);
- ``queued``: the streaming process with its 100 ms look-ahead queue kept in the loop
  (``force_lookahead_s=0.1``): what the force loops would see without the per-use look-ahead.

Scenarios (one emulator session each):

- ``lead_through_step``: lead-through (:func:`robointel.teach.lead_through.lead_through`) with a
  simulated Net F/T box (its own process, RDT over UDP at 500 Hz) that pushes 20 N along world +y / -y
  for 0.4 s after 0.6 s of rest, ``--steps`` times. Per push: the time from the box's step to the first
  moved target the loop streamed (``loop_ms``) and to the first controller tick whose command (the
  core's ``q_cmd``) moved (``core_ms``).
- ``lead_through_wall``: the hand (the box) pushes 20 N down onto a virtual wall 10 mm under the TCP;
  the F/T reading is the hand plus the wall's reaction computed from the measured joints (stiffness
  ``--wall-stiffness``, 30 N s/m), with a contact admittance ``--contact-kd`` (0.005 m/(N s): 20 N
  moves the tool at 0.1 m/s in free space). Peak wall force, the last second's mean and standard deviation, and
  contact losses (the wall force falling to 0 after the first contact).
- ``insertion_wall``: the learned insertion skill (GMR on four seated HDD demonstrations) against a
  virtual wall 5 mm below the peg (1500 N/m), 2.5 s: the same figures on the axial push.
"""
from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import socket
import struct
import time
from types import SimpleNamespace
from typing import Any

import numpy as np

from robointel.control.admittance import AdmittanceGains
from robointel.interface import open_robot
from robointel.interface.ft_sensor import RDT_RECORD, NetFTSensor
from robointel.interface.wrench_source import VirtualWall
from robointel.robot import Robot
from robointel.teach.guidance import GuidanceConfig
from robointel.teach.lead_through import lead_through
from robointel.testing.emulator import EmulatorProcess

PERIOD = 0.008
CPF = 1e6
Q0 = np.array([0.0, 0.2, -0.3, 0.0, -0.8, 0.0])
MODES = ("in_process", "direct", "queued")


class Box:
    """A Net F/T box in a forked process: after the RDT start it sends ``force`` (world, rotated into the
    sensor frame at ``R0``) while ``on`` is set, else zeros, every 2 ms."""

    def __init__(self, R0: np.ndarray) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.002)
        self.port = self.sock.getsockname()[1]
        ctx = mp.get_context("fork")
        self.force = ctx.Array("d", 3)
        self.t_on = ctx.Value("d", np.inf)  # perf_counter of the step (shared clock: CLOCK_MONOTONIC)
        self.t_off = ctx.Value("d", np.inf)
        self._stop = ctx.Event()
        self._R0 = R0
        self._proc = ctx.Process(target=self._run, daemon=True)
        self._proc.start()

    def _run(self) -> None:
        peer, seq = None, 0
        while not self._stop.is_set():
            try:
                data, addr = self.sock.recvfrom(64)
                header, cmd, _ = struct.unpack(">HHI", data[:8])
                if header == 0x1234:
                    peer = addr if cmd == 2 else None
            except (TimeoutError, OSError):
                pass
            if peer is not None:
                now = time.perf_counter()
                f = np.array(self.force[:]) if self.t_on.value <= now < self.t_off.value else np.zeros(3)
                counts = np.round(np.concatenate([self._R0.T @ f, np.zeros(3)]) * CPF).astype(int)
                seq += 1
                self.sock.sendto(RDT_RECORD.pack(seq, seq, 0, *counts.tolist()), peer)

    def push(self, force: np.ndarray, t_on: float, t_off: float) -> None:
        """Push ``force`` (3,) N, world, from ``t_on`` to ``t_off`` (perf_counter s)."""
        self.force[:] = list(force)
        self.t_on.value, self.t_off.value = t_on, t_off

    def close(self) -> None:
        self._stop.set()
        self._proc.join(5)
        if self._proc.is_alive():
            self._proc.kill()
        self.sock.close()


class HandAndWall:
    """The wrist sensor's reading: the hand (the Net F/T box) plus a virtual wall's reaction at the
    measured joints of ``arm`` (its latest controller status), in the sensor frame."""

    def __init__(self, port: int, wall: VirtualWall) -> None:
        self.hand = NetFTSensor("127.0.0.1", port)
        self.wall = wall
        self.arm: Any = None
        self.last_wall_n = 0.0

    def read(self) -> np.ndarray | None:
        h = self.hand.read()
        if h is None or self.arm is None or not self.arm._snap:
            return h
        s = self.arm._snap
        st = SimpleNamespace(q=np.array(s["q_meas"], float), qd=np.array(s["qd_est"], float))
        self.last_wall_n = float(self.wall.world_force(st.q, st.qd) @ self.wall.normal)
        return h + self.wall.wrench(st)  # type: ignore[arg-type]

    def close(self) -> None:
        self.hand.close()


def _open(fake: EmulatorProcess, mode: str, **kw: Any) -> Any:
    force = 0.1 if mode == "queued" else 0.0  # queued: the 100 ms look-ahead inside the force loop too
    return open_robot(fake.url, stream_process=mode != "in_process", stall_periods=50, force_lookahead_s=force, **kw)


def _direct_stats(arm: Any) -> dict:
    st = arm.timing_stats()
    keys = ("stream_windows", "stream_fresh", "stream_starved", "stream_late", "stream_core_late",
            "direct_submits", "direct_latency_mean_ms", "direct_latency_max_ms", "skipped_tick_windows")
    return {k: st[k] for k in keys if k in st}


def lead_through_step(mode: str, steps: int) -> dict:
    robot = Robot.load("lrmate200id7l")
    R0 = robot.frame_pose(Q0, robot.flange_frame)[:3, :3]
    box = Box(R0)
    fake = EmulatorProcess(Q0)
    rows: list[tuple[float, float, np.ndarray]] = []  # (wall time after the target, tick s, core q_cmd)
    onsets: list[float] = []
    try:
        with _open(fake, mode, ft_sensor=f"netft://127.0.0.1:{box.port}") as arm:
            t_start = time.perf_counter() + 0.6
            for i in range(steps):
                onsets.append(t_start + i * 1.0)
            armed = [False] * steps

            def on_cycle(k: int, step: Any) -> None:
                now = time.perf_counter()
                for i, t in enumerate(onsets):
                    if not armed[i] and now >= t - 0.3:  # arm each push 0.3 s before it (the last one is over)
                        armed[i] = True
                        box.push(np.array([0.0, 20.0 if i % 2 == 0 else -20.0, 0.0]), t, t + 0.4)
                s = arm._snap  # the snapshot this cycle's state came from: the core's command and its tick
                rows.append((now, int(s["tick_mono_ns"]) * 1e-9, np.array(s["q_cmd"], float)))

            res = lead_through(arm, robot, 0.6 + steps * 1.0 + 0.2, on_cycle=on_cycle)
            stats = _direct_stats(arm) if mode != "in_process" else {}
    finally:
        violations = fake.close()
        box.close()
    # the loop's targets, cycle by cycle (rows carry the core's command seen at each cycle)
    wall = np.array([r[0] for r in rows])
    ticks = np.array([r[1] for r in rows])
    qc = np.array([r[2] for r in rows])
    tgt = res.q_cmd[:len(rows)]
    loop_ms, core_ms = [], []
    for t in onsets:
        k0 = int(np.searchsorted(wall, t))
        if k0 < 2 or k0 >= len(wall):
            continue
        moved = np.flatnonzero(np.max(np.abs(np.diff(tgt[k0 - 1:], axis=0)), axis=1) > 1e-7)
        if len(moved):
            loop_ms.append((wall[k0 + moved[0]] - t) * 1e3)
        base = qc[k0 - 1]
        cm = np.flatnonzero(np.max(np.abs(qc[k0:] - base), axis=1) > 1e-7)
        if len(cm):
            core_ms.append((ticks[k0 + cm[0]] - t) * 1e3)
    return {"loop_ms": _s(loop_ms), "core_ms": _s(core_ms), "pushes": len(onsets), "held_cycles": int(res.held.sum()),
            "cycles": len(res.t), "violations": len(violations), "stream": stats}


def lead_through_wall(mode: str, stiffness: float, kd: float, seconds: float = 3.0) -> dict:
    robot = Robot.load("lrmate200id7l")
    R0 = robot.frame_pose(Q0, robot.flange_frame)[:3, :3]
    box = Box(R0)
    p0 = robot.fk(Q0)[:3, 3]
    wall = VirtualWall(robot, p0 - [0.0, 0.0, 0.01], (0.0, 0.0, 1.0), stiffness=stiffness, damping=30.0)
    sensor = HandAndWall(box.port, wall)
    fake = EmulatorProcess(Q0)
    fn: list[float] = []
    try:
        with _open(fake, mode, ft_sensor=sensor) as arm:  # type: ignore[arg-type]
            sensor.arm = arm
            t = time.perf_counter() + 0.3
            box.push(np.array([0.0, 0.0, -20.0]), t, t + 100.0)
            cfg = GuidanceConfig(gains=AdmittanceGains(kd, 10 * kd, 1.0, 0.1))
            res = lead_through(arm, robot, seconds, config=cfg, on_cycle=lambda k, s: fn.append(sensor.last_wall_n))
            stats = _direct_stats(arm) if mode != "in_process" else {}
    finally:
        violations = fake.close()
        sensor.close()
        box.close()
    out = _contact(np.array(fn), PERIOD)
    out.update({"held_cycles": int(res.held.sum()), "violations": len(violations), "stream": stats,
                "stiffness_n_per_m": stiffness, "kd_m_per_n_s": kd})
    return out


def insertion_wall(mode: str, skill: Any) -> dict:
    from robointel.skills.cells import HoleTask, PegTool, ik_near
    from robointel.skills.insertion import run_insertion

    peg, hole = PegTool(), HoleTask()
    robot = peg.robot()
    q0 = ik_near(robot, hole.start_tcp(peg))
    p = robot.fk(q0)[:3, 3] - [0.0, 0.0, 0.005]
    wall = VirtualWall(robot, p, (0.0, 0.0, 1.0), stiffness=1500.0, damping=30.0, noise=0.05)
    fake = EmulatorProcess(q0)
    try:
        with _open(fake, mode) as arm:
            res = run_insertion(arm, robot, skill.predict, 0.02, source=wall, time_limit=2.5)
            stats = _direct_stats(arm) if mode != "in_process" else {}
    finally:
        violations = fake.close()
    push = -res.wrench[:, 2]
    out = _contact(push, PERIOD, floor=0.3)
    out.update({"advance_max_mm": float(res.advance.max() * 1e3), "outcome": res.outcome.reason.value
                if res.outcome.reason is not None else "success", "violations": len(violations), "stream": stats})
    return out


def _contact(f: np.ndarray, dt: float, floor: float = 0.0) -> dict:
    """Peak, last-second mean/std and contact losses of a contact force series (N) sampled every dt s."""
    last = f[-int(round(1.0 / dt)):]
    on = f > floor
    first = int(np.argmax(on)) if on.any() else len(f)
    losses = int(np.sum(on[first:-1] & ~on[first + 1:]))
    return {"peak_n": float(f.max()), "last_s_mean_n": float(last.mean()), "last_s_std_n": float(last.std()),
            "contact_losses": losses, "first_contact_s": first * dt}


def _s(x: list[float]) -> dict:
    a = np.asarray(x, float)
    if a.size == 0:
        return {"n": 0}
    return {"n": int(a.size), "mean": float(a.mean()), "median": float(np.median(a)), "max": float(a.max()),
            "min": float(a.min())}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--modes", default=",".join(MODES))
    ap.add_argument("--scenarios", default="lead_through_step,lead_through_wall,insertion_wall")
    ap.add_argument("--steps", type=int, default=6, help="pushes in lead_through_step")
    ap.add_argument("--wall-stiffness", type=float, default=1500.0, help="lead_through_wall's wall, N/m")
    ap.add_argument("--contact-kd", type=float, default=0.005,
                    help="lead_through_wall's admittance K_d, m/(N s) (the guidance default 0.07 is for free space)")
    args = ap.parse_args()
    import os

    modes = [m for m in args.modes.split(",") if m]
    scen = [s for s in args.scenarios.split(",") if s]
    out: dict = {"load_avg_1min_at_start": os.getloadavg()[0], "modes": modes}
    skill = None
    if "insertion_wall" in scen:
        from robointel.learning import insertion as ins
        from robointel.skills.cells import PegTool

        task = ins.PegHole()
        demos = ins.seated_demonstrations(task, np.random.default_rng(0), 4, scene=ins.HDDScene(task))
        skill = ins.InsertionSkill(4, centre=PegTool().centre).fit(demos)
    for m in modes:
        r: dict = {}
        if "lead_through_step" in scen:
            r["lead_through_step"] = lead_through_step(m, args.steps)
        if "lead_through_wall" in scen:
            r["lead_through_wall"] = lead_through_wall(m, args.wall_stiffness, args.contact_kd)
        if "insertion_wall" in scen:
            r["insertion_wall"] = insertion_wall(m, skill)
        out[m] = r
    out["load_avg_1min_at_end"] = os.getloadavg()[0]
    print(json.dumps(out, indent=None if args.json else 1))


if __name__ == "__main__":
    main()
