"""Sessions of the streaming server against real WebSocket clients on 127.0.0.1: unauthenticated
connections hold no slot and time out, the deadman holds whatever the client's clock does, a JSON
``null`` gets an error reply."""
from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np
import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from robointel.teach.stream_client import StreamClient
from robointel.teach.stream_session import MAX_PENDING, Gatekeeper, Session
from robointel.teach.streaming import StreamingController, StreamingServer

TOKEN = "s3cret-token-0123456789"
READY = [0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0]
LEFT = [-2.5, 0.0, 0.0, 0.0, -np.pi / 2, 0.0]


@pytest.fixture()
def server(lrmate):
    srv = StreamingServer(StreamingController(lrmate), port=0, token=TOKEN, max_clients=2).start()
    yield srv
    srv.stop()


def test_idle_unauthenticated_connections_hold_no_slot_and_are_closed(server):
    idle = [connect(server.url) for _ in range(8)]      # 4x the session slots, none authenticates
    try:
        for ws in idle:
            assert json.loads(ws.recv(timeout=5)) == {"type": "welcome", "protocol": 2, "auth": True}
        t0 = time.monotonic()
        with StreamClient(server.url, token=TOKEN) as op:  # the operator still gets a session ...
            assert op.request({"type": "stop"}, "ok")["latched"] is True  # ... and its stop gets through
            waited = time.monotonic() - t0
            assert waited < 2.0
            closed = 0
            for ws in idle:                              # the idle ones are closed after ~2 s
                try:
                    msg = json.loads(ws.recv(timeout=5))
                    assert msg["code"] == "unauthorized" and "within 2 s" in msg["message"]
                    ws.recv(timeout=5)
                except ConnectionClosed:
                    closed += 1
            assert closed == len(idle) and time.monotonic() - t0 < 6.0
            assert server.gate.timeouts == len(idle)
            assert op.state()["latched"] is True        # the operator's session stays
    finally:
        for ws in idle:
            ws.close()


def test_oldest_pending_connection_makes_room():
    gate = Gatekeeper(TOKEN)
    sessions = [Session(f"c{i}", None, authed=False, opened=float(i)) for i in range(MAX_PENDING + 3)]
    out = [gate.admit_pending(s) for s in sessions]
    assert out[:MAX_PENDING] == [None] * MAX_PENDING
    assert [s.id for s in out[MAX_PENDING:]] == ["c0", "c1", "c2"]
    assert len(gate.pending) == MAX_PENDING and gate.evicted == 3


def test_json_null_and_scalars_get_an_error_reply(server):
    with StreamClient(server.url, token=TOKEN) as c:
        for raw in ("null", "7", '"stop"', "[]"):
            c.send_raw(raw)
            err = c.recv("error")
            assert err["code"] == "malformed", raw
        assert c.state()["type"] == "state"


def _stream(c: StreamClient, q, seconds: float, clock: float, period: float = 0.01) -> list[dict]:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        c.send({"type": "joint_target", "q": list(q), "t": time.perf_counter() * clock})
        time.sleep(period)
    out = list(c.seen)
    try:
        while True:
            out.append(c.recv(timeout=0.3))
    except TimeoutError:
        pass
    return out


def test_a_fast_client_clock_is_refused_and_stops_the_arm(lrmate):
    srv = StreamingServer(StreamingController(lrmate), port=0).start()
    try:
        with StreamClient(srv.url) as c:
            c.acquire()
            replies = _stream(c, LEFT, 0.5, clock=1000.0)   # milliseconds where seconds are expected
            codes = [m["code"] for m in replies if m["type"] == "error"]
            assert codes and set(codes) == {"clock_rate"}
            assert "seconds" in next(m["message"] for m in replies if m["type"] == "error")
            assert srv.controller.accepted <= 3              # refused from the first messages on
            s = c.state()
            assert s["mode"] in ("idle", "stopped") and abs(s["q"][0]) < 0.05
            replies = _stream(c, READY, 0.1, clock=1.0)     # refused for good on this connection
            assert {m["code"] for m in replies if m["type"] == "error"} == {"clock_rate"}
        with StreamClient(srv.url) as c:                     # a new connection with a clock in seconds works
            c.acquire()
            assert not [m for m in _stream(c, READY, 0.3, clock=1.0) if m["type"] == "error"]
    finally:
        srv.stop()


def test_a_slow_client_clock_is_stale_and_named(lrmate):
    srv = StreamingServer(StreamingController(lrmate), port=0).start()
    try:
        with StreamClient(srv.url) as c:
            c.acquire()
            replies = _stream(c, LEFT, 1.4, clock=0.001)
            codes = [m["code"] for m in replies if m["type"] == "error"]
            assert set(codes) <= {"stale", "clock_rate"} and "clock_rate" in codes
            assert srv.controller.accepted <= 20             # only within the first deadman
            s = c.state()
            assert s["mode"] == "stopped" and s["q"][0] > -0.5
    finally:
        srv.stop()


@pytest.mark.parametrize("clock", [1000.0, 0.001])
def test_deadman_holds_after_a_flood_whatever_the_clock(lrmate, clock):
    """A flooding client (its own process) with a clock 1000x fast or slow: the arm stops within
    0.25 s of its last send."""
    srv = StreamingServer(StreamingController(lrmate), port=0).start()
    try:
        p = subprocess.Popen([sys.executable, "-m", "robointel.teach.stream_client", srv.url,
                              "command", "0.4", "0.3", str(clock)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             text=True)
        assert p.stdout.readline().strip() == "ready"
        p.stdin.write("go\n")
        p.stdin.flush()
        last = json.loads(p.stdout.readline())["last_send"]
        p.wait(timeout=20)
        ctrl = srv.controller
        assert ctrl.mode in ("idle", "stopped")
        if ctrl.stop_began is not None:
            assert ctrl.stop_began - last <= 0.25
        assert abs(ctrl.wc.q[0]) < 0.3                     # the flood's target (J1 = 2.5 rad) was never followed
    finally:
        srv.stop()
