"""The per-target fault check's fast answer (stream_state.quiet) agrees with the snapshot check it skips."""
from types import SimpleNamespace

import numpy as np

from robointel.interface import stream_layout as layout
from robointel.interface import stream_state as ss
from robointel.interface.fanuc import FanucRobot

BASE_NS = 1_000_000_000
PERIOD = 0.008


class _Core:
    def __init__(self, running):
        self.running = running


class _Driver:
    """The two things the snapshot check reads from the streaming process besides the block."""

    def __init__(self, running, alive=True):
        self.core, self.base_ns, self._alive = _Core(running), BASE_NS, alive

    def alive(self):
        return self._alive


def _robot(v, now_ns, running, alive=True):
    """A FanucRobot shell holding block ``v`` as read at ``now_ns`` (no controller behind it)."""
    r = FanucRobot.__new__(FanucRobot)
    r.driver = _Driver(running, alive)
    r.gate, r.stall_periods, r._stall_extra_s = SimpleNamespace(period=PERIOD), 10, 0.1  # r.period reads the gate's
    r._stale_ms = 12 * PERIOD * 1e3
    r._vals, r._snap_d, r._read_ns = v, None, now_ns
    return r


def _block(rng):
    v = [0.0] * ss.HEAD
    now_s = 5.0
    v[ss.RX] = now_s - rng.choice([0.001, 0.05, 0.0959, 0.0961, 0.5])  # around the 96 ms stale limit
    v[ss.R["published_s"]] = now_s - 0.001
    v[ss.RUNNING] = float(rng.random() < 0.9)
    for k in ("e_stopped", "in_error", "tp_enabled", "refused", "stalled", "wrench_valid"):
        v[ss.R[k]] = float(rng.random() < 0.1)
    v[ss.R["motion_possible"]] = float(rng.random() < 0.9)
    v[ss.R["fault"]] = float(rng.choice([0, 0, 0, 0, 1, 2, 3, 7, 9]))
    v[ss.QM:ss.QM + layout.NDOF] = rng.normal(size=layout.NDOF).tolist()
    return v, BASE_NS + int(now_s * 1e9)


def test_quiet_holds_exactly_when_the_snapshot_check_finds_no_fault():
    rng = np.random.default_rng(25)
    quiet_n = fault_n = 0
    for _ in range(2000):
        v, now_ns = _block(rng)
        running = bool(v[ss.RUNNING])  # the live flag, as the child last published it
        slow = _robot(v, now_ns, running)
        slow._vals, slow._snap_d = None, ss.snapshot(v, BASE_NS, now_ns)  # the snapshot path only
        expected = slow._fault_of(None)
        assert ss.quiet(v, BASE_NS, now_ns, slow._stale_ms) == (expected is None), (v, expected)
        assert _robot(v, now_ns, running)._fault_of(None) == expected  # the fast path changes no answer
        quiet_n += expected is None
        fault_n += expected is not None
    assert quiet_n > 250 and fault_n > 250


def test_a_quiet_block_of_a_dead_streaming_process_is_a_lost_connection():
    rng = np.random.default_rng(1)
    while True:
        v, now_ns = _block(rng)
        if ss.quiet(v, BASE_NS, now_ns, 96.0):
            break
    mode, why, faults = _robot(v, now_ns, running=False, alive=False)._fault_of(None)
    assert faults == ("disconnected",) and "connection lost" in why


def test_the_snapshot_from_the_head_reads_as_the_full_blocks():
    rng = np.random.default_rng(2)
    full = rng.uniform(0, 3, size=layout.RING_OFF - layout.S_OFF).round().tolist()  # every field of the block
    a = ss.snapshot(full, BASE_NS, BASE_NS + 10**9)
    b = ss.snapshot(tuple(full[:ss.HEAD]), BASE_NS, BASE_NS + 10**9)
    assert a == b and a["q_meas"] == full[ss.QM:ss.QM + layout.NDOF]
