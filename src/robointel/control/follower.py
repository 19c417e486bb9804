"""The one jerk-limited online follower of a moving joint target (``ruckig``, velocity interface).

Each period the commanded velocity is the target's velocity plus a feedback on the position error,
``gain * e`` near the target and at most ``sqrt(a_max |e| / 2)`` far from it (so catching up never
overshoots), clipped to the velocity limit; ruckig reaches it within the acceleration and jerk
limits. Used for teleoperation targets, imitation references and the SCARA study.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt
from ruckig import ControlInterface, InputParameter, OutputParameter, Result, Ruckig

from robointel._validate import as_array
from robointel.errors import InvalidInput, SolverFailure

Vector = npt.NDArray[np.float64]


class JerkLimitedFollower:
    """Follow a moving target within velocity, acceleration and jerk limits, one period per call.

    Args:
        vmax: (n,) velocity limits, rad/s.
        amax: (n,) acceleration limits, rad/s^2.
        jmax: (n,) jerk limits, rad/s^3.
        dt: period, s.
        gain: position feedback near the target, 1/s.
        lower: (n,) lower position limits, rad (None: unclipped).
        upper: (n,) upper position limits, rad.

    Raises:
        InvalidInput: non-positive limits or period, shapes that disagree.
    """

    def __init__(self, vmax: npt.ArrayLike, amax: npt.ArrayLike, jmax: npt.ArrayLike, *, dt: float = 0.001,
                 gain: float = 12.0, lower: npt.ArrayLike | None = None, upper: npt.ArrayLike | None = None) -> None:
        self.vmax = as_array(vmax, "vmax", (None,))
        n = self.n = len(self.vmax)
        self.amax = np.broadcast_to(as_array(amax, "amax"), (n,)).astype(float)
        self.jmax = np.broadcast_to(as_array(jmax, "jmax"), (n,)).astype(float)
        if np.any(self.vmax <= 0) or np.any(self.amax <= 0) or np.any(self.jmax <= 0) or not dt > 0:
            raise InvalidInput("velocity, acceleration, jerk limits and dt must be positive",
                               value=(vmax, amax, jmax, dt))
        self.dt, self.gain = float(dt), float(gain)
        self.lower = None if lower is None else as_array(lower, "lower", (n,))
        self.upper = None if upper is None else as_array(upper, "upper", (n,))
        self._otg = Ruckig(n, self.dt)
        self._inp, self._out = InputParameter(n), OutputParameter(n)
        self._inp.control_interface = ControlInterface.Velocity
        self._inp.max_velocity = self.vmax.tolist()
        self._inp.max_acceleration = self.amax.tolist()
        self._inp.max_jerk = self.jmax.tolist()
        self._inp.target_acceleration = [0.0] * n
        self.q = np.zeros(n)
        self.qd = np.zeros(n)
        self.reset(self.q)

    def reset(self, q: npt.ArrayLike, qd: npt.ArrayLike | None = None) -> None:
        """Start from position ``q`` (n,) rad at velocity ``qd`` (n,) rad/s (default rest)."""
        self.q = as_array(q, "q", (self.n,)).copy()
        self.qd = np.zeros(self.n) if qd is None else as_array(qd, "qd", (self.n,)).copy()
        self._inp.current_position = self.q.tolist()
        self._inp.current_velocity = self.qd.tolist()
        self._inp.current_acceleration = [0.0] * self.n

    def step(self, target: npt.ArrayLike, target_velocity: npt.ArrayLike | None = None) -> tuple[Vector, Vector,
                                                                                                  Vector]:
        """One period toward ``target`` (n,) rad moving at ``target_velocity`` (n,) rad/s.

        Returns:
            (q, qd, qdd), each (n,): the next reference, rad, rad/s, rad/s^2.

        Raises:
            SolverFailure: ruckig reported an error.
        """
        e = np.asarray(target, dtype=float) - self.q
        fb = np.sign(e) * np.minimum(self.gain * np.abs(e), np.sqrt(0.5 * self.amax * np.abs(e)))
        tv = np.zeros(self.n) if target_velocity is None else np.asarray(target_velocity, dtype=float)
        self._inp.target_velocity = np.clip(tv + fb, -self.vmax, self.vmax).tolist()
        res = self._otg.update(self._inp, self._out)
        if res not in (Result.Working, Result.Finished):
            raise SolverFailure(f"ruckig failed ({res})", value=res)
        q = np.array(self._out.new_position)
        if self.lower is not None and self.upper is not None:
            q = np.clip(q, self.lower, self.upper)
        self.q, self.qd = q, np.array(self._out.new_velocity)
        self._out.pass_to_input(self._inp)
        return q, self.qd.copy(), np.array(self._out.new_acceleration)
