"""The streaming server's message handling under arbitrary messages: an error reply or an accepted
message, never another exception, and a target reaches the controller only when it is six finite
numbers within the joint limits (a pose: a finite position and unit quaternion or rotation)."""
from __future__ import annotations

import json
import time

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robointel.teach.stream_protocol import MESSAGE_TYPES, Rejected
from robointel.teach.stream_session import Session
from robointel.teach.streaming import StreamingController, StreamingServer

from .conftest import SCALARS, VALUES, finite

KEYS = ("type", "q", "t", "seq", "ack", "position", "quaternion", "rotation", "token")


@pytest.fixture(scope="module")
def rig(lrmate):
    ctrl = StreamingController(lrmate, realtime=False, deadman=5.0)  # never stepped: nothing can move
    srv = StreamingServer(ctrl, port=0)
    c = Session("fuzz", None, authed=True)
    ctrl.acquire(c.id)
    return srv, ctrl, c


def _message():
    numbers6 = st.lists(st.one_of(st.floats(-4, 4), SCALARS), min_size=5, max_size=7)
    value = st.one_of(VALUES, numbers6, st.just(time.perf_counter()))
    typ = st.one_of(st.sampled_from(MESSAGE_TYPES), SCALARS)
    return st.dictionaries(st.sampled_from(KEYS), value, max_size=6).flatmap(
        lambda d: typ.map(lambda t: {**d, "type": t}) if "type" in d else st.just(d))


def _valid_joint_target(msg, lrmate) -> bool:
    q = msg.get("q")
    return (isinstance(q, list) and len(q) == 6 and all(finite(v) for v in q)
            and bool(np.all((np.array(q, float) >= lrmate.lower) & (np.array(q, float) <= lrmate.upper))))


@given(raw=st.one_of(_message().map(lambda m: json.dumps(m, allow_nan=True, default=str)),
                     st.text(max_size=200), st.binary(max_size=64)))
def test_any_message_is_answered_or_refused_never_raises(rig, lrmate, raw):
    srv, ctrl, c = rig
    before = ctrl._pending
    c.slot = None
    msg = srv._parse(raw)
    try:
        if msg is not srv._parse.__globals__["_BAD"]:
            srv._dispatch(c, msg, time.perf_counter())
    except Rejected as exc:
        assert exc.code and str(exc)
    if c.slot is not None:                               # the worker's part (IK, limits, collision)
        kind, payload = c.slot[0], np.asarray(c.slot[1])
        assert kind in ("joint_target", "pose_target") and np.all(np.isfinite(payload))
        try:
            srv._heavy(c.id, c.slot)
        except Rejected as exc:
            assert exc.code and str(exc)
    if ctrl._pending is not before:                      # a target reached the controller: a valid one
        assert isinstance(msg, dict) and msg.get("type") in ("joint_target", "pose_target")
        if msg["type"] == "joint_target":
            assert _valid_joint_target(msg, lrmate)
        q = ctrl._pending.q
        assert np.all(np.isfinite(q)) and np.all((q >= lrmate.lower) & (q <= lrmate.upper))
    ctrl.latched = False
    if ctrl.owner != c.id:
        ctrl.acquire(c.id)
