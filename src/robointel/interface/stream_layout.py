"""The shared memory between a caller and its streaming process: a header, the seqlock state block, the ring.

One array of :data:`SHM_DOUBLES` float64 (:data:`SHM_BYTES` bytes, a ``memfd``): the header (counts
the caller and the streaming process write, ``H_*``), then the state block the streaming process
publishes under a seqlock (:data:`STATE_FIELDS`, placed by :data:`STATE_INDEX`), then the ring of
:data:`RING` targets the caller writes (:data:`SLOT_WIDTH` doubles each, from :data:`RING_OFF`).
Both ends import this module: the caller (:mod:`robointel.interface.stream_ring`) and the streaming
process (:mod:`robointel.interface.stream_child`, :mod:`robointel.interface.sim_child`). It imports
nothing.
"""
from __future__ import annotations

NDOF = 6
"""Joints of a target."""
RING = 1024
"""Ring capacity, targets (8.2 s at 8 ms)."""
H_WRITE, H_CUT, H_HOLD, H_READ, H_VERSION, H_HOLD_GEN = 0, 1, 2, 3, 4, 5
"""Header: targets written, discard below (on stop), written at the last hold (caller); consumed,
seqlock version (child); holds asked (caller)."""
STATE_FIELDS: tuple[tuple[str, int], ...] = (
    ("published_s", 1), ("rx_s", 1), ("tick_s", 1), ("cmd_tick", 1), ("mode", 1), ("fault", 1),
    ("e_stopped", 1), ("in_error", 1), ("tp_enabled", 1), ("motion_possible", 1), ("wrench_valid", 1),
    ("running", 1), ("active_motion_id", 1), ("active_motion_status", 1),
    ("q_meas", NDOF), ("qd_est", NDOF), ("q_cmd", NDOF), ("wrench", NDOF),
    ("stalled", 1), ("stall_gap_s", 1), ("refused", 1),
    ("windows", 1), ("fresh", 1), ("starved", 1), ("late", 1), ("submits", 1), ("last_submit_s", 1),
    ("core_late", 1), ("direct_submits", 1), ("direct_latency_max_s", 1), ("direct_latency_sum_s", 1),
    ("gc_max_s", 1), ("holds", 1),
)
"""The state block: name and length. Times are seconds after the session's base (CLOCK_MONOTONIC)."""
S_OFF = 8
"""Where the state block starts (after the header), doubles."""
STATE_INDEX: dict[str, slice] = {}
_o = S_OFF
for _name, _n in STATE_FIELDS:
    STATE_INDEX[_name], _o = slice(_o, _o + _n), _o + _n
RING_OFF = _o
SLOT_WIDTH = 2 + NDOF
"""A ring slot: play time, arrival time (s after the base), the (6,) target in rad."""
SHM_DOUBLES = RING_OFF + RING * SLOT_WIDTH
SHM_BYTES = SHM_DOUBLES * 8
