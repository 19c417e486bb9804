"""A small synchronous client of the streaming protocol (:mod:`robointel.teach.streaming`).

Stamps every target and heartbeat with the send time ``t`` from ``time.perf_counter`` (the server
only needs a steady clock), and filters replies by type.
"""
from __future__ import annotations

import json
import time
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel._extras import needs_extra


class StreamClient:
    """One WebSocket connection to a streaming server (``websockets`` sync client).

    Args:
        url: ``ws://host:port``.
        token: sent in ``hello`` right after connecting when given.
        timeout: seconds to wait for a reply.

    Attributes:
        welcome: the server's ``welcome`` (and, with a token, ``hello``) message.
    """

    def __init__(self, url: str, *, token: str | None = None, timeout: float = 5.0) -> None:
        with needs_extra("teleop", "the streaming client"):
            from websockets.sync.client import connect

        self.timeout = float(timeout)
        self.ws = connect(url, compression=None, open_timeout=timeout)
        self.welcome: dict[str, Any] = json.loads(self.ws.recv(timeout=timeout))
        self.seen: list[dict[str, Any]] = []  # replies skipped while waiting for another type
        if token is not None:
            self.send({"type": "hello", "token": token})
            self.welcome = self.recv("hello")

    def send(self, msg: dict[str, Any]) -> None:
        """Send one message as JSON (``t`` added to targets and heartbeats when missing)."""
        if msg.get("type") in ("joint_target", "pose_target", "heartbeat") and "t" not in msg:
            msg = {**msg, "t": time.perf_counter()}
        self.ws.send(json.dumps(msg))

    def send_raw(self, text: str) -> None:
        """Send a text frame as is."""
        self.ws.send(text)

    def recv(self, typ: str | None = None, timeout: float | None = None) -> dict[str, Any]:
        """The next reply (of type ``typ`` if given; ``error`` replies are always returned).

        Raises:
            TimeoutError: nothing of that type within ``timeout`` seconds.
        """
        end = time.monotonic() + (self.timeout if timeout is None else timeout)
        while True:
            left = end - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no {typ or 'reply'} within the timeout")
            m = json.loads(self.ws.recv(timeout=left))
            if typ is None or m.get("type") in (typ, "error"):
                return m
            self.seen.append(m)

    def request(self, msg: dict[str, Any], typ: str) -> dict[str, Any]:
        """Send ``msg`` and return the reply of type ``typ`` (or the error)."""
        self.send(msg)
        return self.recv(typ)

    def acquire(self, wait: float = 2.0) -> dict[str, Any]:
        """Take control: the ``ok`` reply, or the last ``error`` reply.

        Args:
            wait: keep asking this long (s) while another client holds control (a client that has
                just disconnected is released when the server notices the close).
        """
        end = time.monotonic() + wait
        while True:
            reply = self.request({"type": "acquire"}, "ok")
            if reply.get("code") != "control_held" or time.monotonic() > end:
                return reply
            time.sleep(0.02)

    def joint_target(self, q: npt.ArrayLike, **extra: Any) -> None:
        """Stream a joint target (n,) rad, stamped with the send time."""
        self.send({"type": "joint_target", "q": [float(v) for v in np.asarray(q, float)], **extra})

    def state(self) -> dict[str, Any]:
        """The server's ``state`` reply."""
        return self.request({"type": "get_state"}, "state")

    def close(self) -> None:
        """Close the connection (the server releases control and the robot stops)."""
        self.ws.close()

    def __enter__(self) -> StreamClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


JUNK = ('{"type": "joint_target", "q": [0, 0, 0, 0, -1.5, 0], "t": %r}',
        '{"type": "pose_target", "position": [3.0, 0, 0.3], "quaternion": [1, 0, 0, 0], "t": %r}',
        '{"type": "get_state"}', '{not json', '{"type": "heartbeat", "t": %r}')


def flood(url: str, mode: str, seconds: float, hold: float, *, start: Any = None, token: str | None = None,
          clock: float = 1.0, send_buffer: int | None = None) -> dict[str, float]:
    """A misbehaving client for load tests: send as fast as the link takes for ``seconds``.

    Modes: ``command`` (takes control, streams a joint target at J1's far end), ``command_poses``
    (takes control, streams unreachable poses: IK work), ``junk`` (no control: a mix of refused
    targets, state requests, bad JSON and heartbeats). Replies are read and discarded.

    Args:
        url: the server, ``ws://127.0.0.1:port``.
        mode: ``command``, ``command_poses`` or ``junk``.
        seconds: flood duration, s.
        hold: stay connected and silent this long afterwards, s.
        start: called (no arguments) once connected, before flooding (e.g. to wait for a go signal).
        token: the server's token (sent in ``hello`` first).
        clock: the rate of the send times ``t`` it stamps: 1 is seconds, 1000 a clock 1000x fast
            (milliseconds where seconds are expected), 0.001 one 1000x slow.
        send_buffer: the kernel send buffer of its socket, bytes (None: the system's, up to 4 MB on
            Linux loopback): what an attacker elsewhere can have in flight towards the server.

    Returns:
        ``{"last_send": perf_counter time of the last send, s, "sent": messages}``.
    """
    import socket
    import threading
    from urllib.parse import urlparse

    with needs_extra("teleop", "the streaming client"):
        from websockets.sync.client import connect

    u = urlparse(url)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    if send_buffer is not None:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, int(send_buffer))
    sock.connect((u.hostname, u.port))
    ws = connect(url, compression=None, sock=sock, close_timeout=0.2)
    ws.recv(timeout=5)
    if token is not None:
        ws.send(json.dumps({"type": "hello", "token": token}))
        ws.recv(timeout=5)

    def drain() -> None:
        try:
            while True:
                ws.recv(timeout=60)
        except Exception:
            pass

    if mode.startswith("command"):
        ws.send(json.dumps({"type": "acquire"}))
    threading.Thread(target=drain, daemon=True).start()
    if start is not None:
        start()
    right = [2.5, 0.0, 0.0, 0.0, -1.5707963, 0.0]
    k, t0 = 0, time.perf_counter()
    last = t0
    while time.perf_counter() - t0 < seconds:
        last = time.perf_counter()
        t = last * clock
        if mode == "command":
            ws.send(json.dumps({"type": "joint_target", "q": right, "t": t, "seq": k}))
        elif mode == "command_poses":
            ws.send(json.dumps({"type": "pose_target", "position": [3.0, 0.1 * (k % 7), 0.3],
                                "quaternion": [1, 0, 0, 0], "t": t, "seq": k}))
        else:
            m = JUNK[k % len(JUNK)]
            ws.send(m % t if "%r" in m else m)
        k += 1
    import os

    cpu = os.times()
    out = {"last_send": last, "sent": float(k), "cpu_s": cpu.user + cpu.system}
    print(json.dumps(out), flush=True)
    time.sleep(hold)
    ws.close()
    return out


if __name__ == "__main__":  # python -m robointel.teach.stream_client URL MODE SECONDS HOLD [CLOCK [SEND_BUFFER]]
    import os
    import sys

    def _wait_for_go() -> None:
        print("ready", flush=True)
        sys.stdin.readline()

    flood(sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), start=_wait_for_go,
          token=os.environ.get("ROBOINTEL_STREAM_TOKEN"), clock=float(sys.argv[5]) if len(sys.argv) > 5 else 1.0,
          send_buffer=int(sys.argv[6]) if len(sys.argv) > 6 and sys.argv[6] != "-" else None)
