"""The force loop's pacing at the robot's ticks (``TickPacer``): fakes, no timing asserted."""
import time

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.interface.state import RobotMode, RobotState
from robointel.interface.tick_pacer import TickPacer


class _Arm:
    """A robot whose state advances at its own ticks (wall clock), or never (``frozen``)."""

    period = 0.008

    def __init__(self, *, paced=True, clocked=True, frozen=False):
        self.paced, self.clocked, self.frozen = paced, clocked, frozen
        self.t0, self.reads = time.perf_counter(), 0

    def state(self):
        self.reads += 1
        tick = 0 if self.frozen else int((time.perf_counter() - self.t0) / self.period)
        return RobotState(t=tick * self.period, q=np.zeros(6), qd=np.zeros(6), wrench=None, mode=RobotMode.IDLE)


def test_each_cycle_answers_a_newer_state_on_a_clocked_robot():
    pacer = TickPacer(_Arm())
    ts = [pacer.next().t for _ in range(12)]
    assert all(b > a for a, b in zip(ts, ts[1:], strict=False))  # never the same tick twice
    assert pacer.cycles == 12 and pacer.stale == 0 and pacer.on_ticks


def test_a_robot_that_stops_ticking_does_not_block_the_loop():
    arm = _Arm(frozen=True)
    pacer = TickPacer(arm)
    for _ in range(3):
        assert pacer.next().t == 0.0
    assert pacer.stale == 2  # the first read is new; the next two waited their bound and went on
    assert arm.reads > 3  # it polled for a newer state


def test_an_unclocked_or_unpaced_robot_keeps_the_callers_clock():
    unpaced = _Arm(paced=False, frozen=True)
    pacer = TickPacer(unpaced)
    for _ in range(5):
        pacer.next()
    assert unpaced.reads == 5 and pacer.stale == 0 and not pacer.on_ticks  # one read per cycle, no polling
    stepped = _Arm(clocked=False, frozen=True)  # the in-process paced sim: its state moves when commanded
    pacer = TickPacer(stepped)
    for _ in range(3):
        pacer.next()
    assert stepped.reads == 3 and pacer.stale == 0


@pytest.mark.parametrize("kw", [{"early_s": -0.001}, {"early_s": 0.008}, {"poll_s": 0.0}, {"poll_s": 0.01}])
def test_bad_pacing_is_refused(kw):
    with pytest.raises(InvalidInput):
        TickPacer(_Arm(), **kw)
