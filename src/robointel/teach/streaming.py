"""The robot streaming interface (Ch. 3.4): a WebSocket server in front of the robot controller.

The controller is :class:`~robointel.teach.stream_control.StreamingController` (simulated).

Safety rules
------------
* **one commanding client**: a client sends ``acquire`` to take control; targets, heartbeats and
  ``resume`` from any other client get ``not_in_control`` / ``control_held`` errors (they stay
  read-only: ``get_state``). ``release`` or a disconnect gives control up and stops the robot.
* **stop latches**: ``stop`` (from any authenticated client: an emergency stop) decelerates the
  robot and forgets its target; no heartbeat, old target or other client moves it again until the
  client in control sends ``resume`` and then a new target.
* **deadman from the sender's clock**: targets and heartbeats carry ``t``, the client's send time
  (s, any steady clock). The server maps it to its own clock (:class:`SendClock`: the smallest
  arrival-minus-send offset seen on the connection) and lets a target move the robot only until
  ``t + deadman``; a target older than ``deadman`` on arrival is dropped (``stale``), never
  replayed. A stall therefore stops the robot ``deadman`` after the client's last send, however
  long the server's backlog.
* **bounded work per client**: a client over the rate limit (1000 messages/s, bursts of 200) is
  not read from until it is back under it (TCP backpressure slows it; one ``rate_limited`` error
  per second tells it), so its late messages arrive stale and are dropped; at most 100 error
  replies per second go back to one client (the rest are counted); a 64 kB kernel
  receive buffer bounds each client's backlog; each client has a one-target mailbox (a newer
  target replaces an unprocessed one); IK and collision checks run in a worker thread, one target
  at a time, never on the event loop (except the one-sample check, ~0.1 ms, of a joint target
  within 0.05 rad of the reference: the usual small streaming step); the loop yields after every
  message; while the server runs the interpreter's thread switch interval is 1 ms (the control
  thread and the loop wait for the GIL at most that long).
* **checks**: JSON, type, shapes, finiteness (also ``10**400``), booleans (``"ack": "false"`` is an
  error), joint limits, IK reachability, and the straight joint-space move to the target clear of
  the table, the floor and the robot itself (``collision``, naming the link). A bad message gets
  an ``error`` reply and changes nothing; acks go to the client that asked.
* **binding and authentication**: 127.0.0.1 by default; any other address needs a token of >= 16
  characters, checked before binding. With a token, the server says only its protocol version
  until ``hello`` carries the token; a wrong token closes the connection after 0.5 s, and after 5
  failures in 60 s from one address its connections are refused (``rate_limited``).

Messages (JSON text frames < 64 kB; angles rad, positions m, times s), protocol version 2
------------------------------------------------------------------------------------------
Client -> server:

``{"type": "hello", "token": "..."?}``
    authenticate (first, when the server has a token); answered by ``hello``.
``{"type": "acquire"}`` / ``{"type": "release"}``
    take / give up control; answered by ``ok``.
``{"type": "joint_target", "q": [n floats], "t": send time, "seq": int?, "ack": bool?}``
    move to joint positions (within limits; needs control).
``{"type": "pose_target", "position": [x, y, z], "quaternion": [w, x, y, z] | "rotation": 3x3,
"t": send time, "seq": int?, "ack": bool?}``
    move the TCP to a pose (robot root frame), solved by IK closest to the current target.
``{"type": "heartbeat", "t": send time}``
    keep the current target alive until ``t + deadman`` (never restarts a stopped robot).
``{"type": "get_state"}``
    ask for a ``state`` reply.
``{"type": "stop"}`` / ``{"type": "resume"}``
    latched stop (any client) / clear the latch (the client in control); answered by ``ok``.

Server -> client:

``{"type": "welcome", "protocol": 2, "auth": bool, ...}`` on connect; without a token (or after
``hello``) also ``"robot", "joint_names", "lower", "upper", "deadman", "client"``;
``{"type": "hello", "protocol": 2, "client": id, "robot": ..., ...}`` the answer to ``hello``;
``{"type": "ok", "of": type, "seq": int | null, "in_control": bool, "latched": bool}``;
``{"type": "applied", "seq": int, "t": sim time}`` to the sender of a target with ``"ack": true``
when the controller first acts on it;
``{"type": "state", "t": s, "q": [...], "qd": [...], "target": [...] | null, "mode": "idle" |
"tracking" | "stopping" | "stopped" | "faulted", "latched": bool, "in_control": bool, "controlled": bool,
"accepted": int, "rejected": int, "fault": "why the robot interface stopped" | null}``;
``{"type": "error", "code": "malformed" | "unknown_type" | "bad_shape" | "not_finite" |
"out_of_limits" | "unreachable" | "collision" | "stale" | "superseded" | "stopped" | "fault" |
"not_in_control" | "control_held" | "rate_limited" | "unauthorized" | "internal", "message": "...",
"seq": int | null}``.
"""
from __future__ import annotations

import asyncio
import collections
import concurrent.futures
import hmac
import ipaddress
import itertools
import json
import socket
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robointel._extras import needs_extra
from robointel.errors import InvalidInput
from robointel.teach.collision_guard import CollisionGuard
from robointel.teach.stream_control import StreamingController, Target
from robointel.teach.stream_protocol import (
    MAX_MESSAGE_BYTES,
    MESSAGE_TYPES,
    PROTOCOL_VERSION,
    TIMED_TYPES,
    RateLimit,
    Rejected,
    SendClock,
    flag,
    number,
    numbers,
    pose,
    sequence,
)

__all__ = ["StreamingController", "StreamingServer", "check_bind", "is_loopback", "PROTOCOL_VERSION",
           "MAX_MESSAGE_BYTES", "Rejected"]

AUTH_FAILURES = 5        # failed hellos per address ...
AUTH_WINDOW = 60.0       # ... within this many seconds lock the address out
AUTH_DELAY = 0.5         # s before a wrong token is answered
ERROR_REPLIES = 100.0    # error replies per second and client (more are counted, not sent)
SWITCH_INTERVAL = 0.001  # s: the control thread and the event loop get the GIL within 1 ms while serving
RECEIVE_BUFFER = 64 * 1024  # bytes of kernel receive buffer per connection: a bounded backlog per client


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and 'localhost'."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def check_bind(host: str, token: str | None) -> None:
    """Refuse a non-loopback bind without a token (checked before any socket is opened).

    Raises:
        InvalidInput: ``host`` is not a loopback address and no (>= 16 character) token is given.
    """
    if not is_loopback(host):
        if not token or len(token) < 16:
            raise InvalidInput(
                f"refusing to bind {host!r} without a token: the streaming interface moves a robot. "
                "Bind 127.0.0.1 (default) or pass a token of at least 16 characters", value=host)


def _same_token(given: str, token: str) -> bool:
    """Constant-time comparison of two tokens of any characters."""
    return hmac.compare_digest(given.encode("utf-8", "surrogatepass"), token.encode("utf-8", "surrogatepass"))


@dataclass
class _Client:
    id: str
    ws: Any
    authed: bool
    clock: SendClock = field(default_factory=SendClock)
    limit: RateLimit = field(default_factory=RateLimit)
    slot: tuple | None = None  # the newest unprocessed target: (kind, payload, seq, ack, sent)
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    limited_reply: float = -1e9
    throttled: int = 0
    error_budget: RateLimit = field(default_factory=lambda: RateLimit(rate=ERROR_REPLIES, burst=ERROR_REPLIES))
    suppressed: int = 0


class StreamingServer:
    """WebSocket server around a :class:`StreamingController` (runs in its own thread).

    Args:
        controller: the controller (default: a new one on the LR Mate).
        host: bind address (default 127.0.0.1); anything else needs ``token``.
        port: TCP port (0: pick a free one; see :attr:`port` after :meth:`start`).
        token: shared secret clients send in ``hello``.
        max_clients: connections served at once (more are closed with ``rate_limited``).

    Raises:
        InvalidInput: a non-loopback ``host`` without a token (before binding), or a port outside
            0..65535.
    """

    def __init__(self, controller: StreamingController | None = None, *, host: str = "127.0.0.1", port: int = 0,
                 token: str | None = None, max_clients: int = 32) -> None:
        check_bind(host, token)
        if not (0 <= int(port) <= 65535):
            raise InvalidInput(f"port must be in 0..65535, got {port}", value=port)
        self.host, self.port, self.token = host, int(port), token
        self.max_clients = int(max_clients)
        self.controller = controller or StreamingController()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._stop: asyncio.Event | None = None
        self._clients: dict[str, _Client] = {}
        self._ids = itertools.count(1)
        self._auth_failures: dict[str, collections.deque] = collections.defaultdict(collections.deque)
        self._pool = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="robointel-ik")
        # the event loop's own collision guard (own kinematic data) for small steps checked inline
        self._guard = CollisionGuard(self.controller.robot, self.controller.guard.obstacles,
                                     clearance=self.controller.guard.clearance,
                                     self_clearance=self.controller.guard.self_clearance)
        self._error: BaseException | None = None
        self._switch: float | None = None

    @property
    def url(self) -> str:
        """``ws://host:port``."""
        return f"ws://{self.host}:{self.port}"

    def _robot_info(self, client: str) -> dict[str, Any]:
        r = self.controller.robot
        return {"protocol": PROTOCOL_VERSION, "client": client, "robot": r.name, "joint_names": r.joint_names,
                "lower": r.lower.tolist(), "upper": r.upper.tolist(), "deadman": self.controller.deadman,
                "auth": self.token is not None}

    # ------------------------------------------------------------------ per connection
    async def _handler(self, ws: Any) -> None:
        c = _Client(f"c{next(self._ids)}", ws, authed=self.token is None)
        if len(self._clients) >= self.max_clients:
            await self._send(ws, {"type": "error", "code": "rate_limited", "message": "too many clients", "seq": None})
            await ws.close(code=1013, reason="too many clients")
            return
        self._clients[c.id] = c
        worker = asyncio.ensure_future(self._worker(c))
        try:
            await self._send(ws, {"type": "welcome", **self._robot_info(c.id)} if c.authed else
                             {"type": "welcome", "protocol": PROTOCOL_VERSION, "auth": True})
            async for raw in ws:
                await asyncio.sleep(0)  # one message per turn: a flooding client cannot starve the others
                now = time.perf_counter()
                wait = c.limit.delay(now)
                if wait > 0:  # over the rate: stop reading this client (TCP backpressure slows it down)
                    c.throttled += 1
                    if now - c.limited_reply > 1.0:
                        c.limited_reply = now
                        await self._error_to(c, "rate_limited", "over 1000 messages/s: reading paused", None)
                    await asyncio.sleep(wait)
                    now = time.perf_counter()
                if isinstance(raw, bytes) or len(raw) > MAX_MESSAGE_BYTES:
                    msg = None
                    await self._error_to(c, "malformed", "send JSON text frames under 64 kB", None)
                else:
                    try:
                        msg = json.loads(raw, parse_constant=lambda _c: float("nan"))
                    except (ValueError, RecursionError):
                        msg = None
                        await self._error_to(c, "malformed", "not valid JSON", None)
                if msg is None:
                    if not c.authed:  # before authentication only a valid hello keeps the connection
                        await ws.close(code=1008, reason="unauthorized")
                        return
                    continue
                if not c.authed:
                    if not await self._authenticate(c, msg):
                        await ws.close(code=1008, reason="unauthorized")
                        return
                    continue
                try:
                    reply = self._dispatch(c, msg, now)
                except Rejected as exc:
                    self.controller.rejected += 1
                    seq = msg.get("seq") if isinstance(msg, dict) and type(msg.get("seq")) is int else None
                    reply = {"type": "error", "code": exc.code, "message": str(exc), "seq": seq}
                except Exception as exc:  # never drop the connection on a bug: say so
                    self.controller.rejected += 1
                    reply = {"type": "error", "code": "internal", "message": f"{type(exc).__name__}: {exc}",
                             "seq": None}
                if reply is not None:
                    await self._reply(c, reply)
        except Exception:  # connection dropped: release control, the robot stops
            pass
        finally:
            worker.cancel()
            self._clients.pop(c.id, None)
            self.controller.release(c.id)

    async def _authenticate(self, c: _Client, msg: Any) -> bool:
        peer = str((c.ws.remote_address or ("?",))[0])
        fails = self._auth_failures[peer]
        now = time.monotonic()
        while fails and now - fails[0] > AUTH_WINDOW:
            fails.popleft()
        if len(fails) >= AUTH_FAILURES:
            await self._error_to(c, "rate_limited", f"too many failed authentications from {peer}; retry in "
                                                    f"{AUTH_WINDOW - (now - fails[0]):.0f} s", None)
            return False
        tok = msg.get("token") if isinstance(msg, dict) and msg.get("type") == "hello" else None
        assert self.token is not None
        if isinstance(tok, str) and _same_token(tok, self.token):
            c.authed = True
            await self._send(c.ws, {"type": "hello", **self._robot_info(c.id)})
            return True
        fails.append(now)
        await asyncio.sleep(AUTH_DELAY)
        await self._error_to(c, "unauthorized", "send {'type': 'hello', 'token': ...} first", None)
        return False

    def _dispatch(self, c: _Client, msg: Any, now: float) -> dict[str, Any] | None:
        """Cheap handling on the event loop; targets go to the client's mailbox. Raises Rejected."""
        ctrl = self.controller
        if not isinstance(msg, dict):
            raise Rejected("malformed", "a message must be a JSON object")
        typ = msg.get("type")
        if typ is None:
            raise Rejected("malformed", "a message needs a 'type'")
        if typ not in MESSAGE_TYPES:
            raise Rejected("unknown_type", f"unknown message type {str(typ)[:40]!r}")
        seq = sequence(msg)
        sent = now
        if "t" in msg:
            sent = c.clock.to_server(number(msg["t"], "t"), now)
        elif typ in TIMED_TYPES:
            raise Rejected("malformed", f"{typ} needs 't': the client's send time [s] (any steady clock)")
        if typ in ("joint_target", "pose_target"):
            ack = flag(msg, "ack")
            payload = numbers(msg.get("q"), ctrl.n, "q") if typ == "joint_target" else pose(msg)
            ctrl.may_command(c.id, sent, now)
            if typ == "joint_target" and c.slot is None and \
                    float(np.max(np.abs(payload - ctrl.q_ref))) <= self._guard.step:
                # a small step (the usual stream): one collision sample, checked here (~0.1 ms)
                ctrl.command(payload, client=c.id, sent=sent, seq=seq, ack=ack, guard=self._guard)
                return None
            if c.slot is not None and c.slot[3]:
                self._post(c, {"type": "error", "code": "superseded", "message": "replaced by a newer target "
                                                                                 "before it was checked",
                               "seq": c.slot[2]})
            c.slot = (typ, payload, seq, ack, sent)
            c.wake.set()
            return None
        if typ == "heartbeat":
            ctrl.heartbeat(c.id, sent)
            return None
        if typ == "get_state":
            return ctrl.state(c.id)
        if typ == "hello":
            return {"type": "hello", **self._robot_info(c.id)}
        if typ == "stop":
            ctrl.emergency_stop()
        elif typ == "resume":
            ctrl.resume(c.id)
        elif typ == "acquire":
            ctrl.acquire(c.id)
        elif typ == "release":
            ctrl.release(c.id)
        return {"type": "ok", "of": typ, "seq": seq, "in_control": ctrl.owner == c.id, "latched": ctrl.latched}

    def _heavy(self, client: str, item: tuple) -> None:
        """IK (pose targets) and the collision check, in the worker thread."""
        kind, payload, seq, ack, sent = item
        ctrl = self.controller
        if kind == "pose_target":
            ctrl.may_command(client, sent, time.perf_counter())
            payload = ctrl.solve_pose(payload)
        ctrl.command(np.asarray(payload, float), client=client, sent=sent, seq=seq, ack=ack)

    async def _worker(self, c: _Client) -> None:
        loop = asyncio.get_running_loop()
        while True:
            await c.wake.wait()
            c.wake.clear()
            item, c.slot = c.slot, None
            if item is None:
                continue
            try:
                await loop.run_in_executor(self._pool, self._heavy, c.id, item)
            except Rejected as exc:
                self.controller.rejected += 1
                await self._error_to(c, exc.code, str(exc), item[2])

    def _on_applied(self, target: Target, t: float) -> None:
        """Control thread: route the ``applied`` ack to the client that sent the target."""
        c = self._clients.get(target.client)
        if c is not None:
            self._post(c, {"type": "applied", "seq": target.seq, "t": t})

    def _post(self, c: _Client, obj: dict[str, Any]) -> None:
        if self._loop is not None and not self._loop.is_closed():
            try:
                self._loop.call_soon_threadsafe(asyncio.ensure_future, self._send(c.ws, obj))
            except RuntimeError:
                pass

    async def _error_to(self, c: _Client, code: str, message: str, seq: int | None) -> None:
        if code != "rate_limited":
            self.controller.rejected += 1
        await self._reply(c, {"type": "error", "code": code, "message": message, "seq": seq})

    async def _reply(self, c: _Client, obj: dict[str, Any]) -> None:
        """Send a reply; error replies beyond ERROR_REPLIES per second are counted, not sent."""
        if obj.get("type") == "error" and obj.get("code") not in ("unauthorized", "rate_limited") \
                and c.error_budget.delay(time.perf_counter()) > 0:
            c.suppressed += 1
            return
        await self._send(c.ws, obj)

    @staticmethod
    async def _send(ws: Any, obj: dict[str, Any]) -> None:
        try:
            await ws.send(json.dumps(obj))
        except Exception:
            pass

    # ------------------------------------------------------------------ lifecycle
    async def _main(self) -> None:
        from websockets.asyncio.server import serve

        self._stop = asyncio.Event()
        try:
            async with serve(self._handler, self.host, self.port, max_size=MAX_MESSAGE_BYTES * 2, max_queue=32,
                             compression=None) as server:
                self.port = server.sockets[0].getsockname()[1] if self.port == 0 else self.port
                for s in server.sockets:  # accepted connections inherit these
                    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER)
                self._ready.set()
                await self._stop.wait()
        except BaseException as exc:  # bind failure etc.
            self._error = exc
            self._ready.set()

    def start(self, timeout: float = 10.0) -> StreamingServer:
        """Start the control thread and the server thread; return when listening.

        Raises:
            InvalidInput: the server could not bind (port in use, bad address) or did not start.
            MissingExtra: websockets is not installed (the ``teleop`` extra).
        """
        with needs_extra("teleop", "the streaming server"):
            import websockets.asyncio.server  # noqa: F401  (here, not in the server thread: a missing one is said)
        self.controller.on_applied = self._on_applied
        self._switch = sys.getswitchinterval()
        sys.setswitchinterval(min(self._switch, SWITCH_INTERVAL))
        self.controller.start()

        def run() -> None:
            self._loop = asyncio.new_event_loop()
            self._loop.run_until_complete(self._main())
            self._loop.close()

        self._thread = threading.Thread(target=run, name="robointel-stream", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            self.stop()
            raise InvalidInput("streaming server did not start in time")
        if self._error is not None:
            self.stop()
            raise InvalidInput(f"could not start the streaming server on {self.host}:{self.port}: {self._error}",
                               value=self.port)
        return self

    def stop(self) -> None:
        """Close the server, join its thread and the control thread."""
        if self._loop is not None and self._stop is not None and not self._loop.is_closed():
            try:
                self._loop.call_soon_threadsafe(self._stop.set)
            except RuntimeError:
                pass
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        self._pool.shutdown(wait=False, cancel_futures=True)
        self.controller.stop()
        if self._switch is not None:
            sys.setswitchinterval(self._switch)
            self._switch = None

    def __enter__(self) -> StreamingServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
