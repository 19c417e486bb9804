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
* **deadman by the server's clock**: targets and heartbeats carry ``t``, the client's send time
  (s, any steady clock). The server maps it to its own clock (:class:`SendClock`: the smallest
  arrival-minus-send offset seen on the connection, so a mapped send time is never later than the
  arrival) and lets a target move the robot only until that time plus ``deadman``; a target older
  than ``deadman`` on arrival is dropped (``stale``), never replayed. The client's clock must keep
  the server's time: one that runs fast (it would make a backlog look fresh) is refused
  (``clock_rate``; the robot stops), one that runs slow makes every target stale and is named in the
  refusal. A stall therefore stops the robot ``deadman`` after the client's last send, however long
  the server's backlog and whatever the client's clock does.
* **bounded work per client**: a client over its rate limit (the client in control 1000
  messages/s, bursts of 200; the others 200/s, bursts of 50) is not read from until it is back
  under it (TCP backpressure slows it; one ``rate_limited`` error per second tells it), so its
  late messages arrive stale and are dropped; at most 100 error replies per second go back to one
  client (the rest are counted); a 64 kB kernel receive buffer bounds each client's backlog; each
  client has a one-target mailbox (a newer target replaces an unprocessed one); IK and collision
  checks run in a worker thread, one target at a time, never on the event loop (except the
  one-sample check, ~0.1 ms, of a joint target within 0.05 rad of the reference: the usual small
  streaming step); the loop yields after every message; while the server runs the interpreter's
  thread switch interval is 1 ms (the control thread and the loop wait for the GIL at most that
  long).
* **checks**: JSON, type, shapes, finiteness (also ``10**400``), booleans (``"ack": "false"`` is an
  error), joint limits, IK reachability, and the straight joint-space move to the target clear of
  the table, the floor and the robot itself (``collision``, naming the link). A bad message gets
  an ``error`` reply and changes nothing; acks go to the client that asked.
* **binding and authentication**: 127.0.0.1 by default; any other address needs a token of >= 16
  characters, checked before binding. With a token, a connection is told only the protocol version
  until ``hello`` carries the token, and nothing it sends before is acted on; a wrong token closes
  the connection after 0.5 s, and after 5 failures in 60 s from one address its connections are
  refused (``rate_limited``). An unauthenticated connection does not take one of the
  ``max_clients`` session slots, is closed when it has not authenticated within 2 s, and beyond 128
  of them the oldest is closed (:mod:`robointel.teach.stream_session`): ``stop`` from any
  authenticated session always gets through. The token is never echoed.

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
"not_in_control" | "control_held" | "rate_limited" | "unauthorized" | "clock_rate" | "internal",
"message": "...",
"seq": int | null}``.
"""
from __future__ import annotations

import asyncio
import concurrent.futures
import itertools
import json
import socket
import sys
import threading
import time
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
    Rejected,
    flag,
    number,
    numbers,
    pose,
    sequence,
)
from robointel.teach.stream_session import (
    AUTH_DELAY,
    AUTH_TIMEOUT,
    Gatekeeper,
    Session,
    check_bind,
    is_loopback,
)

__all__ = ["StreamingController", "StreamingServer", "check_bind", "is_loopback", "PROTOCOL_VERSION",
           "MAX_MESSAGE_BYTES", "Rejected"]

SWITCH_INTERVAL = 0.001  # s: the control thread and the event loop get the GIL within 1 ms while serving
RECEIVE_BUFFER = 8 * 1024  # bytes of kernel receive buffer per connection: a bounded backlog per client
_BAD = object()  # a frame that did not parse


class StreamingServer:
    """WebSocket server around a :class:`StreamingController` (runs in its own thread).

    Args:
        controller: the controller (default: a new one on the LR Mate).
        host: bind address (default 127.0.0.1); anything else needs ``token``.
        port: TCP port (0: pick a free one; see :attr:`port` after :meth:`start`).
        token: shared secret clients send in ``hello`` (>= 16 printable characters).
        max_clients: authenticated sessions served at once (more are closed with ``rate_limited``);
            unauthenticated connections do not count (see :mod:`robointel.teach.stream_session`).

    Raises:
        InvalidInput: a non-loopback ``host`` without a token, a malformed token, a port outside
            0..65535 or ``max_clients`` < 1 (all before binding).
    """

    def __init__(self, controller: StreamingController | None = None, *, host: str = "127.0.0.1", port: int = 0,
                 token: str | None = None, max_clients: int = 32) -> None:
        check_bind(host, token)
        if isinstance(port, bool) or not isinstance(port, int | np.integer) or not (0 <= int(port) <= 65535):
            raise InvalidInput(f"port must be an integer in 0..65535, got {port!r}", value=port)
        if isinstance(max_clients, bool) or not isinstance(max_clients, int | np.integer) or max_clients < 1:
            raise InvalidInput(f"max_clients must be an integer >= 1, got {max_clients!r}", value=max_clients)
        self.host, self.port, self.token = host, int(port), token
        self.max_clients = int(max_clients)
        self.controller = controller or StreamingController()
        self.gate = Gatekeeper(token)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._stop: asyncio.Event | None = None
        self._clients: dict[str, Session] = {}
        self._ids = itertools.count(1)
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
        c = Session(f"c{next(self._ids)}", ws, authed=self.token is None)
        if not c.authed and not await self._authenticate(c):
            return
        if len(self._clients) >= self.max_clients:
            await self._send(ws, {"type": "error", "code": "rate_limited", "message": "too many clients", "seq": None})
            await ws.close(code=1013, reason="too many clients")
            return
        self._clients[c.id] = c
        worker = asyncio.ensure_future(self._worker(c))
        try:
            await self._send(ws, {"type": "welcome" if self.token is None else "hello", **self._robot_info(c.id)})
            async for raw in ws:
                await asyncio.sleep(0)  # one message per turn: a flooding client cannot starve the others
                now = time.perf_counter()
                msg = self._parse(raw)
                c.use_rate(self.controller.owner == c.id)
                wait = c.limit.delay(now)
                if wait > 0 and not (isinstance(msg, dict) and msg.get("type") == "stop"):  # a stop is never held
                    c.throttled += 1  # over the rate: stop reading this client (TCP backpressure slows it down)
                    if now - c.limited_reply > 1.0:
                        c.limited_reply = now
                        await self._error_to(c, "rate_limited", f"over {c.limit.rate:.0f} messages/s: reading "
                                                                "paused", None)
                    await asyncio.sleep(wait)
                    now = time.perf_counter()
                if msg is _BAD:
                    await self._error_to(c, "malformed", "send JSON text frames under 64 kB holding one object",
                                         None)
                    continue
                try:
                    reply = self._dispatch(c, msg, now)
                except Rejected as exc:
                    self.controller.rejected += 1
                    seq = msg.get("seq") if isinstance(msg, dict) and type(msg.get("seq")) is int else None
                    code, text = exc.code, str(exc)
                    if code == "clock_rate":  # a client clock that runs fast: its target no longer moves the arm
                        self.controller.drop(c.id)
                    elif code == "stale" and isinstance(msg, dict) and isinstance(msg.get("t"), int | float):
                        note = c.clock.rate_note(float(msg["t"]), now)
                        code, text = ("clock_rate", text + note) if note else (code, text)
                    reply = {"type": "error", "code": code, "message": text, "seq": seq}
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

    @staticmethod
    def _parse(raw: Any) -> Any:
        """The decoded JSON of a text frame, or ``_BAD`` (binary, too large, not JSON)."""
        if isinstance(raw, bytes) or len(raw) > MAX_MESSAGE_BYTES:
            return _BAD
        try:
            return json.loads(raw, parse_constant=lambda _c: float("nan"))
        except (ValueError, RecursionError):
            return _BAD

    async def _authenticate(self, c: Session) -> bool:
        """The pending phase of a connection: a ``hello`` with the token within AUTH_TIMEOUT, or closed.

        Only the protocol version is sent before; a pending connection holds no session slot, and the
        oldest pending one is closed when there are too many.
        """
        evict = self.gate.admit_pending(c)
        if evict is not None:
            asyncio.ensure_future(evict.ws.close(code=1013, reason="too many unauthenticated connections"))
        try:
            await self._send(c.ws, {"type": "welcome", "protocol": PROTOCOL_VERSION, "auth": True})
            try:
                ok = await asyncio.wait_for(self._hello(c), AUTH_TIMEOUT)
            except TimeoutError:
                self.gate.timeouts += 1
                ok = False
                await self._send(c.ws, {"type": "error", "code": "unauthorized", "seq": None,
                                        "message": f"authenticate within {AUTH_TIMEOUT:g} s: send "
                                                   "{'type': 'hello', 'token': ...}"})
        except Exception:  # the connection went away
            ok = False
        finally:
            self.gate.pending.pop(c.id, None)
        if not ok:
            try:
                await c.ws.close(code=1008, reason="unauthorized")
            except Exception:
                pass
        return ok

    async def _hello(self, c: Session) -> bool:
        raw = await c.ws.recv()
        peer = str((c.ws.remote_address or ("?",))[0])
        now = time.monotonic()
        wait = self.gate.locked_out(peer, now)
        if wait is not None:
            await self._error_to(c, "rate_limited", f"too many failed authentications from {peer}; retry in "
                                                    f"{wait:.0f} s", None)
            return False
        if self.gate.accepts(self._parse(raw)):
            c.authed = True
            return True
        self.gate.fail(peer, now)
        await asyncio.sleep(AUTH_DELAY)
        await self._error_to(c, "unauthorized", "send {'type': 'hello', 'token': ...} first", None)
        return False

    def _dispatch(self, c: Session, msg: Any, now: float) -> dict[str, Any] | None:
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

    async def _worker(self, c: Session) -> None:
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

    def _post(self, c: Session, obj: dict[str, Any]) -> None:
        if self._loop is not None and not self._loop.is_closed():
            try:
                self._loop.call_soon_threadsafe(asyncio.ensure_future, self._send(c.ws, obj))
            except RuntimeError:
                pass

    async def _error_to(self, c: Session, code: str, message: str, seq: int | None) -> None:
        if code != "rate_limited":
            self.controller.rejected += 1
        await self._reply(c, {"type": "error", "code": code, "message": message, "seq": seq})

    async def _reply(self, c: Session, obj: dict[str, Any]) -> None:
        """Send a reply; error replies beyond ERROR_REPLIES per second are counted, not sent."""
        if obj.get("type") == "error" and obj.get("code") not in ("unauthorized", "rate_limited") \
                and not c.error_budget.take(time.perf_counter()):
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
                             compression=None, open_timeout=AUTH_TIMEOUT) as server:
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
