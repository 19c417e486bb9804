"""The one jerk-limited online follower of a moving joint target (``ruckig``).

:meth:`JerkLimitedFollower.step` (velocity interface): each period the commanded velocity is the
target's velocity plus a feedback on the position error, ``gain * e`` near the target and at most
``sqrt(2 s a_b |e|)`` far from it (a_b the deceleration available when arriving from e's side, s the
share of it the feedback may use; so catching up never overshoots), clipped to the velocity limit;
ruckig reaches it within the acceleration and jerk limits. :meth:`~JerkLimitedFollower.step_position`
is ruckig's time-optimal move to a target state (position interface), :meth:`~JerkLimitedFollower.brake`
decelerates to rest. The limits may change every period (:meth:`~JerkLimitedFollower.set_limits`), e.g.
the torque-feasible acceleration bounds (3.9) of the SCARA study. Used for teleoperation streaming,
imitation references and the SCARA study.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt
from ruckig import ControlInterface, InputParameter, OutputParameter, Result, Ruckig, Synchronization

from robointel._validate import as_array
from robointel.errors import InvalidInput, SolverFailure

Vector = npt.NDArray[np.float64]


class JerkLimitedFollower:
    """Follow a moving target within velocity, acceleration and jerk limits, one period per call.

    Args:
        vmax: (n,) velocity limits, rad/s.
        amax: (n,) acceleration limits, rad/s^2 (the lower bound is -amax until :meth:`set_limits`).
        jmax: (n,) jerk limits, rad/s^3.
        dt: period, s.
        gain: position feedback near the target, 1/s.
        lower: (n,) lower position limits the output is clipped to, rad (None: unclipped).
        upper: (n,) upper position limits, rad.
        brake_share: s, the share of the available deceleration the far-field feedback
            ``sqrt(2 s a_b |e|)`` plans with, in (0, 1].
        velocity_share: the commanded velocity stays within ``velocity_share * vmax``, in (0, 1].
        synchronize: ruckig's time synchronisation of the joints (False: each joint as fast as it can).

    Raises:
        InvalidInput: non-positive limits or period, shares outside (0, 1], shapes that disagree.
    """

    def __init__(self, vmax: npt.ArrayLike, amax: npt.ArrayLike, jmax: npt.ArrayLike, *, dt: float = 0.001,
                 gain: float = 12.0, lower: npt.ArrayLike | None = None, upper: npt.ArrayLike | None = None,
                 brake_share: float = 0.25, velocity_share: float = 1.0, synchronize: bool = True) -> None:
        self.vmax = as_array(vmax, "vmax", (None,))
        n = self.n = len(self.vmax)
        self.amax = np.broadcast_to(as_array(amax, "amax"), (n,)).astype(float)
        self.jmax = np.broadcast_to(as_array(jmax, "jmax"), (n,)).astype(float)
        if np.any(self.vmax <= 0) or np.any(self.amax <= 0) or np.any(self.jmax <= 0) or not dt > 0:
            raise InvalidInput("velocity, acceleration, jerk limits and dt must be positive",
                               value=(vmax, amax, jmax, dt))
        if not (0.0 < brake_share <= 1.0 and 0.0 < velocity_share <= 1.0):
            raise InvalidInput(f"brake_share and velocity_share must be in (0, 1], got {brake_share}, "
                               f"{velocity_share}", value=(brake_share, velocity_share))
        self.amin = -self.amax
        self.dt, self.gain = float(dt), float(gain)
        self._brake = 2.0 * float(brake_share)
        self.velocity_share = float(velocity_share)
        self.lower = None if lower is None else as_array(lower, "lower", (n,))
        self.upper = None if upper is None else as_array(upper, "upper", (n,))
        self._otg = Ruckig(n, self.dt)
        self._inp, self._out = InputParameter(n), OutputParameter(n)
        if not synchronize:
            self._inp.synchronization = Synchronization.No
        self._inp.control_interface = ControlInterface.Velocity
        self._inp.max_velocity = self.vmax.tolist()
        self._inp.max_acceleration = self.amax.tolist()
        self._inp.max_jerk = self.jmax.tolist()
        self._inp.target_acceleration = [0.0] * n
        self.q = np.zeros(n)
        self.qd = np.zeros(n)
        self.qdd = np.zeros(n)
        self.reset(self.q)

    def reset(self, q: npt.ArrayLike, qd: npt.ArrayLike | None = None, qdd: npt.ArrayLike | None = None) -> None:
        """Continue from position ``q`` (n,) rad, velocity ``qd`` (n,) rad/s, acceleration ``qdd`` (n,) rad/s^2.

        ``qd`` and ``qdd`` default to rest.

        Raises:
            ShapeError, NotFinite: bad arrays.
        """
        self.q = as_array(q, "q", (self.n,)).copy()
        self.qd = np.zeros(self.n) if qd is None else as_array(qd, "qd", (self.n,)).copy()
        self.qdd = np.zeros(self.n) if qdd is None else as_array(qdd, "qdd", (self.n,)).copy()
        self._inp.current_position = self.q.tolist()
        self._inp.current_velocity = self.qd.tolist()
        self._inp.current_acceleration = self.qdd.tolist()

    def set_limits(self, *, max_acceleration: npt.ArrayLike | None = None,
                   min_acceleration: npt.ArrayLike | None = None, max_jerk: npt.ArrayLike | None = None) -> None:
        """Change the acceleration and jerk limits from the next period on (e.g. state-dependent bounds).

        Args:
            max_acceleration: (n,) upper acceleration bounds, rad/s^2, > 0 (None: unchanged).
            min_acceleration: (n,) lower acceleration bounds, rad/s^2, < 0 (None: unchanged).
            max_jerk: (n,) jerk limits, rad/s^3, > 0 (None: unchanged).

        Raises:
            InvalidInput: a bound of the wrong sign or shape.
        """
        if max_acceleration is not None:
            hi = np.asarray(max_acceleration, dtype=float)
            if hi.shape != (self.n,) or not np.all(hi > 0):
                raise InvalidInput(f"max_acceleration must be {self.n} numbers > 0, got {hi}", value=hi)
            self.amax = hi
            self._inp.max_acceleration = hi.tolist()
        if min_acceleration is not None:
            lo = np.asarray(min_acceleration, dtype=float)
            if lo.shape != (self.n,) or not np.all(lo < 0):
                raise InvalidInput(f"min_acceleration must be {self.n} numbers < 0, got {lo}", value=lo)
            self.amin = lo
            self._inp.min_acceleration = lo.tolist()
        if max_jerk is not None:
            j = np.asarray(max_jerk, dtype=float)
            if j.shape != (self.n,) or not np.all(j > 0):
                raise InvalidInput(f"max_jerk must be {self.n} numbers > 0, got {j}", value=j)
            self.jmax = j
            self._inp.max_jerk = j.tolist()

    def step(self, target: npt.ArrayLike, target_velocity: npt.ArrayLike | None = None) -> tuple[Vector, Vector,
                                                                                                  Vector]:
        """One period toward ``target`` (n,) rad moving at ``target_velocity`` (n,) rad/s (velocity interface).

        Returns:
            (q, qd, qdd), each (n,): the next reference, rad, rad/s, rad/s^2.

        Raises:
            SolverFailure: ruckig reported an error.
        """
        e = np.asarray(target, dtype=float) - self.q
        brake = np.where(e > 0, -self.amin, self.amax)  # deceleration available when arriving from e's side
        fb = np.sign(e) * np.minimum(self.gain * np.abs(e), np.sqrt(self._brake * brake * np.abs(e)))
        tv = np.zeros(self.n) if target_velocity is None else np.asarray(target_velocity, dtype=float)
        vcap = self.vmax if self.velocity_share == 1.0 else self.velocity_share * self.vmax
        self._inp.control_interface = ControlInterface.Velocity
        self._inp.target_velocity = np.clip(tv + fb, -vcap, vcap).tolist()
        self._inp.target_acceleration = [0.0] * self.n
        return self._update()

    def step_position(self, target: npt.ArrayLike, target_velocity: npt.ArrayLike | None = None) -> tuple[
            Vector, Vector, Vector]:
        """One period of the time-optimal move to the state (``target`` (n,) rad, ``target_velocity`` (n,) rad/s).

        ruckig's position interface; the target velocity (default rest) is clipped to the velocity limit.

        Returns:
            (q, qd, qdd), each (n,): the next reference, rad, rad/s, rad/s^2.

        Raises:
            SolverFailure: ruckig reported an error.
        """
        vcap = self.vmax if self.velocity_share == 1.0 else self.velocity_share * self.vmax
        tv = np.zeros(self.n) if target_velocity is None else np.clip(np.asarray(target_velocity, dtype=float),
                                                                      -vcap, vcap)
        self._inp.control_interface = ControlInterface.Position
        self._inp.target_position = np.asarray(target, dtype=float).tolist()
        self._inp.target_velocity = tv.tolist()
        self._inp.target_acceleration = [0.0] * self.n
        return self._update()

    def brake(self) -> tuple[Vector, Vector, Vector]:
        """One period of decelerating to rest within the limits (velocity interface, target velocity 0).

        Returns:
            (q, qd, qdd), each (n,), rad, rad/s, rad/s^2.

        Raises:
            SolverFailure: ruckig reported an error.
        """
        self._inp.control_interface = ControlInterface.Velocity
        self._inp.target_velocity = [0.0] * self.n
        self._inp.target_acceleration = [0.0] * self.n
        return self._update()

    @property
    def at_rest(self) -> bool:
        """Velocity and acceleration below 1e-9 (rad/s, rad/s^2) on every joint."""
        return bool(np.max(np.abs(self.qd)) < 1e-9 and np.max(np.abs(self.qdd)) < 1e-9)

    def _update(self) -> tuple[Vector, Vector, Vector]:
        res = self._otg.update(self._inp, self._out)
        if res not in (Result.Working, Result.Finished):
            raise SolverFailure(f"ruckig failed ({res})", value=res)
        q = np.array(self._out.new_position)
        if self.lower is not None and self.upper is not None:
            q = np.clip(q, self.lower, self.upper)
        self.q, self.qd, self.qdd = q, np.array(self._out.new_velocity), np.array(self._out.new_acceleration)
        self._out.pass_to_input(self._inp)
        return q, self.qd.copy(), self.qdd.copy()
