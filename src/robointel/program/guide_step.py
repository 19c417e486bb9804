"""The ``guide`` step: the robot is handed to the operator for lead-through until they press continue.

Lead-through is :func:`robointel.teach.lead_through.lead_through` on the cell's robot interface:
the measured F/T wrench drives the guidance controller (compliance (3.10)-(3.13) with collision
avoidance (4.11) around the scene's obstacles) into streamed joint position targets. The step ends when
the operator presses continue (the robot then holds), or fails at its timeout (the robot holds where it
is). The guided path is kept, so teaching can turn it into a ``path`` step
(:func:`robointel.program.teaching.path_step_from_guided`).

In simulation the operator is scripted: :class:`PushOperator` pushes the tool with a hand force, lets
go, and presses continue once the arm has come to rest.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from robointel.interface.backend import Backend
from robointel.outcome import Failure, TrialOutcome
from robointel.sim import Workcell
from robointel.teach.guidance import GuidanceConfig, GuidanceController
from robointel.teach.lead_through import LeadThroughResult, lead_through


class Operator(Protocol):
    """The person at the robot during a ``guide`` step."""

    def __call__(self, cycle: int, q: npt.NDArray[np.float64]) -> bool:
        """Act on the world for controller cycle ``cycle`` (the arm at ``q``); return True to press continue."""
        ...


@dataclass
class PushOperator:
    """A scripted operator: push the TCP with ``force`` for ``push_s``, let go, press continue after ``rest_s``.

    Attributes:
        workcell: The simulated workcell the hand acts on (None: the cell applies :meth:`force` itself).
        force_n: (3,) hand force at the TCP in world axes, N.
        push_s: How long the hand pushes, s.
        rest_s: How long after letting go the operator presses continue, s.
        period: The controller period, s.
    """

    workcell: Workcell | None = None
    force_n: tuple[float, float, float] = (0.0, 20.0, 0.0)
    push_s: float = 0.5
    rest_s: float = 0.4
    period: float = 0.008

    def force(self, cycle: int) -> npt.NDArray[np.float64]:
        """(3,) the hand's force at the TCP during ``cycle``, N (world axes)."""
        return np.asarray(self.force_n, float) if cycle * self.period < self.push_s else np.zeros(3)

    def pressed(self, cycle: int) -> bool:
        """Whether continue is pressed at ``cycle``."""
        return cycle * self.period >= self.push_s + self.rest_s

    def __call__(self, cycle: int, q: npt.NDArray[np.float64]) -> bool:
        """Push on the workcell's TCP, release, then press continue (see the class docstring)."""
        assert self.workcell is not None
        f = self.force(cycle)
        if np.any(f):
            self.workcell.apply_wrench(f.tolist(), point=self.workcell.robot.fk(q)[:3, 3])
        else:
            self.workcell.clear_wrench()
        return self.pressed(cycle)


def guide_with_hand(robot: Any, operator: PushOperator, *, timeout: float, period: float,
                    read_q: Callable[[], npt.NDArray[np.float64]],
                    step: Callable[[npt.NDArray[np.float64], npt.NDArray[np.float64]], str | None],
                    obstacles: Sequence[Any] = ()) -> GuideResult:
    """Lead-through on a cell whose hand force is known (a simulated, ideal F/T reading of the operator's push).

    Each period the guidance controller (3.10)-(3.13) with collision avoidance (4.11) maps the hand's
    wrench at the TCP to a joint velocity, integrated into the next joint position target.

    Args:
        robot: The arm's :class:`robointel.robot.Robot` (its tool frame is the TCP).
        operator: The scripted operator (:meth:`PushOperator.force`, :meth:`PushOperator.pressed`).
        timeout: Longest guidance, s.
        period: Controller period, s.
        read_q: Returns the measured joints (n,), rad.
        step: Applies the hand force (3,) N at the TCP, sends the target (n,) rad and runs one period;
            returns why the cell stopped (a contact), or None.
        obstacles: Obstacles the guidance avoids (world frame).

    Returns:
        The :class:`GuideResult`.
    """
    ctl = GuidanceController(robot, obstacles, GuidanceConfig(dt=period))
    q_cmd = read_q()
    Q: list[npt.NDArray[np.float64]] = []
    D: list[float] = []
    W: list[npt.NDArray[np.float64]] = []
    outcome = TrialOutcome(False, Failure.TIMEOUT, f"the operator did not press continue within {timeout:.1f} s")
    for k in range(int(round(timeout / period))):
        q = read_q()
        if operator.pressed(k):
            outcome = TrialOutcome(True, figures={"guided_s": k * period,
                                                  "min_distance_m": float(min(D)) if D else float("inf")})
            break
        f = operator.force(k)
        w = np.r_[f, 0.0, 0.0, 0.0]
        s = ctl.step(q, w)
        q_cmd = np.clip(q_cmd + s.qd * period, robot.lower, robot.upper)
        Q.append(q)
        D.append(float(s.distance))
        W.append(w)
        why = step(q_cmd, f)
        if why is not None:
            outcome = TrialOutcome(False, Failure.COLLISION, why)
            break
    n = len(Q)
    Qa = np.array(Q).reshape(n, -1)
    lead = LeadThroughResult(np.arange(n, dtype=float) * period, Qa, Qa.copy(), np.array(W).reshape(n, 6), np.array(D),
                             np.zeros(n, dtype=bool))
    return GuideResult(outcome, lead)


class _Continue(Exception):
    """The operator pressed continue."""


@dataclass
class GuideResult:
    """What a ``guide`` step did.

    Attributes:
        outcome: Success when the operator pressed continue before the timeout.
        lead: The lead-through record (joints, targets, wrenches, obstacle distances), cut at continue.
    """

    outcome: TrialOutcome
    lead: LeadThroughResult


def run_guide(arm: Backend, robot: Any, operator: Operator, *, timeout: float, obstacles: Sequence[Any] = (),
              on_cycle: Callable[[int], None] | None = None) -> GuideResult:
    """Hand the robot to the operator until they press continue (or ``timeout`` s pass).

    Args:
        arm: The robot interface (its state must carry the F/T wrench).
        robot: The :class:`robointel.robot.Robot` of the arm.
        operator: The operator (a person's input, or a scripted one in simulation).
        timeout: Longest guidance, s.
        obstacles: Obstacles the guidance keeps the arm away from (world frame).
        on_cycle: Called with each cycle index (progress).

    Returns:
        The :class:`GuideResult`; the robot holds where it is in every case.

    Raises:
        InvalidInput: The robot reports no F/T wrench.
    """
    pressed = [False]
    log_t: list[float] = []
    log_q: list[npt.NDArray[np.float64]] = []
    log_d: list[float] = []

    def world(k: int) -> None:
        if operator(k, arm.state().q):
            pressed[0] = True

    def cycle(k: int, s: Any) -> None:
        st = arm.state()
        log_t.append(float(st.t))
        log_q.append(np.asarray(st.q, float).copy())
        log_d.append(float(s.distance))
        if on_cycle is not None:
            on_cycle(k)
        if pressed[0]:
            raise _Continue

    try:
        lead = lead_through(arm, robot, timeout, obstacles=obstacles, step_world=world, on_cycle=cycle)
    except _Continue:
        n = len(log_q)
        Q = np.array(log_q).reshape(n, -1)
        lead = LeadThroughResult(np.array(log_t), Q, Q.copy(), np.zeros((n, 6)), np.array(log_d),
                                 np.zeros(n, dtype=bool))
        figures = {"guided_s": n * arm.period, "min_distance_m": float(np.min(log_d)) if log_d else float("inf")}
        return GuideResult(TrialOutcome(True, figures=figures), lead)
    return GuideResult(TrialOutcome(False, Failure.TIMEOUT, f"the operator did not press continue within "
                                    f"{timeout:.1f} s"), lead)
