"""Time-optimal rest-to-rest timing of a piecewise-linear joint path.

Under velocity and acceleration limits, each straight segment is traversed with the trapezoidal (or triangular)
profile of its path parameter, the fastest motion that stays exactly on the segment.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robointel._validate import as_array
from robointel.errors import InvalidInput
from robointel.trajectory import Trajectory

_MIN_GAP = 1e-4
"""A grid knot closer than this to a switch of the profile or to a vertex, s, is left out (rounding in
the positions over a shorter interval would bend the interpolant's acceleration)."""


def _segment(delta: np.ndarray, vmax: np.ndarray, amax: np.ndarray) -> tuple[float, float, float]:
    """Peak path speed, path acceleration (per unit of the parameter s in [0, 1]) and duration."""
    a = np.abs(delta)
    nz = a > 0
    sv = float(np.min(vmax[nz] / a[nz]))
    sa = float(np.min(amax[nz] / a[nz]))
    if sv * sv / sa >= 1.0:  # triangular: never reaches sv
        sv = float(np.sqrt(sa))
        return sv, sa, 2.0 * sv / sa
    return sv, sa, 1.0 / sv + sv / sa


def polyline_timing(path: npt.ArrayLike, vmax: npt.ArrayLike, amax: npt.ArrayLike, *, dt: float = 1e-3,
                    joint_names: list[str] | None = None) -> Trajectory:
    """Time a polyline rest-to-rest per segment, time-optimally, sampled every ``dt``.

    With s in [0, 1] along a segment of joint displacement d, q = q_a + s d; the limits become
    |s'| <= min_k vmax_k / |d_k| and |s''| <= min_k amax_k / |d_k|, and the fastest rest-to-rest
    motion is the trapezoid (or triangle) of s.

    Args:
        path: (N+1, n) vertices, rad.
        vmax: (n,) velocity limits, rad/s.
        amax: (n,) acceleration limits, rad/s^2.
        dt: sampling step, s.
        joint_names: names of the n joints.

    Returns:
        The trajectory with knots every ``dt``, at every vertex and at every switch of the profile
        (so its cubic Hermite interpolant is the profile itself: exact q, qd, qdd everywhere).

    Raises:
        InvalidInput: bad shapes, non-positive limits or dt.
    """
    P = as_array(path, "path", (None, None))
    n = P.shape[1]
    vmax, amax = as_array(vmax, "vmax", (n,)), as_array(amax, "amax", (n,))
    if np.any(vmax <= 0) or np.any(amax <= 0) or not dt > 0 or len(P) < 2:
        raise InvalidInput("polyline timing needs >= 2 points, positive limits and dt", value=(vmax, amax, dt))
    T: list[np.ndarray] = [np.zeros(1)]
    Q: list[np.ndarray] = [P[:1].copy()]
    QD: list[np.ndarray] = [np.zeros((1, n))]
    QDD: list[np.ndarray] = [np.zeros((1, n))]
    t0 = 0.0
    for k in range(len(P) - 1):
        d = P[k + 1] - P[k]
        if not np.any(np.abs(d) > 1e-12):
            continue
        sv, sa, dur = _segment(d, vmax, amax)
        tr = sv / sa  # ramp time
        # knots every dt plus the profile's switching times: between two knots the motion is then one
        # quadratic piece, which the trajectory's cubic Hermite interpolant reproduces exactly (a knot
        # interval across a switch would bend its acceleration up to 1.5x the limit)
        grid = np.arange(1, int(np.ceil(dur / dt))) * dt
        keys = np.array([x for x in (tr, dur - tr) if 0.0 < x < dur] + [dur])
        near = np.min(np.abs(grid[:, None] - keys[None, :]), axis=1) < _MIN_GAP
        ts = np.union1d(grid[~near], keys)
        s = np.where(ts < tr, 0.5 * sa * ts ** 2,
                     np.where(ts > dur - tr, 1.0 - 0.5 * sa * (dur - ts) ** 2, 0.5 * sa * tr ** 2 + sv * (ts - tr)))
        sd = np.where(ts < tr, sa * ts, np.where(ts > dur - tr, sa * (dur - ts), sv))
        sdd = np.where(ts < tr, sa, np.where(ts > dur - tr, -sa, 0.0))
        s[-1], sd[-1] = 1.0, 0.0
        T.append(t0 + ts)
        Q.append(P[k] + s[:, None] * d)
        QD.append(sd[:, None] * d)
        QDD.append(sdd[:, None] * d)
        t0 += dur
    return Trajectory(np.concatenate(T), np.concatenate(Q), np.concatenate(QD), np.concatenate(QDD),
                      list(joint_names or []), {"timing": "rest-to-rest per segment"})
