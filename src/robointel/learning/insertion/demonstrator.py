"""The scripted person demonstrating the insertion with the hand-held device (Sec. 5.5).

A scripted person holding the hand-held demonstration device (a free body with the F/T sensor and the
peg, :class:`~robointel.learning.insertion.hdd_scene.HDDScene`) performs approach, rotation, insertion
and completion with human-like variation (speed changes, tremor, different approach tilts, occasional
hesitation), reacting to the felt wrench during insertion; recorded at 100 Hz with ground-truth phase
labels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robointel.errors import InvalidInput
from robointel.geometry.rotations import rotation_about, so3_exp, so3_log
from robointel.learning.demonstration import Demonstration
from robointel.learning.insertion.hdd_scene import HDDScene
from robointel.learning.insertion.peg_hole import R_DOWN, PegHole, tip_point

PHASES = ("approach", "rotation", "insertion", "completion")

@dataclass(frozen=True)
class Demonstrator:
    """A scripted person: hand impedance, corrective reflexes and their variation between demonstrations."""

    stiffness: float = 800.0      # N/m
    damping: float = 60.0         # N s/m
    rot_stiffness: float = 6.0    # N m/rad (firm grip: approach, rotation)
    grip_rot_stiffness: float = 0.4  # N m/rad (loose grip while inserting)
    grip_lateral_stiffness: float = 100.0  # N/m across the tool axis while inserting
    rot_damping: float = 0.2      # N m s/rad
    record_dt: float = 0.01       # s (100 Hz)
    force_noise: float = 0.05     # N, sensor noise std
    torque_noise: float = 0.002   # N m
    hesitation_prob: float = 0.35
    insertion_timeout: float = 10.0
    max_tilt_deg: float = 5.0     # residual tilt at the entry, uniform in [0, max] (deg)
    max_lateral: float = 2e-3     # lateral entry error, uniform in +/- per axis (m)
    stall_time: float = 0.3       # s without progress under a firm push: wedged
    stall_progress: float = 1e-4  # m of depth gained within stall_time that counts as progress
    recovery_time: float = 0.6    # s of one recovery (back off, tilt back, wiggle)


def min_jerk(s: float) -> float:
    """Progress (0..1) of a minimum-jerk motion at normalised time ``s`` (0..1)."""
    s = float(np.clip(s, 0.0, 1.0))
    return s ** 3 * (10 - 15 * s + 6 * s * s)


def trapezoid(s: float, ramp: float = 0.1) -> float:
    """Progress (0..1) of a trapezoidal velocity profile at normalised time ``s`` (0..1).

    The acceleration ramps take ``ramp`` of the duration: a deliberate hand motion that starts and stops
    within ~0.1-0.2 s.
    """
    s = float(np.clip(s, 0.0, 1.0))
    vmax = 1.0 / (1.0 - ramp)
    if s < ramp:
        return 0.5 * vmax * s * s / ramp
    if s > 1 - ramp:
        return 1.0 - 0.5 * vmax * (1 - s) ** 2 / ramp
    return 0.5 * vmax * ramp + vmax * (s - ramp)


def demonstrate(task: PegHole, rng: np.random.Generator, *, scene: HDDScene | None = None,
                person: Demonstrator = Demonstrator(), name: str = "") -> Demonstration:
    """One human-like demonstration with the HDD: approach, rotation, insertion, completion.

    Returns a :class:`Demonstration` at 100 Hz with ground-truth ``labels`` (indices into
    :data:`PHASES`) and ``meta`` (phase times, start errors, whether the peg was seated).
    """
    scene = scene or HDDScene(task)
    tool = scene.tool
    dt = float(scene.model.opt.timestep)
    top = np.array(task.top)
    # --- randomised script
    tilt0 = np.radians(rng.uniform(6, 14))
    ax0 = rng.normal(size=2)
    ax0 = np.array([*ax0 / np.linalg.norm(ax0), 0.0])
    R_start = rotation_about(ax0, tilt0) @ R_DOWN
    tilt_r = np.radians(rng.uniform(0.0, person.max_tilt_deg))
    axr = rng.normal(size=2)
    axr = np.array([*axr / np.linalg.norm(axr), 0.0])
    R_rot = rotation_about(axr, tilt_r) @ R_DOWN
    lat_err = rng.uniform(-person.max_lateral, person.max_lateral, 2)
    entry_tip = top + np.array([lat_err[0], lat_err[1], rng.uniform(0.002, 0.004)])
    start_tip = top + np.array([*rng.uniform(0.04, 0.08, 2) * rng.choice([-1, 1], 2), rng.uniform(0.05, 0.09)])
    T_a, T_r, T_c = rng.uniform(1.3, 2.0), rng.uniform(0.6, 1.0), rng.uniform(0.5, 0.8)
    gamma = rng.uniform(0.8, 1.25)  # speed profile
    pause = (rng.uniform(0.3, 0.7), rng.uniform(0.15, 0.4)) if rng.random() < person.hesitation_prob else None
    # reflex gains: lateral m/s per N; rotational rad/s per N m about the handle. (With 3-5 rad/s/(N m)
    # the handle rotation swings the tip into the wall and feeds the lateral force back as torque:
    # 40/60 demonstrations seated once _exp rotated by the right angle.)
    k_f, k_t = rng.uniform(0.8e-3, 1.4e-3), rng.uniform(0.3, 0.5)
    v_ins, f_lim, tau_lim = rng.uniform(0.006, 0.010), rng.uniform(6.0, 10.0), rng.uniform(0.3, 0.5)
    f_press = rng.uniform(8.0, 15.0)
    tremor_f = rng.uniform(8, 12, 3)
    tremor_a = rng.uniform(0.5e-4, 1.5e-4, 3)
    tremor_ph = rng.uniform(0, 2 * np.pi, (3, 3))

    def tip_to_origin(tip, R):
        return tip - R[:, 2] * tool.tip

    T0 = np.eye(4)
    T0[:3, :3] = R_start
    T0[:3, 3] = tip_to_origin(start_tip, R_start)
    scene.reset(T0)
    mg = np.array([0, 0, scene.mass * 9.81])

    ts, poses, wrenches, labels = [], [], [], []
    rec_every = max(1, int(round(person.record_dt / dt)))
    step = 0
    t = 0.0
    phase_t = [0.0]
    max_pen = 0.0

    k_rot = person.rot_stiffness
    k_lat = None

    def hand(p_ref, R_ref):
        nonlocal step, t, max_pen
        T = scene.pose()
        v, w = scene.twist()
        trem = tremor_a @ np.sin(2 * np.pi * tremor_f[:, None] * t + tremor_ph)
        e = p_ref + trem - T[:3, 3]
        if k_lat is not None:  # loose grip across the tool axis
            z = T[:3, 2]
            e = (e @ z) * z + (k_lat / person.stiffness) * (e - (e @ z) * z)
        f = person.stiffness * e - person.damping * v + mg
        tq = k_rot * so3_log(R_ref @ T[:3, :3].T) - person.rot_damping * w
        scene.step(f, tq)
        step += 1
        t = step * dt
        max_pen = max(max_pen, scene.wall_penetration())

    def record(label):
        if step % rec_every == 0:
            ts.append(t)
            poses.append(scene.pose())
            w = scene.wrench()
            w[:3] += person.force_noise * rng.standard_normal(3)
            w[3:] += person.torque_noise * rng.standard_normal(3)
            wrenches.append(w)
            labels.append(label)

    # approach: min-jerk with a speed profile and an optional pause
    n_a = int(T_a / dt)
    n_pause = int(pause[1] / dt) if pause else 0
    k = 0
    paused = 0
    while k < n_a or paused < n_pause:
        if pause and k >= int(pause[0] * n_a) and paused < n_pause:
            paused += 1
        else:
            k += 1
        s = trapezoid((k / n_a) ** gamma)
        tip = start_tip + s * (entry_tip - start_tip)
        R = R_start  # orientation kept while approaching
        hand(tip_to_origin(tip, R), R)
        record(0)
    phase_t.append(t)
    # rotation about the tip: from the approach tilt to a small residual tilt
    rv = so3_log(R_rot @ R_start.T)
    n_r = int(T_r / dt)
    for k in range(1, n_r + 1):
        R = so3_exp(rv * trapezoid(k / n_r, 0.15)) @ R_start
        hand(tip_to_origin(entry_tip, R), R)
        record(1)
    phase_t.append(t)
    # insertion: push along the tool axis, comply with the felt wrench (the skill to learn)
    R_ref = R_rot.copy()
    p_ref = tip_to_origin(entry_tip, R_ref)
    t_ins = t
    k_rot = person.grip_rot_stiffness
    k_lat = person.grip_lateral_stiffness
    depth_hist: list[tuple[float, float]] = []
    recover_until, recoveries = -1.0, 0
    tilt_back = np.zeros(3)
    wiggle_f, wiggle_a = rng.uniform(2.5, 4.0), np.radians(rng.uniform(0.2, 0.5))
    back_speed = rng.uniform(0.002, 0.004)
    tilt_rate = rng.uniform(0.04, 0.08)  # rad/s while tilting back
    while True:
        w = scene.wrench()
        f_push = max(0.0, -w[2])
        depth = float(top[2] - tip_point(scene.pose(), tool)[2])
        depth_hist.append((t, depth))
        while depth_hist and depth_hist[0][0] < t - person.stall_time:
            depth_hist.pop(0)
        stalled = (t - t_ins > person.stall_time and f_push > 0.5 * f_lim
                   and depth - depth_hist[0][1] < person.stall_progress)
        if t >= recover_until and stalled:
            # wedged: the person backs off a little, tilts the peg back the way the torque asks, and wiggles
            recover_until, recoveries = t + person.recovery_time, recoveries + 1
            c = tool.tip - tool.radius  # the torque about the tip sphere's centre says which way the peg leans
            tau = np.array([w[3] + c * w[1], w[4] - c * w[0], 0.0])
            tilt_back = tilt_rate * tau / max(float(np.linalg.norm(tau)), 1e-9)
        if t < recover_until:
            ph = 2 * np.pi * wiggle_f * (recover_until - t)
            v_tool = np.array([k_f * w[0], k_f * w[1], -back_speed])
            om_tool = tilt_back + wiggle_a * 2 * np.pi * wiggle_f * np.array([np.cos(ph), np.sin(ph), 0.0])
        else:
            slow = np.clip(1 - f_push / f_lim - np.hypot(w[3], w[4]) / tau_lim, 0.0, 1.0)
            v_tool = np.array([k_f * w[0], k_f * w[1], v_ins * slow])
            om_tool = np.array([k_t * w[3], k_t * w[4], 0.0])
        p_ref = p_ref + R_ref @ v_tool * dt
        # the hand leads the tool by at most the push force it is willing to apply
        lead = R_ref.T @ (p_ref - scene.pose()[:3, 3])
        if lead[2] > f_lim / person.stiffness:
            p_ref = p_ref - R_ref[:, 2] * (lead[2] - f_lim / person.stiffness)
        R_ref = R_ref @ so3_exp(om_tool * dt)
        hand(p_ref, R_ref)
        record(2)
        if tip_point(scene.pose(), tool)[2] - task.bottom_z < 3e-4 or t - t_ins > person.insertion_timeout:
            break
    phase_t.append(t)
    # completion: a final press, then release
    T = scene.pose()
    p_hold, R_hold = T[:3, 3].copy(), T[:3, :3].copy()
    n_c = int(T_c / dt)
    R_hold = scene.pose()[:3, :3].copy()
    for k in range(1, n_c + 1):
        s = k / n_c
        push = f_press * np.sin(np.pi * min(1.0, 1.6 * s)) if s < 1 / 1.6 else 0.0
        hand(p_hold + R_hold[:, 2] * push / person.stiffness, R_hold)
        record(3)
    seated = tip_point(scene.pose(), tool)[2] - task.bottom_z < 1e-3
    meta = {"phase_times": phase_t[1:], "seated": bool(seated), "max_wall_penetration": max_pen,
            "lateral_error": lat_err.tolist(), "residual_tilt": float(tilt_r), "approach_tilt": float(tilt0),
            "hesitation": pause is not None, "recoveries": recoveries}
    return Demonstration.create(np.array(ts), np.array(poses), np.array(wrenches), np.array(labels),
                                action_names=PHASES, device="hdd", name=name, meta=meta)



def seated_demonstrations(task: PegHole, rng: np.random.Generator, n: int, *, scene: HDDScene | None = None,
                          max_tries: int = 30) -> list[Demonstration]:
    """The first ``n`` demonstrations in which the scripted person seated the peg.

    At a tight fit the person does not seat every try (``meta["seated"]``); a skill is learned from
    the seated ones, as the benchmark does.

    Args:
        task: The peg-hole task.
        rng: Generator of the demonstrations (drawn from in order).
        n: Seated demonstrations wanted, >= 1.
        scene: The HDD scene (built from ``task`` when None).
        max_tries: Demonstrations tried at most.

    Returns:
        ``n`` seated demonstrations, in the order drawn.

    Raises:
        InvalidInput: ``n < 1``, or fewer than ``n`` seated within ``max_tries`` tries.
    """
    if n < 1:
        raise InvalidInput(f"n must be >= 1 seated demonstrations, got {n}", value=n)
    scene = scene or HDDScene(task)
    out: list[Demonstration] = []
    for _ in range(max_tries):
        d = demonstrate(task, rng, scene=scene)
        if d.meta["seated"]:
            out.append(d)
            if len(out) == n:
                return out
    raise InvalidInput(f"only {len(out)} of {max_tries} demonstrations seated the peg, {n} wanted", value=len(out))
