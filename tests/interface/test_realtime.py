"""The streaming thread's real-time section and wait (robointel.interface.realtime)."""
import gc
import os
import sys
import threading
import time

import pytest

from robointel.errors import InvalidInput
from robointel.interface.realtime import realtime_thread, sleep_until


def test_sleep_until_never_returns_before_the_deadline():
    for dt in (0.0, 0.0001, 0.002, 0.011):
        deadline = time.perf_counter() + dt
        sleep_until(deadline)
        assert time.perf_counter() >= deadline


def test_realtime_section_freezes_the_heap_and_restores_everything():
    old_switch, old_policy = sys.getswitchinterval(), os.sched_getscheduler(0)
    keep = [object() for _ in range(100)]  # noqa: F841  (part of the heap to freeze)
    with realtime_thread(30, switch_interval=0.001) as st:
        assert sys.getswitchinterval() == pytest.approx(0.001)
        assert st.gc_frozen > 0 and gc.get_freeze_count() > 0
        if st.policy == "SCHED_FIFO":  # granted where the process may (CAP_SYS_NICE)
            assert os.sched_getscheduler(0) == os.SCHED_FIFO and st.priority == 30
        else:
            assert st.priority == 0
    assert sys.getswitchinterval() == pytest.approx(old_switch)
    assert os.sched_getscheduler(0) == old_policy
    assert gc.get_freeze_count() == 0


def test_realtime_section_in_a_thread_leaves_the_others_alone():
    seen = {}

    def run():
        with realtime_thread(20) as st:
            seen["inside"] = (st.policy, os.sched_getscheduler(0))

    before = os.sched_getscheduler(0)
    th = threading.Thread(target=run)
    th.start()
    th.join(timeout=30)
    assert "inside" in seen
    assert os.sched_getscheduler(0) == before  # the calling thread's policy is per thread


@pytest.mark.parametrize("kw", [{"priority": 0}, {"priority": 99}, {"switch_interval": 0.0},
                                {"switch_interval": 1.0}])
def test_bad_settings_are_refused(kw):
    args = {"priority": 40, **kw}
    with pytest.raises(InvalidInput), realtime_thread(args.pop("priority"), **args):
        pass
