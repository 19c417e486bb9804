"""Robot interface benchmark: streaming at the controller's period on the FANUC emulator and
in the simulated cell, with a planner running in another thread; e-stop reaction; FRMP tracking.

    python benchmarks/interface.py --json [--seconds 60]

A *missed cycle* on the FANUC is a controller window that got no fresh command from robointel: the
streaming process (``FanucRobot(stream_process=True)``) counts every window of a
stream as fresh (a target interpolated at the tick's time, submitted before the tick), starved (the
caller had not delivered a target for it: late by more than the look-ahead) or late (the streaming
process itself submitted after the tick). ``fanuc_missed_cycles`` = starved + late. Windows the
airo-fanuc core itself skipped (its real-time thread stalled by the machine) are reported apart
(``fanuc_core_skipped_windows``), and so are windows whose tick the core sent late while the
streaming process was awake polling for it (``fanuc_core_late_windows``: the tick was not there
after its due time, then came together with the next one). The same stream with the driver in the caller's process
(``stream_process=False``, a target per ``stream()`` call) is measured in the same run: there a
cycle is missed when ``stream()`` returned after the end of its period.

The ``sim`` backend is measured the same way: ``open_robot("sim", stream_process=True)``
(:class:`~robointel.interface.sim_stream.SimStreamRobot`: the workcell stepped at wall-clock ticks in a
process of its own, fed through the same look-ahead ring) counts each window fresh, starved or late in
its child, and ``sim_missed_cycles`` = starved + late. The paced sim stepped inside the caller's
``stream()`` (``SimRobot(paced=True)``) is measured after it, as
``sim_in_process_*``: there a cycle is missed when ``stream()`` returned after the end of its period.

The emulator (airo_fanuc.testing.FakeCRXController, strict conformance, 127.0.0.1) runs in a child
process (robointel.testing.emulator) so that its Python real-time loop does not share our
interpreter lock. Peer: the same
stream sent straight through ``FanucDriver.servo_j`` (no robointel gate, state read or recording),
measured in the same run.

The host during each stream (:class:`~robointel.testing.host_probe.HostProbe`):
``<run>_host`` holds the CPU count, the load average at the stream's start and end, the share of each
CPU taken by the hypervisor (``/proc/stat`` steal) over the stream and its worst 0.5 s, and what bare
SCHED_FIFO-55 sleepers, one pinned to each CPU, woken every 2 ms saw (lateness, stalls over 2 ms and when;
a pinned sleeper also stalls while a thread above 55 holds its CPU: the FANUC core and streaming process);
``<run>_late_us`` (median / max), ``<run>_late_at_s`` (s after the stream's start) and
``<run>_late_in_host_stall`` (late windows within 20 ms of a stall of the sleeper) describe the late
windows of the streaming process (``fanuc``, ``sim``) or the late cycles of the caller (``in_process``,
``peer``, ``sim_in_process``); ``<run>_child_scheduling`` the streaming process's threads by policy
(was SCHED_FIFO granted). A late window at an instant the sleeper also stalled is the host's, not ours.
"""
from __future__ import annotations

import argparse
import json
import math
import threading
import time

import numpy as np

from _planner_load import planner_thread
from robointel.testing.emulator import EmulatorProcess
from robointel.testing.host_probe import HostProbe

PERIOD = 0.008


def _wait_warm(counter, segments=5, timeout=120.0):
    """Wait until the planner thread has planned a few segments (imports and JIT compilation done)."""
    t = time.perf_counter()
    while counter[0] < segments and time.perf_counter() - t < timeout:
        time.sleep(0.05)


def _targets(q0, seconds):
    k = np.arange(int(round(seconds / PERIOD)))
    amp = np.radians([20, 10, 10, 30, 20, 45])
    return q0 + amp * np.sin(2 * np.pi * 0.25 * k[:, None] * PERIOD) * np.array([1, 1, -1, 1, 1, 1])


def _stream(send, targets, robot=None):
    """Send targets paced at the period.

    Returns (cycle compute us, missed cycles, late ms per cycle, stall stops, CLOCK_MONOTONIC s at which
    each cycle ended: its deadline). A stall stop (the
    watchdog stopped the robot because this thread got no CPU for N periods) is counted, recovered,
    and the rest of the path is shifted to start where the robot stopped.
    """
    from robointel.errors import ControllerFault
    from robointel.interface.realtime import sleep_until

    K = len(targets)
    cyc, late, missed, stalls, due = np.zeros(K), np.zeros(K), 0, [], np.zeros(K)
    offset = np.zeros(targets.shape[1])
    t0 = time.perf_counter() + 0.02
    for k in range(K):
        sleep_until(t0 + k * PERIOD)
        c0 = time.perf_counter()
        try:
            send(targets[k] + offset)
        except ControllerFault as exc:
            if robot is None:
                raise
            stalls.append(exc.reason)
            robot.recover()
            offset = robot.state().q_cmd - targets[k]
            c0 = time.perf_counter()  # the recovery is not robointel's per-command compute
            send(targets[k] + offset)
            t0 += c0 - (t0 + k * PERIOD)  # the schedule restarts after the recovery
        c1 = time.perf_counter()
        cyc[k] = (c1 - c0) * 1e6
        due[k] = t0 + (k + 1) * PERIOD
        late[k] = (c1 - due[k]) * 1e3
        if late[k] > 0:
            missed += 1
    return cyc, missed, late, stalls, due


def _late_figures(probe, origin, at, late_ms):
    """The late windows beside the host's figures: how late, when, and how many fell in a host stall.

    ``at``: CLOCK_MONOTONIC s of each late window; ``late_ms``: how late each was. Keys: ``host``
    (:meth:`HostProbe.summary`, times after ``origin``: the stream's start), ``late_us`` (median / max,
    per late window or event), ``late_at_s`` (the first 100, s after the start), ``late_in_host_stall``
    (how many of them fell within 20 ms of a stall of the host probe's bare sleeper).
    """
    at, late_ms = np.asarray(at, dtype=float), np.asarray(late_ms, dtype=float)
    return {"host": probe.summary(origin),
            "late_us": ({"median": float(np.median(late_ms)) * 1e3, "max": float(np.max(late_ms)) * 1e3}
                        if len(late_ms) else None),
            "late_at_s": [round(float(t - origin), 3) for t in at[:100]],
            "late_in_host_stall": probe.coincident(at.tolist())}


def _streaming_run(make_robot, seconds, planner=True):
    import os

    stop, counter = threading.Event(), [0]
    th = threading.Thread(target=planner_thread, args=(stop, counter), daemon=True)
    robot = make_robot()
    load0 = os.getloadavg()[0]
    try:
        if planner:
            th.start()
            _wait_warm(counter)
        targets = _targets(robot.state().q, seconds)
        with _fifo(), HostProbe() as probe:
            origin = time.monotonic()
            cyc, missed, late, stalls, due = _stream(robot.stream, targets, robot)
        robot.hold()
        if hasattr(getattr(robot, "driver", None), "held"):  # the sim stream: count its queued targets too
            deadline = time.monotonic() + 30.0
            while not robot.driver.held() and time.monotonic() < deadline:
                time.sleep(0.01)
        extra = robot.timing_stats() if hasattr(robot, "timing_stats") else {}
        if getattr(robot, "stream_process", False):  # the missed windows, for locating them
            keys = ("kind", "t_s", "tick", "gap_ms", "cpu_ms", "runq_ms", "runs", "wait_ms", "late_ms", "faults",
                    "preemptions")
            events = robot.driver.missed_events()
            extra["missed_events"] = [dict(zip(keys, (e[0], round(e[1], 4), *e[2:]), strict=True))
                                      for e in events]
            base = robot.driver.base_ns * 1e-9
            mine = [e for e in events if e[0] == "late"]  # the streaming process's own (not starved, core-late)
            extra["late"] = _late_figures(probe, origin, [base + e[1] for e in mine], [e[8] for e in mine])
            extra["child_scheduling"] = robot.driver.scheduling()
        if "slow_steps" in extra:  # the sim child's windows with a long physics step: [s after start, wall, CPU ms]
            slow = extra["slow_steps"]
            extra["slow_steps"] = {"count": len(slow), "in_host_stall": probe.coincident([x[0] for x in slow]),
                                   "first": [[round(x[0] - origin, 3), x[1], x[2]] for x in slow[:50]]}
    finally:
        stop.set()
        if planner:
            th.join()
        robot.close()
    return {"cycles": len(cyc), "missed_cycles": int(missed), "per_cycle_us": _stats(cyc),
            "planner_segments_meanwhile": counter[0], "core": extra, "max_late_ms": float(late.max()),
            "stall_stops": len(stalls), "late_over_100ms": int(np.sum(late > 100.0)),
            "caller_late": _late_figures(probe, origin, due[late > 0], late[late > 0]),
            "load_avg_1min": [load0, os.getloadavg()[0]]}


FIFO = [True]


def _fifo():
    """The streaming thread's real-time section (SCHED_FIFO 40 unless --no-fifo, gc.freeze, 0.5 ms switch)."""
    from robointel.interface.realtime import realtime_thread

    return realtime_thread(40, fifo=FIFO[0], switch_interval=SWITCH[0])


SWITCH = [0.0005]


def _flat(prefix, late):
    """``_late_figures``' keys as ``<prefix>_host``, ``<prefix>_late_us``, ``<prefix>_late_at_s``, ..."""
    return {f"{prefix}_{k}": v for k, v in late.items()}


def _stats(us):
    return {"median": float(np.median(us)), "p99": float(np.percentile(us, 99)), "max": float(np.max(us))}


def _peer_run(url_fake, seconds):
    """The same stream straight through FanucDriver.servo_j (the peer), same planner load."""
    from airo_fanuc import FanucDriver

    from robointel.interface.fanuc import FanucRobot

    stop, counter = threading.Event(), [0]
    th = threading.Thread(target=planner_thread, args=(stop, counter), daemon=True)
    robot = FanucRobot("127.0.0.1", rmi_port=url_fake.rmi_port, sm_port=url_fake.sm_port, stream_process=False)
    policy = robot.policy
    robot.close()
    drv = FanucDriver("127.0.0.1", policy)
    try:
        th.start()
        _wait_warm(counter)
        targets = _targets(drv.get_joint_configuration(), seconds)
        with _fifo(), HostProbe() as probe:
            origin = time.monotonic()
            cyc, missed, late, _, due = _stream(lambda q: drv.servo_j(q, PERIOD), targets)
    finally:
        stop.set()
        th.join()
        drv.close()
    return {"cycles": len(cyc), "missed_cycles": int(missed), "per_cycle_us": _stats(cyc),
            "max_late_ms": float(late.max()), "late": _late_figures(probe, origin, due[late > 0], late[late > 0])}


def _estop_run(fake):
    from robointel.errors import ControllerFault
    from robointel.interface import open_robot
    from robointel.interface.realtime import sleep_until

    robot = open_robot(fake.url, stream_process=True)
    try:
        targets = _targets(robot.state().q, 3.0)
        t0, t_press, err, submits0 = time.perf_counter(), None, None, 0
        for k in range(len(targets)):
            sleep_until(t0 + k * PERIOD)
            if k == 150:
                t_press = fake.timed("press_estop")[1]
                submits0 = _submits(robot)
            try:
                robot.stream(targets[k])
            except ControllerFault as exc:
                err = exc
                break
        time.sleep(0.2)
        after = [t for t in robot.sent_times if t > t_press]
        st = robot.state()
        if robot.stream_process:  # what reached the core: the streaming process's submissions
            last = robot.driver.last_submit_ns() * 1e-9
            out = {"estop_to_last_command_ms": max(0.0, last - t_press) * 1e3,
                   "commands_after_estop": _submits(robot) - submits0, "targets_accepted_after_estop": len(after)}
        else:
            out = {"estop_to_last_command_ms": (max(after) - t_press) * 1e3 if after else 0.0,
                   "commands_after_estop": len(after)}
        out.update({"raised": type(err).__name__ if err else None, "state_mode": st.mode.value,
                    "state_why": st.why_stopped})
    finally:
        robot.close()
    fake.call("release_estop")
    return out


def _submits(robot):
    """Targets the streaming process has submitted to the core so far."""
    return int(robot.driver.read_state()["submits"])


def _frmp_run():
    from robointel.interface import open_robot
    from robointel.planning import plan_scene
    from robointel.planning.scene import load_scene

    res = plan_scene(load_scene("table71"))
    tr = res.trajectory
    fake = EmulatorProcess(tr.q[0])
    try:
        with open_robot(fake.url, stream_process=True) as robot:
            ex = robot.execute(tr)
            time.sleep(1.0)
            final = robot.state().q
    finally:
        violations = fake.close()
    a = 1 - math.exp(-PERIOD / 0.125)  # the emulator's first-order plant lag (MEASURED_FACTS.tracking_lag_s)
    x, model = tr.q[0].copy(), np.empty_like(ex.q_cmd)
    for k, u in enumerate(ex.q_cmd):
        x = x + (u - x) * a
        model[k] = x
    with open_robot("sim", q0=tr.q[0]) as sim:
        sx = sim.execute(tr)
    return {"frmp_tracking_rms_rad": ex.tracking_rms_rad,
            "frmp_lag_model_rms_rad": float(np.sqrt(np.mean((ex.q - model) ** 2))),
            "frmp_final_error_rad": float(np.max(np.abs(final - tr.q[-1]))),
            "frmp_completed": ex.completed, "frmp_duration_s": tr.duration, "frmp_cycles": len(ex.q_cmd),
            "frmp_monitor_per_cycle_us": _stats(ex.cycle_us),
            "sim_frmp_tracking_rms_rad": sx.tracking_rms_rad}, violations


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--switch-interval", type=float, default=0.0005,
                    help="sys.setswitchinterval for this process (the interpreter lock hand-over), s")
    ap.add_argument("--fifo", action=argparse.BooleanOptionalAction, default=True,
                    help="stream from a SCHED_FIFO thread (needs CAP_SYS_NICE; else normal priority)")
    ap.add_argument("--lookahead", type=float, default=0.1,
                    help="look-ahead of the FANUC and sim streaming processes, s (lookahead_s=...)")
    ap.add_argument("--sim-lock-memory", action="store_true",
                    help="the sim's streaming process locks its memory (mlockall; lock_memory=True)")
    ap.add_argument("--in-process", action=argparse.BooleanOptionalAction, default=True,
                    help="also stream with the driver in this process (stream_process=False)")
    args = ap.parse_args()
    FIFO[0], SWITCH[0] = args.fifo, args.switch_interval
    import os

    from robointel.interface import open_robot
    from robointel.interface.sim import SimRobot

    out: dict = {"seconds": args.seconds, "lookahead_s": args.lookahead, "streaming_thread_fifo": args.fifo,
                 "period_ms": PERIOD * 1e3,
                 "switch_interval_s": args.switch_interval,
                 "process_policy": {os.SCHED_OTHER: "SCHED_OTHER", os.SCHED_RR: "SCHED_RR",
                                    os.SCHED_FIFO: "SCHED_FIFO"}.get(os.sched_getscheduler(0), "other"),
                 "process_nice": os.nice(0), "load_avg_1min_at_start": os.getloadavg()[0]}
    fake = EmulatorProcess(record_arrivals=True)  # each flagged command with the arrivals around it
    try:
        fan = _streaming_run(lambda: open_robot(fake.url, stream_process=True, lookahead_s=args.lookahead),
                             args.seconds)
        n_proc = len(fake.call("violations"))
        inproc = (_streaming_run(lambda: open_robot(fake.url, stream_process=False), args.seconds)
                  if args.in_process else None)
        n_fan = len(fake.call("violations"))
        peer = _peer_run(fake, args.seconds)
        n_peer = len(fake.call("violations")) - n_fan
        est = _estop_run(fake)
        n_est = len(fake.call("violations"))
        arrivals = fake.call("arrival_context")
    finally:
        violations = fake.close()
    peer_violations = violations[n_fan:n_fan + n_peer]  # the bare driver's session (its close included)
    by_session = {"streaming": n_proc, "in_process": n_fan - n_proc, "peer": n_peer,
                  "estop": n_est - n_fan - n_peer, "close_of_emulator": len(violations) - n_est}
    inproc_violations = violations[n_proc:n_fan]  # the in-process session's
    violations = violations[:n_proc] + violations[n_fan + n_peer:]
    core = fan["core"]
    frmp, v2 = _frmp_run()
    sim = _streaming_run(lambda: open_robot("sim", stream_process=True, stall_periods=10, lookahead_s=args.lookahead,
                                            lock_memory=args.sim_lock_memory), args.seconds)
    score = sim["core"]
    sim_in = _streaming_run(lambda: SimRobot(paced=True, stall_periods=10), args.seconds)
    out.update({  # the host during each stream, and when and how late the late windows were
        "host_cpus": os.cpu_count(),
        **_flat("fanuc", core["late"]), "fanuc_child_scheduling": core["child_scheduling"],
        **_flat("sim", score["late"]), "sim_child_scheduling": score["child_scheduling"],
        "sim_slow_steps": score.get("slow_steps"), "sim_wake_after_tick_ms": score.get("wake_after_tick_ms"),
        "sim_memory_locked": score.get("memory_locked"),
        **(_flat("in_process", inproc["caller_late"]) if inproc else {}),
        **_flat("peer", peer["late"]), **_flat("sim_in_process", sim_in["caller_late"]),
    })
    out.update({
        "fanuc_cycles": fan["cycles"],
        "fanuc_missed_cycles": int(core["stream_starved"] + core["stream_late"]),
        "fanuc_windows": core["stream_windows"], "fanuc_fresh_windows": core["stream_fresh"],
        "fanuc_starved_windows": core["stream_starved"], "fanuc_late_windows": core["stream_late"],
        "fanuc_core_late_windows": core["stream_core_late"], "fanuc_missed_events": core["missed_events"],
        "fanuc_child_gc_max_ms": core.get("gc_max_ms"),
        "fanuc_core_skipped_windows": core.get("skipped_tick_windows"),
        "fanuc_lookahead_ms": core["lookahead_s"] * 1e3,
        "fanuc_caller_late_cycles": fan["missed_cycles"], "fanuc_caller_late_over_100ms": fan["late_over_100ms"],
        "fanuc_load_avg_1min": fan["load_avg_1min"],
        "in_process_missed_cycles": inproc["missed_cycles"] if inproc else None,
        "in_process_per_cycle_us": inproc["per_cycle_us"] if inproc else None,
        "in_process_conformance_violations": len(inproc_violations),
        "in_process_max_late_ms": inproc["max_late_ms"] if inproc else None,
        "in_process_stall_stops": inproc["stall_stops"] if inproc else None,
        "in_process_load_avg_1min": inproc["load_avg_1min"] if inproc else None,
        "conformance_violations": len(violations) + len(v2), "peer_conformance_violations": len(peer_violations),
        "estop_to_last_command_ms": est["estop_to_last_command_ms"],
        "per_cycle_us": fan["per_cycle_us"],
        "peer_servo_j_per_cycle_us": peer["per_cycle_us"], "peer_missed_cycles": peer["missed_cycles"],
        "per_cycle_ratio_median": fan["per_cycle_us"]["median"] / peer["per_cycle_us"]["median"],
        **frmp,
        "fanuc_stall_stops": fan["stall_stops"], "fanuc_max_late_ms": fan["max_late_ms"],
        "peer_max_late_ms": peer["max_late_ms"],
        "sim_cycles": sim["cycles"], "sim_missed_cycles": int(score["stream_starved"] + score["stream_late"]),
        "sim_windows": score["stream_windows"], "sim_fresh_windows": score["stream_fresh"],
        "sim_starved_windows": score["stream_starved"], "sim_late_windows": score["stream_late"],
        "sim_missed_events": score["missed_events"], "sim_lookahead_ms": score["lookahead_s"] * 1e3,
        "sim_step_max_ms": score["step_max_ms"], "sim_catch_up_max_windows": score["catch_up_max_windows"],
        "sim_child_gc_max_ms": score["gc_max_ms"], "sim_caller_late_cycles": sim["missed_cycles"],
        "sim_per_cycle_us": sim["per_cycle_us"], "sim_load_avg_1min": sim["load_avg_1min"],
        "sim_stall_stops": sim["stall_stops"], "sim_max_late_ms": sim["max_late_ms"],
        "sim_in_process_cycles": sim_in["cycles"], "sim_in_process_missed_cycles": sim_in["missed_cycles"],
        "sim_in_process_per_cycle_us": sim_in["per_cycle_us"], "sim_in_process_stall_stops": sim_in["stall_stops"],
        "sim_in_process_max_late_ms": sim_in["max_late_ms"], "sim_in_process_load_avg_1min": sim_in["load_avg_1min"],
        "planner_segments_during_sim_in_process_stream": sim_in["planner_segments_meanwhile"],
        "estop": est, "planner_segments_during_fanuc_stream": fan["planner_segments_meanwhile"],
        "planner_segments_during_sim_stream": sim["planner_segments_meanwhile"],
        "fanuc_core_timing": {k: fan["core"].get(k) for k in ("tx_count", "tick_count", "skipped_tick_windows",
                                                               "missed_rx_ticks", "tx_interval_p99_ms",
                                                               "tx_interval_max_ms", "double_send_guard",
                                                               "stream_submits")},
        "violations": violations + v2, "peer_violations": peer_violations,
        "in_process_violations": inproc_violations,
        "violations_by_session": {**by_session, "frmp": len(v2)},
        "violation_arrivals": arrivals,
    })
    print(json.dumps(out, indent=None if args.json else 1))


if __name__ == "__main__":
    main()
