"""A force loop paced at the robot's own ticks: each cycle starts on the first state newer than the last one.

A force loop closed over the stream (read the wrench, move the target, send it) paced by the caller's
clock (``sleep_until(t0 + k * period)``) reads the robot's state at an arbitrary, fixed phase of the
robot's controller window. On a robot that ticks on its own clock (a FANUC controller, the sim's
streaming process) the target sent at that phase is played at the next tick, or, when the phase falls
after the tick's cut-off, one tick later: the loop's delay from a measurement to its effect is one or two
periods depending on when the loop started, and an admittance whose gain is tuned for one period goes
unstable at two (the grinding skill through ``sim?process=1``, docs/design/force-loops.md).
:class:`TickPacer` starts each cycle on the robot's clock instead: it sleeps until shortly before the next
state is due and polls until the state's time has advanced, so the target goes out right after the
measurement it answers. A backend whose state advances only when it is commanded (the in-process
``SimRobot``) keeps the caller's clock (``Backend.clocked`` False).
"""
from __future__ import annotations

import time
from typing import Any

from robointel.errors import InvalidInput
from robointel.interface.realtime import sleep_until
from robointel.interface.state import RobotState

EARLY_S = 0.001
"""How long before the next state is due the pacer starts polling for it, s."""
POLL_S = 0.0002
"""The polling interval while waiting for the next state, s."""
WAIT_PERIODS = 1.5
"""After this many periods without a newer state the cycle goes on with the newest one (counted as ``stale``)."""


class TickPacer:
    """Paces a loop over a robot interface: one cycle per robot tick (``clocked`` backends) or per period.

    ``pacer = TickPacer(arm)``; each cycle ``st = pacer.next()``, then compute and ``arm.stream(...)``.

    Args:
        arm: the robot interface (``period``, ``paced``, ``clocked``, ``state()``).
        early_s: start polling this long before the next state is due, s.
        poll_s: polling interval, s.

    Attributes:
        cycles: cycles paced so far.
        stale: cycles that went on after :data:`WAIT_PERIODS` periods without a newer state.

    Raises:
        InvalidInput: ``early_s`` outside [0, period) or ``poll_s`` outside (0, period].
    """

    def __init__(self, arm: Any, *, early_s: float = EARLY_S, poll_s: float = POLL_S) -> None:
        dt = float(arm.period)
        if not 0.0 <= early_s < dt:
            raise InvalidInput(f"early_s must be in [0, {dt}) s, got {early_s}", value=early_s)
        if not 0.0 < poll_s <= dt:
            raise InvalidInput(f"poll_s must be in (0, {dt}] s, got {poll_s}", value=poll_s)
        self.arm, self.period, self.early_s, self.poll_s = arm, dt, float(early_s), float(poll_s)
        self.on_ticks = bool(arm.paced and getattr(arm, "clocked", False))
        self.cycles = self.stale = 0
        self._t0 = self._wake = -1.0
        self._t_prev = float("-inf")

    def next(self) -> RobotState:
        """Wait for this cycle's start and return the state it answers.

        Unpaced backend: the state at once. Paced, not clocked: the state at ``t0 + k * period``
        (``t0``: the first call). Clocked: the first state whose time is past the last cycle's, polled
        from :attr:`early_s` before it is due (at most :data:`WAIT_PERIODS` periods, then the newest).
        """
        arm, k = self.arm, self.cycles
        self.cycles += 1
        if not arm.paced:
            return arm.state()  # type: ignore[no-any-return]
        now = time.perf_counter()
        if self._t0 < 0:
            self._t0 = self._wake = now
        if not self.on_ticks:
            sleep_until(self._t0 + k * self.period)
            return arm.state()  # type: ignore[no-any-return]
        sleep_until(self._wake)
        deadline = time.perf_counter() + WAIT_PERIODS * self.period
        st: RobotState = arm.state()
        while st.t <= self._t_prev and time.perf_counter() < deadline:
            time.sleep(self.poll_s)
            st = arm.state()
        if st.t <= self._t_prev:
            st = arm.state()  # once more after the bound: this thread may have been off the CPU past it
            self.stale += int(st.t <= self._t_prev)
        self._t_prev = st.t
        self._wake = time.perf_counter() + self.period - self.early_s
        return st
