"""Numeric inverse kinematics for any chain: the compiled Levenberg-Marquardt search of ``_ik_kernels``."""
from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from robointel._validate import as_array
from robointel.errors import IKFailure
from robointel.robot._ik_kernels import ik_solve


def numeric_ik(robot: Any, T: ArrayLike, *, q0: ArrayLike | None = None, tol: float = 1e-9, max_iter: int = 100,
               restarts: int = 200, rng: int | None = 0) -> np.ndarray:
    """Q within ``robot``'s limits with fk(q) = T (see :meth:`robointel.robot.Robot.ik_numeric`).

    Args:
        robot: a :class:`robointel.robot.Robot` (its chain arrays, flange frame, tool and limits).
        T: (4, 4) TCP pose in the world frame.
        q0: first start (nq,), rad (default: the mid-range).
        tol: converged when the 6-D error's norm is below it (m and rad).
        max_iter: iterations per start.
        restarts: random starts after the first.
        rng: seed of the random starts.

    Returns:
        (nq,) the solution.

    Raises:
        IKFailure: no start converged.
    """
    T = as_array(T, "T", (4, 4))
    seeds = (robot.check_q(q0, "q0") if q0 is not None else 0.5 * (robot.lower + robot.upper))[None]
    tip = robot.model.frames[robot._flange_id].placement.homogeneous @ robot._tool
    jt = int(robot.model.frames[robot._flange_id].parentJoint)
    out = np.empty(robot.nq)
    seed = int(np.random.default_rng(rng).integers(1 << 31))
    parent, place, axis, kind, qidx = robot.chain
    k, err2 = ik_solve(np.ascontiguousarray(T), np.ascontiguousarray(seeds), parent, place, axis, kind, qidx, jt,
                       np.ascontiguousarray(tip), robot.lower, robot.upper, float(tol), int(max_iter), int(restarts),
                       seed, out)
    if k < 0:
        raise IKFailure(f"numeric IK did not converge in {restarts + 1} starts (best 6-D error "
                        f"{np.sqrt(err2):.3g} > {tol:g}); the pose at {np.round(T[:3, 3], 4).tolist()} m may be "
                        "unreachable within the joint limits", value=out)
    return out
