"""The streaming process's state block as the caller reads it: field offsets, the snapshot, the quiet check.

The streaming process (:mod:`robointel.interface.stream_child`) publishes the core's snapshot and its
counters into a seqlock block of shared memory; :meth:`StreamProcess.values
<robointel.interface.stream_process.StreamProcess.values>` copies it out as a list of floats. This
module says where each field sits in that list, turns it into the ``core.get_snapshot()`` dict
``FanucRobot`` reads (:func:`snapshot`), and answers the one question the per-target path asks
(:func:`quiet`: may a target go out?) from a few of its fields, without building that dict.
"""
from __future__ import annotations

import operator
from collections.abc import Sequence
from typing import Any

from robointel.interface import stream_layout as layout

R = {name: sl.start - layout.S_OFF for name, sl in layout.STATE_INDEX.items()}
"""Offset of each state field in the list :meth:`StreamProcess.values` returns."""
FLAG_KEYS = ("e_stopped", "in_error", "tp_enabled", "motion_possible", "wrench_valid", "stalled", "refused")
INT_KEYS = ("mode", "fault", "cmd_tick", "active_motion_id", "active_motion_status")
WRENCH_KEYS = ("fx", "fy", "fz", "mx", "my", "mz")
_FLAG_GET = operator.itemgetter(*(R[k] for k in FLAG_KEYS))
_INT_GET = operator.itemgetter(*(R[k] for k in INT_KEYS))
RX, TICK, STALL_GAP, PUBLISHED, RUNNING = R["rx_s"], R["tick_s"], R["stall_gap_s"], R["published_s"], R["running"]
QM, QD, QC, WR = R["q_meas"], R["qd_est"], R["q_cmd"], R["wrench"]
WRENCH_VALID = R["wrench_valid"]
_E_STOPPED, _IN_ERROR, _TP, _MOTION = R["e_stopped"], R["in_error"], R["tp_enabled"], R["motion_possible"]
_FAULT, _STALLED, _REFUSED = R["fault"], R["stalled"], R["refused"]
HEAD = max(R[k] + (layout.NDOF if k in ("q_meas", "qd_est", "q_cmd", "wrench") else 1)
           for k in (*FLAG_KEYS, *INT_KEYS, "rx_s", "tick_s", "stall_gap_s", "published_s", "running",
                     "q_meas", "qd_est", "q_cmd", "wrench"))
"""The leading fields of the block that :func:`snapshot` and :func:`quiet` read (``StreamProcess.head``)."""


def snapshot(v: Sequence[float], base_ns: int, now_ns: int) -> dict[str, Any]:
    """The core's snapshot (the keys of ``FanucDriver.core.get_snapshot()`` that ``FanucRobot`` reads).

    Args:
        v: the state block as :meth:`StreamProcess.values` returns it (or its first :data:`HEAD` fields).
        base_ns: CLOCK_MONOTONIC origin of the block's times, ns.
        now_ns: CLOCK_MONOTONIC time of the read, ns (``rx_age_ms`` is the status's age then).

    Returns:
        The flags as bools, the integer fields as ints, ``rx_mono_ns``/``tick_mono_ns``, ``rx_age_ms``, the
        (6,) ``q_meas``/``qd_est``/``q_cmd`` lists, ``fx``..``mz`` and ``stall_gap_s``.
    """
    snap: dict[str, Any] = dict(zip(FLAG_KEYS, map(bool, _FLAG_GET(v)), strict=True))
    snap.update(zip(INT_KEYS, map(int, _INT_GET(v)), strict=True))
    rx_ns = base_ns + int(v[RX] * 1e9)
    snap["rx_mono_ns"] = rx_ns
    snap["tick_mono_ns"] = base_ns + int(v[TICK] * 1e9)
    snap["rx_age_ms"] = (now_ns - rx_ns) * 1e-6
    snap["q_meas"], snap["qd_est"], snap["q_cmd"] = (list(v[QM:QM + layout.NDOF]), list(v[QD:QD + layout.NDOF]),
                                                       list(v[QC:QC + layout.NDOF]))
    snap.update(zip(WRENCH_KEYS, v[WR:WR + layout.NDOF], strict=True))
    snap["stall_gap_s"] = v[STALL_GAP]
    return snap


def quiet(v: Sequence[float], base_ns: int, now_ns: int, stale_ms: float) -> bool:
    """True when the block shows nothing that stops commanding: the per-target fault check's fast answer.

    Quiet means: the core runs, the last status is at most ``stale_ms`` old, no fault reason, no
    e-stop, alarm or enabled teach pendant, motion possible, no refused motion and no stall stop. A
    check on the snapshot (``FanucRobot._fault_of``) finds no fault exactly when all of these hold
    (that the child process itself runs is the caller's to check), so a quiet block needs no more
    work and any other goes through that check, which names the cause.

    Args:
        v: the state block as :meth:`StreamProcess.values` returns it (or its first :data:`HEAD` fields).
        base_ns: CLOCK_MONOTONIC origin of the block's times, ns.
        now_ns: CLOCK_MONOTONIC time of the read, ns.
        stale_ms: a status older than this is a lost connection, ms.
    """
    return bool(v[RUNNING] and v[_FAULT] == 0.0 and v[_MOTION] and not (v[_E_STOPPED] or v[_IN_ERROR] or v[_TP]
                                                                        or v[_REFUSED] or v[_STALLED])
                and (now_ns - base_ns - int(v[RX] * 1e9)) * 1e-6 <= stale_ms)
