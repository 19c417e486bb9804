"""The motion planner's last stage: time the shortened path, then check the trajectory.

The dense check (:func:`~robointel.planning.motion_check.check_dense`) of every limit and of the
spheres' clearance, then the collision-mesh checks the spheres leave in doubt (the start and goal
edges of a hybrid plan, every doubtful sample in the fitted-sphere fallback, self-collision on the
exact geometry).
"""
from __future__ import annotations

import time

import numpy as np

from robointel.planning.budget_clock import now as clock_now
from robointel.planning.environment import Environment
from robointel.planning.hybrid_check import (
    exact_check,
    interior_check,
    interior_window,
    path_touches,
    self_check,
    timed_out,
)
from robointel.planning.jerk_limited import jerk_limited_polyline
from robointel.planning.motion_check import DenseCheck, check_dense
from robointel.planning.motion_settings import MotionSettings
from robointel.planning.polyline_timing import polyline_timing
from robointel.planning.stage_times import StageTimes, cpu_clock
from robointel.planning.temporal import temporal_optimize
from robointel.planning.topp import densify, topp_spline
from robointel.trajectory import Trajectory


def smooth_and_check(env: Environment, path: np.ndarray, st: MotionSettings, deadline: float, Wc: tuple,
                     hybrid: bool, vmax: np.ndarray, amax: np.ndarray, timings: StageTimes,
                     exact: bool) -> tuple[Trajectory | None, DenseCheck | None]:
    """Timing and the dense (and mesh) checks of the shortened ``path``: (trajectory, check).

    A spline through knots along ``path`` (TOPP, or temporal optimization), knots 4x closer when it
    fails the dense check, then rest-to-rest motion along the polyline (or ruckig's jerk-limited one),
    unless the collision meshes refuse the polyline itself where they refused the spline
    (:func:`~robointel.planning.hybrid_check.path_touches`).

    Args:
        env: the environment (its current spheres).
        path: (k, n) the shortened path, rad.
        st: the plan's settings.
        deadline: on ``budget_clock``: past it a check ends as a failed one of kind ``"timeout"``.
        Wc: the packed world of the mesh-covering spheres.
        hybrid: relaxed spheres at the start and goal edges (their samples checked on the meshes).
        vmax: (n,) velocity limits, rad/s.
        amax: (n,) acceleration limits, rad/s^2.
        timings: the plan's stage times (``smooth``, ``timing``).
        exact: every sample the covering spheres leave in doubt is checked on the meshes.
    """
    robot = env.robot
    t3, c3 = time.perf_counter(), cpu_clock()
    names = list(robot.joint_names)
    traj, chk = None, None
    touched = False  # the collision meshes failed the path itself, not only its smoothing
    # hybrid: the interior (between the inner vertices) is checked in the covering spheres Wc alone (they
    # contain the relaxed ones in use, so passing there passes env.world too), the start/goal edges on the meshes
    win = hybrid and not exact and len(path) >= 3
    if st.smooth and not st.jerk_limited and len(path) > 2:
        steps = (st.knot_step,) if st.timing == "temporal" else (st.spline_step, st.spline_step / 4)
        for step in steps:  # a spline that leaves the checked polyline too far: knots closer together
            if chk is not None and clock_now() >= deadline:
                chk = timed_out("the smoothing", chk)
                break
            if st.timing == "temporal":
                tt = temporal_optimize(densify(path, float(step)), vmax, amax).trajectory
                traj = Trajectory(tt.t, tt.q, tt.qd, tt.qdd, names, {"timing": "temporal optimization (7.7)-(7.9)"})
            else:
                traj = topp_spline(path, vmax, amax, step=float(step), dt=st.check_dt, joint_names=names)
            tw = interior_window(traj, path) if hybrid and not exact else None
            chk = check_dense(env, traj, d_min=st.d_min, vmax=vmax, amax=amax, dt=st.check_dt,
                              window=(*tw, Wc) if win and tw is not None else None, self_collision=not env.exact_self)
            chk = mesh_checks(env, traj, path, Wc, chk, st, deadline, hybrid, exact, win, tw)
            if chk.ok or chk.kind != "collision":
                break
            if path_touches(env, path, chk, d_min=st.d_min):  # no timing of this path passes there
                touched = True
                break
        timings.add("smooth", t3, c3)
    if chk is not None and not chk.ok and chk.kind != "timeout" and clock_now() >= deadline:
        chk = timed_out("the smoothing", chk)  # a collision or a limit: no rest-to-rest fallback past the budget
    if chk is None or (not chk.ok and chk.kind != "timeout" and not touched):  # rest to rest along the polyline
        t4, c4 = time.perf_counter(), cpu_clock()
        if st.jerk_limited:
            jmax = np.asarray(st.jerk_limit if st.jerk_limit is not None else 10 * amax, float)
            traj = jerk_limited_polyline(path, vmax, amax, jmax, dt=st.check_dt, joint_names=names)
        else:
            traj = polyline_timing(path, vmax, amax, dt=st.check_dt, joint_names=names)
        tw = interior_window(traj, path) if hybrid and not exact else None
        chk = check_dense(env, traj, d_min=st.d_min, vmax=vmax, amax=amax, dt=st.check_dt,
                          window=(*tw, Wc) if win and tw is not None else None, self_collision=not env.exact_self)
        chk = mesh_checks(env, traj, path, Wc, chk, st, deadline, hybrid, exact, win, tw)
        timings.add("timing", t4, c4)
    return traj, chk


def mesh_checks(env: Environment, traj: Trajectory, path: np.ndarray, Wc: tuple, chk: DenseCheck, st: MotionSettings,
                deadline: float, hybrid: bool, exact: bool, window_checked: bool = False,
                window: tuple[float, float] | None = None) -> DenseCheck:
    """The collision-mesh checks a passed dense check still needs: start/goal edges (hybrid) or all (exact).

    ``window``: the trajectory's :func:`interior_window` when already known (hybrid).
    """
    if not chk.ok:
        return chk
    if exact:
        chk = exact_check(env, traj, env.world_cover, chk, d_min=st.d_min, dt=st.check_dt, deadline=deadline)
    elif hybrid:
        chk = interior_check(env, traj, path, Wc, chk, d_min=st.d_min, dt=st.check_dt, deadline=deadline,
                             window_checked=window_checked, window=window)
    return self_check(env, traj, chk, dt=st.check_dt, deadline=deadline)
