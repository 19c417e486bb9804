"""The dense check of a planned trajectory.

Every 1 ms sample within the joint limits and at least
``d_min - tol`` from the obstacles and from the robot itself (constraints (7.2)-(7.3) and the
limits of (7.8), checked on the executed curve rather than at the knots).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from robointel.outcome import Failure
from robointel.planning import _collision_kernels as K
from robointel.planning import _dense_kernels as D
from robointel.planning.environment import Environment
from robointel.trajectory import Trajectory

#: clearance tolerance of the dense check below d_min, m
CLEARANCE_TOL = 1e-3
#: relative tolerance on the velocity and acceleration limits (floating-point rounding only)
LIMIT_TOL = 1e-6


@dataclass(frozen=True)
class DenseCheck:
    """Outcome of :func:`check_dense`.

    Attributes:
        ok: every sample passed.
        reason: "" when ok, else the first failed property with its figure.
        kind: "collision", "limit" or "" when ok.
        min_clearance_m: smallest clearance over the evaluated samples, m (capped at ``d_min + 0.1``
            m). Exact when it is below ``d_min - CLEARANCE_TOL`` (the check fails); otherwise the
            samples skipped by the travel bound are proven >= ``d_min - CLEARANCE_TOL`` and the true
            minimum lies between that and this value. The spheres' clearance to the obstacles and
            between the robot's links (to the obstacles only with ``self_collision=False``).
        samples: number of samples checked.
        links: the robot links of the failed pair on the exact geometry (the link, or both links
            of a self-collision), when the collision meshes failed the check; else empty.
        q: (n,) the configuration of the sample the collision meshes failed, rad; else None.
    """

    ok: bool
    reason: str
    kind: str
    min_clearance_m: float
    samples: int
    links: tuple[str, ...] = ()
    q: np.ndarray | None = field(default=None, compare=False)

    @property
    def failure(self) -> Failure:
        """The shared failure reason: ``COLLISION``, ``LIMIT``, or ``NONE`` when ok."""
        return {"collision": Failure.COLLISION, "limit": Failure.LIMIT}.get(self.kind, Failure.NONE)


def check_dense(env: Environment, traj: Trajectory, *, d_min: float, vmax: npt.ArrayLike,
                amax: npt.ArrayLike, dt: float = 1e-3, window: tuple[float, float, tuple] | None = None,
                self_collision: bool = True) -> DenseCheck:
    """Resample ``traj`` every ``dt`` seconds and check limits and clearance.

    Args:
        env: the environment (robot spheres, obstacles, self-collision pairs).
        traj: the trajectory (t, q, qd, qdd), n joints.
        d_min: required clearance, m; samples must keep ``d_min - CLEARANCE_TOL``.
        vmax: (n,) velocity limits, rad/s.
        amax: (n,) acceleration limits, rad/s^2.
        dt: resampling step, s (1 ms).
        window: (t0, t1, W): the samples with t0 <= t <= t1 are checked in the packed world ``W``
            instead of ``env.world``. ``W`` must be ``env.world`` with spheres at least as large (e.g.
            :attr:`Environment.world_cover` while relaxed spheres are in use): its clearance is then
            never above ``env.world``'s, so passing in it implies passing in ``env.world`` (the
            reported clearance of those samples is ``W``'s).
        self_collision: also check the spheres' self-collision pairs. False when the caller decides
            self-collision on the exact geometry afterwards
            (:func:`~robointel.planning.hybrid_check.self_check`): the sphere pairs would only repeat it.

    Returns:
        The :class:`DenseCheck`.
    """
    robot = env.robot
    # knots already on a grid at least as fine as dt are checked as given (their qdd is exact)
    dense = traj if float(np.max(np.diff(traj.t))) <= dt * (1 + 1e-9) else traj.resample(dt)
    Q = np.ascontiguousarray(dense.q)
    vmax = np.ascontiguousarray(vmax, dtype=float)
    amax = np.ascontiguousarray(amax, dtype=float)
    V = np.empty(Q.shape)
    first, rv, ra = D.limits_travel(Q, np.ascontiguousarray(dense.qd), np.ascontiguousarray(dense.qdd),
                                    np.asarray(robot.lower, float), np.asarray(robot.upper, float), vmax, amax, V)
    cap = d_min + 0.1
    s = env.scratch
    floor = d_min - CLEARANCE_TOL
    spans: tuple[tuple[int, int, tuple], ...]
    Wd = env.world if self_collision else obstacles_only(env.world)
    if window is None:
        spans = ((0, len(Q), Wd),)
        Ww: tuple | None = None
    else:  # before, inside, after the window: each stretch with its world
        t0, t1, Ww = window
        if not self_collision:
            Ww = obstacles_only(Ww)
        a = int(np.searchsorted(dense.t, t0, side="left"))
        b = max(a, int(np.searchsorted(dense.t, t1, side="right")))
        spans = ((0, a, Wd), (a, b, Ww), (b, len(Q), Wd))
    dmin, worst, inside = cap, 0, False
    for lo, hi, W in spans:
        if hi > lo:
            d, w, _ = D.span_clearance(Q, V, lo, hi, W, s.T, s.C, s.G, s.out, env.lever, floor, cap, dmin)
            if w >= 0:
                dmin, worst, inside = d, w, W is Ww
    n = len(Q)
    if first >= 0:
        return DenseCheck(False, f"joint position limit exceeded at t = {dense.t[first]:.3f} s", "limit", dmin, n)
    if rv.max() > 1 + LIMIT_TOL:
        j = int(np.argmax(rv))
        return DenseCheck(False, f"velocity limit of {robot.joint_names[j]} exceeded {rv[j]:.4f}x", "limit", dmin, n)
    if ra.max() > 1 + LIMIT_TOL:
        j = int(np.argmax(ra))
        return DenseCheck(False, f"acceleration limit of {robot.joint_names[j]} exceeded {ra[j]:.4f}x", "limit",
                          dmin, n)
    if dmin < floor and inside:
        return DenseCheck(False, f"the covering spheres come {dmin * 1e3:.1f} mm from the obstacles at t = "
                          f"{dense.t[worst]:.3f} s (required {d_min * 1e3:.1f} mm - {CLEARANCE_TOL * 1e3:.0f} mm)",
                          "collision", dmin, n)
    if dmin < floor:
        c = env.contact(Q[worst], cap=cap)
        return DenseCheck(False, f"{c.message(f'trajectory sample at t = {dense.t[worst]:.3f} s')} "
                          f"(required {d_min * 1e3:.1f} mm - {CLEARANCE_TOL * 1e3:.0f} mm)", "collision", dmin, n)
    return DenseCheck(True, "", "", float(dmin), n)


def obstacles_only(W: tuple) -> tuple:
    """The packed world ``W`` without its self-collision pairs (``W[14]`` and ``W[20]`` emptied)."""
    n = W[20].shape[1]
    return W[:14] + (np.zeros((0, 2), W[14].dtype),) + W[15:20] + (np.zeros((0, n)),) + W[21:]


def window_clearance(env: Environment, traj: Trajectory, W: tuple, t0: float, t1: float, *, d_min: float,
                     dt: float = 1e-3) -> float:
    """Smallest clearance in world ``W`` over the samples of ``traj`` with t0 <= t <= t1.

    Args:
        env: the environment (its scratch arrays and levers are used).
        traj: the trajectory.
        W: the packed world to check in (e.g. :attr:`Environment.world_cover`).
        t0: window start, s.
        t1: window end, s.
        d_min: required clearance, m (as in :func:`check_dense`, the result is exact below
            ``d_min - CLEARANCE_TOL``, else the samples skipped are proven >= that).
        dt: resampling step, s.

    Returns:
        The clearance, m (``d_min + 0.1`` when the window is empty or far from everything).
    """
    dense = traj if float(np.max(np.diff(traj.t))) <= dt * (1 + 1e-9) else traj.resample(dt)
    Q = np.ascontiguousarray(dense.q[(dense.t >= t0) & (dense.t <= t1)])
    if len(Q) == 0:
        return d_min + 0.1
    s = env.scratch
    d, _ = K.samples_clearance(Q, W, s.T, s.C, s.G, s.out, env.lever, d_min - CLEARANCE_TOL, d_min + 0.1)
    return float(d)
