"""Jerk-limited timing of a piecewise-linear joint path with ruckig.

Each straight segment is a
time-optimal, phase-synchronised (straight in joint space) motion from rest to rest.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt
from ruckig import InputParameter, Result, Ruckig, Synchronization
from ruckig import Trajectory as RuckigTrajectory

from robointel._validate import as_array
from robointel.errors import InvalidInput, SolverFailure
from robointel.trajectory import Trajectory


def jerk_limited_polyline(path: npt.ArrayLike, vmax: npt.ArrayLike, amax: npt.ArrayLike, jmax: npt.ArrayLike,
                          *, dt: float = 1e-3, joint_names: list[str] | None = None) -> Trajectory:
    """Time a polyline rest-to-rest per segment under velocity, acceleration and jerk limits.

    Args:
        path: (N+1, n) vertices, rad; N >= 1.
        vmax: (n,) velocity limits, rad/s.
        amax: (n,) acceleration limits, rad/s^2.
        jmax: (n,) jerk limits, rad/s^3.
        dt: sampling step of the returned trajectory, s.
        joint_names: names of the n joints.

    Returns:
        The trajectory sampled every ``dt`` (knots on the grid; each segment's end on its knot).

    Raises:
        InvalidInput: bad shapes or non-positive limits.
        SolverFailure: ruckig could not compute a segment.
    """
    P = as_array(path, "path", (None, None))
    n = P.shape[1]
    lim = [as_array(x, name, (n,)) for x, name in ((vmax, "vmax"), (amax, "amax"), (jmax, "jmax"))]
    if any(np.any(v <= 0) for v in lim) or len(P) < 2:
        raise InvalidInput("jerk-limited timing needs >= 2 path points and positive limits", value=lim)
    otg = Ruckig(n)
    inp = InputParameter(n)
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = (v.tolist() for v in lim)
    inp.synchronization = Synchronization.Phase
    T, Q, QD, QDD = [np.zeros(1)], [P[:1]], [np.zeros((1, n))], [np.zeros((1, n))]
    t0 = 0.0
    for k in range(len(P) - 1):
        if np.allclose(P[k], P[k + 1], atol=1e-12):
            continue
        inp.current_position, inp.target_position = P[k].tolist(), P[k + 1].tolist()
        inp.current_velocity = inp.current_acceleration = [0.0] * n
        inp.target_velocity = inp.target_acceleration = [0.0] * n
        tr = RuckigTrajectory(n)
        res = otg.calculate(inp, tr)
        if res not in (Result.Working, Result.Finished):
            raise SolverFailure(f"ruckig failed on segment {k}: {res}", value=k)
        dur = float(tr.duration)
        ts = np.arange(dt, dur, dt)
        ts = np.append(ts, dur) if (len(ts) == 0 or ts[-1] < dur - 1e-9) else ts
        smp = [tr.at_time(float(x)) for x in ts]
        T.append(t0 + ts)
        Q.append(np.array([s[0] for s in smp]))
        QD.append(np.array([s[1] for s in smp]))
        QDD.append(np.array([s[2] for s in smp]))
        Q[-1][-1], QD[-1][-1], QDD[-1][-1] = P[k + 1], 0.0, 0.0
        t0 += dur
    t = np.concatenate(T)
    keep = np.concatenate([[True], np.diff(t) > 1e-9])
    return Trajectory(t[keep], np.concatenate(Q)[keep], np.concatenate(QD)[keep], np.concatenate(QDD)[keep],
                      list(joint_names or []), {"timing": "ruckig"})
