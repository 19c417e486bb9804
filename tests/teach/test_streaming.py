"""Streaming interface over a real WebSocket on 127.0.0.1: validation, deadman, binding rules."""
from __future__ import annotations

import json
import time

import numpy as np
import pytest
from websockets.sync.client import connect

from robointel.errors import InvalidInput
from robointel.teach.stream_client import StreamClient
from robointel.teach.streaming import StreamingController, StreamingServer, check_bind

READY = [0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0]


@pytest.fixture(scope="module")
def server(lrmate):
    srv = StreamingServer(StreamingController(lrmate), port=0).start()
    yield srv
    srv.stop()


def test_welcome_and_tracking(server):
    with StreamClient(server.url) as c:
        w = c.welcome
        assert w["type"] == "welcome" and w["robot"] == "lrmate200id7l" and w["deadman"] == 0.1
        assert w["protocol"] == 2
        assert c.acquire()["in_control"] is True
        goal = [0.2, 0.1, -0.1, 0.0, -1.4, 0.3]
        for k in range(150):  # stream the same goal at ~100 Hz for 1.5 s
            c.joint_target(goal, seq=k)
            time.sleep(0.01)
        s = c.state()
        np.testing.assert_allclose(s["q"], goal, atol=2e-3)
        assert s["mode"] == "tracking" and s["in_control"]


T = "__T__"  # replaced by the send time


@pytest.mark.parametrize("raw, code", [
    ("{not json", "malformed"),
    ("[1, 2, 3]", "malformed"),
    ('{"q": [0, 0, 0, 0, 0, 0]}', "malformed"),
    ('{"type": "fly"}', "unknown_type"),
    ('{"type": "joint_target", "q": [0, 0, 0], "t": __T__}', "bad_shape"),
    ('{"type": "joint_target", "q": [0, 0, "a", 0, 0, 0], "t": __T__}', "bad_shape"),
    ('{"type": "joint_target", "q": [0, 0, NaN, 0, 0, 0], "t": __T__}', "not_finite"),
    ('{"type": "joint_target", "q": [0, 0, Infinity, 0, 0, 0], "t": __T__}', "not_finite"),
    ('{"type": "joint_target", "q": [0, 0, 1' + "0" * 400 + ', 0, -1.5, 0], "t": __T__}', "not_finite"),
    ('{"type": "joint_target", "q": [0, 0, 0, 0, -1.5, 0], "t": 1' + "0" * 400 + '}', "not_finite"),
    ('{"type": "joint_target", "q": [0, 0, 0, 0, -1.5, 0], "t": __T__, "ack": "false"}', "malformed"),
    ('{"type": "joint_target", "q": [0, 0, 0, 0, -1.5, 0], "t": __T__, "seq": "7"}', "malformed"),
    ('{"type": "joint_target", "q": [0, 0, 0, 0, -1.5, 0]}', "malformed"),          # no send time
    ('{"type": "joint_target", "q": [4.0, 0, 0, 0, 0, 0], "t": __T__}', "out_of_limits"),
    ('{"type": "joint_target", "q": [0, 1.5, 0, 0, -0.5, 0], "t": __T__}', "collision"),  # TCP under the table
    ('{"type": "joint_target", "q": [0, 0, 0, 0, -1.5, 0], "t": 0.0}', "stale"),
    ('{"type": "pose_target", "position": [3.0, 0, 0.3], "quaternion": [0.7071068, 0, 0.7071068, 0], "t": __T__}',
     "unreachable"),
    ('{"type": "pose_target", "position": [0.4, 0, 0.3], "quaternion": [3, 0, 0, 0], "t": __T__}', "bad_shape"),
    ('{"type": "\u00e9\u00e9"}', "unknown_type"),
])
def test_bad_messages_get_error_and_never_reach_robot(server, raw, code):
    with StreamClient(server.url) as c:
        assert c.acquire()["in_control"]
        c.joint_target(READY, seq=1, ack=True)  # a fresh clock offset for this connection
        assert c.recv("applied", timeout=10)["type"] == "applied"
        before = server.controller.accepted
        tgt = server.controller.state()["target"]
        c.send_raw(raw.replace(T, repr(time.perf_counter())))
        err = c.recv("error")
        assert err["code"] == code and err["message"]
        assert server.controller.accepted == before
        assert server.controller.state()["target"] == tgt
        assert c.state()["type"] == "state"  # the connection stays open after the error


def test_pose_target_reaches_pose(server, lrmate):
    T = lrmate.fk(np.array([0.3, 0.2, -0.2, 0.1, -1.2, 0.2]))
    from scipy.spatial.transform import Rotation
    x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
    with StreamClient(server.url) as c:
        c.acquire()
        for _ in range(150):
            c.send({"type": "pose_target", "position": T[:3, 3].tolist(), "quaternion": [w, x, y, z]})
            time.sleep(0.01)
        s = c.state()
    np.testing.assert_allclose(lrmate.fk(np.array(s["q"]))[:3, 3], T[:3, 3], atol=2e-3)


def test_stalled_stream_decelerates_to_stop(server):
    with StreamClient(server.url) as c:
        c.acquire()
        start = [-2.5, 0.0, 0.0, 0.0, -np.pi / 2, 0.0]
        for _ in range(150):  # settle at one end of J1's range
            c.joint_target(start)
            time.sleep(0.01)
        far = [2.5, 0.0, 0.0, 0.0, -np.pi / 2, 0.0]
        for _ in range(20):  # stream the other end for 0.2 s: the robot is moving fast
            c.joint_target(far)
            time.sleep(0.01)
        wc = server.controller.wc
        speeds, t0 = [], time.monotonic()
        while time.monotonic() - t0 < 1.0:  # the stream has stalled
            speeds.append(abs(wc.qd[0]))
            time.sleep(0.01)
        s = c.state()
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
    with pytest.raises(InvalidInput, match="port"):
        StreamingServer(StreamingController.__new__(StreamingController), port=99999)


def test_token_required_when_set(lrmate):
    token = "s3cret-token-0123456789"
    srv = StreamingServer(StreamingController(lrmate), port=0, token=token).start()
    try:
        with connect(srv.url) as ws:
            w = json.loads(ws.recv(timeout=5))
            assert w == {"type": "welcome", "protocol": 2, "auth": True}  # nothing but the version
            ws.send(json.dumps({"type": "joint_target", "q": READY, "t": time.perf_counter()}))
            assert json.loads(ws.recv(timeout=5))["code"] == "unauthorized"
        with connect(srv.url) as ws:  # a non-ASCII token: an error reply, not a dropped connection
            ws.recv(timeout=5)
            ws.send(json.dumps({"type": "hello", "token": "\u00e9t\u00e9-\u2603-0123456789abcdef"}))
            assert json.loads(ws.recv(timeout=5))["code"] == "unauthorized"
        assert srv.controller.accepted == 0
        with StreamClient(srv.url, token=token) as c:
            assert c.welcome["type"] == "hello" and c.welcome["robot"] == "lrmate200id7l"
            c.acquire()
            c.joint_target(READY)
            assert c.state()["accepted"] == 1
    finally:
        srv.stop()


def test_failed_authentication_is_rate_limited(lrmate):
    token = "s3cret-token-0123456789"
    srv = StreamingServer(StreamingController(lrmate), port=0, token=token).start()
    try:
        codes = []
        t0 = time.monotonic()
        for k in range(7):
            with connect(srv.url) as ws:
                ws.recv(timeout=5)
                ws.send(json.dumps({"type": "hello", "token": f"guess-{k:02d}-0123456789"}))
                codes.append(json.loads(ws.recv(timeout=5))["code"])
        elapsed = time.monotonic() - t0
        assert codes[:5] == ["unauthorized"] * 5 and codes[5:] == ["rate_limited"] * 2
        assert elapsed >= 5 * 0.5                    # each wrong guess costs the guesser 0.5 s
        with connect(srv.url) as ws:                 # locked out: even the right token is refused now
            ws.recv(timeout=5)
            ws.send(json.dumps({"type": "hello", "token": token}))
            assert json.loads(ws.recv(timeout=5))["code"] == "rate_limited"
        assert srv.controller.accepted == 0
    finally:
        srv.stop()
