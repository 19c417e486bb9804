"""Streaming interface over a real WebSocket on 127.0.0.1: validation, deadman, binding rules."""
from __future__ import annotations

import json
import time

import numpy as np
import pytest
from websockets.sync.client import connect

from robointel.errors import InvalidInput
from robointel.programming.streaming import StreamingController, StreamingServer, check_bind

READY = [0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0]


@pytest.fixture(scope="module")
def server(lrmate):
    srv = StreamingServer(StreamingController(lrmate), port=0).start()
    yield srv
    srv.stop()


def _recv(ws, typ, timeout=5.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        m = json.loads(ws.recv(timeout=max(0.01, end - time.monotonic())))
        if m["type"] == typ:
            return m
    raise TimeoutError(typ)


def _state(ws):
    ws.send(json.dumps({"type": "get_state"}))
    return _recv(ws, "state")


def test_welcome_and_tracking(server):
    with connect(server.url) as ws:
        w = json.loads(ws.recv(timeout=5))
        assert w["type"] == "welcome" and w["robot"] == "lrmate200id7l" and w["deadman"] == 0.1
        goal = [0.2, 0.1, -0.1, 0.0, -1.4, 0.3]
        for k in range(150):  # stream the same goal at ~100 Hz for 1.5 s
            ws.send(json.dumps({"type": "joint_target", "q": goal, "seq": k}))
            time.sleep(0.01)
        s = _state(ws)
        np.testing.assert_allclose(s["q"], goal, atol=2e-3)
        assert s["mode"] == "tracking"


@pytest.mark.parametrize("raw, code", [
    ("{not json", "malformed"),
    ("[1, 2, 3]", "malformed"),
    ('{"q": [0, 0, 0, 0, 0, 0]}', "malformed"),
    ('{"type": "fly"}', "unknown_type"),
    ('{"type": "joint_target", "q": [0, 0, 0]}', "bad_shape"),
    ('{"type": "joint_target", "q": [0, 0, "a", 0, 0, 0]}', "bad_shape"),
    ('{"type": "joint_target", "q": [0, 0, NaN, 0, 0, 0]}', "not_finite"),
    ('{"type": "joint_target", "q": [0, 0, Infinity, 0, 0, 0]}', "not_finite"),
    ('{"type": "joint_target", "q": [4.0, 0, 0, 0, 0, 0]}', "out_of_limits"),
    ('{"type": "pose_target", "position": [3.0, 0, 0.3], "quaternion": [0.7071068, 0, 0.7071068, 0]}', "unreachable"),
    ('{"type": "pose_target", "position": [0.4, 0, 0.3], "quaternion": [3, 0, 0, 0]}', "bad_shape"),
])
def test_bad_messages_get_error_and_never_reach_robot(server, raw, code):
    with connect(server.url) as ws:
        ws.recv(timeout=5)
        before = server.controller.accepted
        tgt = server.controller.state()["target"]
        ws.send(raw)
        err = _recv(ws, "error")
        assert err["code"] == code and err["message"]
        assert server.controller.accepted == before
        assert server.controller.state()["target"] == tgt


def test_pose_target_reaches_pose(server, lrmate):
    T = lrmate.fk(np.array([0.3, 0.2, -0.2, 0.1, -1.2, 0.2]))
    from scipy.spatial.transform import Rotation
    x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
    with connect(server.url) as ws:
        ws.recv(timeout=5)
        for _ in range(150):
            ws.send(json.dumps({"type": "pose_target", "position": T[:3, 3].tolist(), "quaternion": [w, x, y, z]}))
            time.sleep(0.01)
        s = _state(ws)
    np.testing.assert_allclose(lrmate.fk(np.array(s["q"]))[:3, 3], T[:3, 3], atol=2e-3)


def test_stalled_stream_decelerates_to_stop(server):
    with connect(server.url) as ws:
        ws.recv(timeout=5)
        start = [-2.5, 0.0, 0.0, 0.0, -np.pi / 2, 0.0]
        for _ in range(150):  # settle at one end of J1's range
            ws.send(json.dumps({"type": "joint_target", "q": start}))
            time.sleep(0.01)
        far = [2.5, 0.0, 0.0, 0.0, -np.pi / 2, 0.0]
        for _ in range(20):  # stream the other end for 0.2 s: the robot is moving fast
            ws.send(json.dumps({"type": "joint_target", "q": far}))
            time.sleep(0.01)
        wc = server.controller.wc
        speeds, t0 = [], time.monotonic()
        while time.monotonic() - t0 < 1.0:  # the stream has stalled
            speeds.append(abs(wc.qd[0]))
            time.sleep(0.01)
        s = _state(ws)
    assert max(speeds[:5]) > 1.0                       # it was moving when the stream stopped
    assert s["mode"] == "stopped" and abs(s["qd"][0]) < 1e-2
    assert s["q"][0] < 2.0                             # stopped well short of the far goal
    # deceleration, no re-acceleration: the speed never rises by more than noise after its peak
    k = int(np.argmax(speeds))
    assert np.all(np.diff(speeds[k:]) < 0.05)


def test_remote_bind_without_token_refused():
    for host in ("0.0.0.0", "192.168.1.10", "::"):
        with pytest.raises(InvalidInput, match="token"):
            check_bind(host, None)
        with pytest.raises(InvalidInput):
            StreamingServer(StreamingController.__new__(StreamingController), host=host)
        with pytest.raises(InvalidInput):
            check_bind(host, "short")
    check_bind("0.0.0.0", "a-long-enough-secret-token")
    check_bind("127.0.0.1", None)
    check_bind("localhost", None)


def test_token_required_when_set(lrmate):
    srv = StreamingServer(StreamingController(lrmate), port=0, token="s3cret-token-0123456789").start()
    try:
        with connect(srv.url) as ws:
            assert json.loads(ws.recv(timeout=5))["auth"] is True
            ws.send(json.dumps({"type": "joint_target", "q": READY}))
            assert _recv(ws, "error")["code"] == "unauthorized"
        assert srv.controller.accepted == 0
        with connect(srv.url) as ws:
            ws.recv(timeout=5)
            ws.send(json.dumps({"type": "hello", "token": "s3cret-token-0123456789"}))
            ws.send(json.dumps({"type": "joint_target", "q": READY}))
            assert _state(ws)["accepted"] == 1
    finally:
        srv.stop()
