"""The robot streaming interface (Ch. 3.4): a WebSocket server that owns the (simulated) robot
controller and accepts streamed targets.

The server runs the MuJoCo workcell in real time at 1 kHz in a control thread. Between targets an
online trajectory generator (``ruckig``: jerk-limited, within the joint velocity and acceleration
limits) moves the reference; the workcell's joint controller tracks it. Safety:

* **validation**: every message is checked (JSON, type, shapes, finiteness, joint limits, IK
  reachability) before anything reaches the controller; a bad message gets an ``error`` reply and
  changes nothing;
* **deadman**: if no valid target arrives for ``deadman`` seconds (default 0.1 s) while the robot
  is moving toward one, the generator switches to a jerk-limited stop (velocity -> 0) and the
  robot holds where it stopped (mode ``"stopped"``) until a new target arrives;
* **binding**: 127.0.0.1 by default; any other address needs a token, checked before binding;
  with a token every connection must first send ``hello`` with it.

Message schema (JSON text frames; angles in rad, positions in m, times in s)
--------------------------------------------------------------------------------
Client -> server:

``{"type": "hello", "token": "..."}``
    authenticate (required first when the server has a token).
``{"type": "joint_target", "q": [n floats], "seq": int?, "ack": bool?}``
    move to joint positions (within limits).
``{"type": "pose_target", "position": [x, y, z], "quaternion": [w, x, y, z] | "rotation": 3x3,
"seq": int?, "ack": bool?}``
    move the TCP to a pose (robot root frame); solved by IK closest to the current target.
``{"type": "heartbeat"}``
    keep the current target alive without changing it (resets the deadman).
``{"type": "get_state"}``
    ask for a ``state`` reply.
``{"type": "stop"}``
    decelerate to a stop now.

Server -> client:

``{"type": "welcome", "robot": name, "joint_names": [...], "lower": [...], "upper": [...],
"deadman": s, "auth": bool}``  on connect;
``{"type": "applied", "seq": int, "t": sim time}``  when the controller first acts on a target
that asked for ``"ack": true``;
``{"type": "state", "t": s, "q": [...], "qd": [...], "target": [...] | null, "mode": "idle" |
"tracking" | "stopping" | "stopped", "accepted": int, "rejected": int}``;
``{"type": "error", "code": "malformed" | "unknown_type" | "bad_shape" | "not_finite" |
"out_of_limits" | "unreachable" | "unauthorized", "message": "...", "seq": int | null}``.
"""
from __future__ import annotations

import asyncio
import atexit
import hmac
import ipaddress
import json
import math
import socket
import threading
import time
import weakref
from dataclasses import dataclass

import numpy as np

from robointel.errors import IKFailure, InvalidInput

PROTOCOL_VERSION = 1
MAX_MESSAGE_BYTES = 64 * 1024
_LIVE: "weakref.WeakSet[StreamingController]" = weakref.WeakSet()


@atexit.register
def _release_generators() -> None:
    """Stop (join) the control threads still running at exit, then drop the ruckig objects of
    controllers still alive (e.g. held by a web server's callbacks) before the extension module is
    torn down. A daemon thread left inside MuJoCo when the interpreter finalises would crash it."""
    for c in list(_LIVE):
        c.stop()
        c.otg = c.inp = c.out = None


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


class Rejected(Exception):
    """A message that must not reach the robot; carries the error code for the reply."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code


@dataclass
class Target:
    q: np.ndarray
    seq: int | None
    ack: bool
    received: float  # perf_counter


def _quat_to_matrix(qw, qx, qy, qz) -> np.ndarray:
    n = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    if not (0.5 < n < 1.5):
        raise Rejected("bad_shape", f"quaternion must be unit length, got norm {n:.3g}")
    qw, qx, qy, qz = qw / n, qx / n, qy / n, qz / n
    return np.array([[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
                     [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
                     [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]])


def _numbers(x, n: int, what: str) -> np.ndarray:
    if not isinstance(x, list) or len(x) != n:
        raise Rejected("bad_shape", f"{what} must be a list of {n} numbers")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in x):
        raise Rejected("bad_shape", f"{what} must contain numbers only")
    a = np.array(x, dtype=float)
    if not np.all(np.isfinite(a)):
        raise Rejected("not_finite", f"{what} contains NaN or inf")
    return a


class StreamingController:
    """The robot side: a real-time 1 kHz loop over a ``Workcell`` with a ruckig generator, a
    deadman and message validation. Usable without the network (:meth:`submit`).

    Args:
        robot: a :class:`robointel.robot.Robot` (default: the LR Mate).
        workcell: a ``robointel.sim.Workcell`` of the robot (default: built here).
        deadman: stall time [s] after which the robot decelerates to a stop.
        q0: initial configuration (default: a ready pose within limits).
        jerk_factor: jerk limit = jerk_factor * acceleration limit.
        realtime: pace the simulation with the wall clock (False: step only via :meth:`advance`).
    """

    def __init__(self, robot=None, workcell=None, *, deadman: float = 0.1, q0=None, jerk_factor: float = 20.0,
                 realtime: bool = True) -> None:
        from ruckig import InputParameter, OutputParameter, Ruckig

        from robointel.robot import Robot

        self.robot = robot or Robot.load("lrmate200id7l")
        r = self.robot
        # IK runs in the network thread: its own Pinocchio data, never shared with the control thread
        self._ik_robot = Robot(r.urdf, name=r.name, urdf_path=r.urdf_path, flange_frame=r.flange_frame, tool=r.tool)
        self._ik_lock = threading.Lock()
        if workcell is None:
            from robointel.sim import Workcell

            workcell = Workcell(self.robot, ft_sensor=False)
        self.wc = workcell
        if not (0.0 < deadman <= 5.0):
            raise InvalidInput(f"deadman must be in (0, 5] s, got {deadman}", value=deadman)
        self.deadman = float(deadman)
        n = self.robot.nq
        self.n = n
        if q0 is None:
            q0 = np.clip(np.array([0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0][:n] + [0.0] * max(0, n - 6)),
                         self.robot.lower, self.robot.upper)
        q0 = self.robot.check_q(q0, "q0", limits=True)
        self.wc.reset(q0)
        self.dt = 0.001
        self.otg = Ruckig(n, self.dt)
        self.inp, self.out = InputParameter(n), OutputParameter(n)
        self.inp.max_velocity = self.robot.velocity_limit.tolist()
        self.inp.max_acceleration = self.robot.acceleration_limit.tolist()
        self.inp.max_jerk = (jerk_factor * self.robot.acceleration_limit).tolist()
        self.inp.current_position = q0.tolist()
        self.inp.current_velocity = [0.0] * n
        self.inp.current_acceleration = [0.0] * n
        self.q_ref, self.qd_ref, self.qdd_ref = q0.copy(), np.zeros(n), np.zeros(n)
        self.mode = "idle"
        self._lock = threading.Lock()
        self._pending: Target | None = None
        self._target: Target | None = None
        self._last_valid = time.perf_counter()
        self.accepted = 0
        self.rejected = 0
        self.on_applied = None  # callback(seq, sim_time) from the control thread
        self.realtime = realtime
        self._thread: threading.Thread | None = None
        self._running = False
        self.steps = 0
        self.overruns = 0
        _LIVE.add(self)

    # ------------------------------------------------------------------ validation
    def validate(self, msg) -> tuple[str, object]:
        """Check one decoded message; return (type, payload). Raises :class:`Rejected`."""
        if not isinstance(msg, dict):
            raise Rejected("malformed", "a message must be a JSON object")
        typ = msg.get("type")
        seq = msg.get("seq")
        if seq is not None and (not isinstance(seq, int) or isinstance(seq, bool)):
            raise Rejected("malformed", "seq must be an integer")
        ack = bool(msg.get("ack", False))
        if typ == "joint_target":
            q = _numbers(msg.get("q"), self.n, "q")
            bad = np.flatnonzero((q < self.robot.lower) | (q > self.robot.upper))
            if bad.size:
                i = int(bad[0])
                raise Rejected("out_of_limits", f"q[{i}] ({self.robot.joint_names[i]}) = {q[i]:.4g} is outside "
                                                f"[{self.robot.lower[i]:.4g}, {self.robot.upper[i]:.4g}]")
            return typ, Target(q, seq, ack, time.perf_counter())
        if typ == "pose_target":
            p = _numbers(msg.get("position"), 3, "position")
            if "quaternion" in msg:
                R = _quat_to_matrix(*_numbers(msg.get("quaternion"), 4, "quaternion"))
            elif "rotation" in msg:
                rot = msg.get("rotation")
                if not isinstance(rot, list) or len(rot) != 3:
                    raise Rejected("bad_shape", "rotation must be a 3x3 list")
                R = np.array([_numbers(r, 3, "rotation row") for r in rot])
                if not np.allclose(R.T @ R, np.eye(3), atol=1e-4) or np.linalg.det(R) < 0:
                    raise Rejected("bad_shape", "rotation must be a proper rotation matrix")
            else:
                raise Rejected("bad_shape", "pose_target needs 'quaternion' [w, x, y, z] or 'rotation' 3x3")
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = R, p
            with self._lock:
                ref = (self._pending or self._target).q if (self._pending or self._target) else self.q_ref
            try:
                with self._ik_lock:
                    q = self._ik_robot.ik(T, q_ref=ref)[0]
            except IKFailure as exc:
                raise Rejected("unreachable", str(exc)) from None
            return "joint_target", Target(q, seq, ack, time.perf_counter())
        if typ in ("heartbeat", "get_state", "stop", "hello"):
            return typ, None
        if typ is None:
            raise Rejected("malformed", "a message needs a 'type'")
        raise Rejected("unknown_type", f"unknown message type {typ!r}")

    def submit(self, msg) -> dict | None:
        """Handle one decoded message: returns the reply (``error`` / ``state``) or None."""
        try:
            typ, payload = self.validate(msg)
        except Rejected as exc:
            self.rejected += 1
            return {"type": "error", "code": exc.code, "message": str(exc),
                    "seq": msg.get("seq") if isinstance(msg, dict) else None}
        if typ == "joint_target":
            with self._lock:
                self._pending = payload
                self._last_valid = payload.received
            self.accepted += 1
        elif typ == "heartbeat":
            with self._lock:
                self._last_valid = time.perf_counter()
        elif typ == "stop":
            with self._lock:
                self._last_valid = -1e9
        elif typ == "get_state":
            return self.state()
        return None

    def state(self) -> dict:
        with self._lock:
            tgt = None if self._target is None else self._target.q.tolist()
        return {"type": "state", "t": self.wc.time, "q": self.wc.q.tolist(), "qd": self.wc.qd.tolist(),
                "target": tgt, "mode": self.mode, "accepted": self.accepted, "rejected": self.rejected}

    # ------------------------------------------------------------------ control
    def advance(self, steps: int = 1) -> None:
        """Run ``steps`` 1 kHz control periods (the control thread calls this)."""
        from ruckig import ControlInterface, Result

        for _ in range(steps):
            applied = None
            now = time.perf_counter()
            with self._lock:
                if self._pending is not None:
                    self._target, self._pending = self._pending, None
                    applied = self._target
                stalled = now - self._last_valid > self.deadman
            if self._target is not None and not stalled:
                self.inp.control_interface = ControlInterface.Position
                self.inp.target_position = self._target.q.tolist()
                self.inp.target_velocity = [0.0] * self.n
                self.inp.target_acceleration = [0.0] * self.n
                self.mode = "tracking"
            elif self.mode in ("tracking", "stopping"):
                self.inp.control_interface = ControlInterface.Velocity
                self.inp.target_velocity = [0.0] * self.n
                self.inp.target_acceleration = [0.0] * self.n
                self.mode = "stopping"
            if self.mode in ("tracking", "stopping"):
                res = self.otg.update(self.inp, self.out)
                if res not in (Result.Working, Result.Finished):  # pragma: no cover - defensive
                    self.inp.control_interface = ControlInterface.Velocity
                    self.inp.target_velocity = [0.0] * self.n
                    self.mode = "stopping"
                    res = self.otg.update(self.inp, self.out)
                q = np.clip(np.array(self.out.new_position), self.robot.lower, self.robot.upper)
                qd, qdd = np.array(self.out.new_velocity), np.array(self.out.new_acceleration)
                self.out.pass_to_input(self.inp)
                if self.mode == "stopping" and np.max(np.abs(qd)) < 1e-9 and np.max(np.abs(qdd)) < 1e-9:
                    self.mode = "stopped"
                    with self._lock:
                        self._target = None
                self.q_ref, self.qd_ref, self.qdd_ref = q, qd, qdd
            else:
                self.qd_ref, self.qdd_ref = np.zeros(self.n), np.zeros(self.n)
            self.wc.track(self.q_ref, self.qd_ref, self.qdd_ref)
            self.steps += 1
            if applied is not None and applied.ack and self.on_applied is not None:
                self.on_applied(applied.seq, self.wc.time)

    def _loop(self) -> None:
        t0 = time.perf_counter()
        done = 0
        while self._running:
            due = int((time.perf_counter() - t0) / self.dt)
            k = due - done
            if k > 50:  # fell behind (machine busy): drop real time rather than burst
                self.overruns += 1
                t0 += (k - 50) * self.dt
                k = 50
            if k > 0:
                self.advance(k)
                done += k
            else:
                time.sleep(0.0003)

    def start(self) -> None:
        """Start the real-time control thread."""
        if self._thread is not None:
            return
        self._running = True
        self._thread = threading.Thread(target=self._loop, name="robointel-control", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._running = False
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None


class StreamingServer:
    """WebSocket server around a :class:`StreamingController` (runs in its own thread).

    Args:
        controller: the controller (default: a new one on the LR Mate).
        host: bind address (default 127.0.0.1); anything else needs ``token``.
        port: TCP port (0: pick a free one; see :attr:`port` after :meth:`start`).
        token: shared secret clients send in ``hello``.

    Raises:
        InvalidInput: a non-loopback ``host`` without a token (before binding).
    """

    def __init__(self, controller: StreamingController | None = None, *, host: str = "127.0.0.1", port: int = 0,
                 token: str | None = None) -> None:
        check_bind(host, token)
        self.host, self.port, self.token = host, int(port), token
        self.controller = controller or StreamingController()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._server = None
        self._ready = threading.Event()
        self._stop: asyncio.Event | None = None
        self._clients: set = set()
        self._error: BaseException | None = None

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    def _welcome(self) -> dict:
        r = self.controller.robot
        return {"type": "welcome", "protocol": PROTOCOL_VERSION, "robot": r.name, "joint_names": r.joint_names,
                "lower": r.lower.tolist(), "upper": r.upper.tolist(), "deadman": self.controller.deadman,
                "auth": self.token is not None}

    async def _handler(self, ws) -> None:
        loop = asyncio.get_running_loop()
        authed = self.token is None
        acks: dict = {}

        def on_applied(seq, t, _ws=ws):
            loop.call_soon_threadsafe(asyncio.ensure_future, self._send(_ws, {"type": "applied", "seq": seq, "t": t}))

        self._clients.add(ws)
        self.controller.on_applied = on_applied
        try:
            await ws.send(json.dumps(self._welcome()))
            async for raw in ws:
                if isinstance(raw, bytes) or len(raw) > MAX_MESSAGE_BYTES:
                    await self._send(ws, {"type": "error", "code": "malformed",
                                          "message": "send JSON text frames under 64 kB", "seq": None})
                    self.controller.rejected += 1
                    continue
                try:
                    msg = json.loads(raw, parse_constant=lambda c: float("nan"))
                except (ValueError, RecursionError):
                    self.controller.rejected += 1
                    await self._send(ws, {"type": "error", "code": "malformed", "message": "not valid JSON",
                                          "seq": None})
                    continue
                if not authed:
                    tok = msg.get("token") if isinstance(msg, dict) and msg.get("type") == "hello" else None
                    if isinstance(tok, str) and hmac.compare_digest(tok, self.token):
                        authed = True
                        continue
                    self.controller.rejected += 1
                    await self._send(ws, {"type": "error", "code": "unauthorized",
                                          "message": "send {'type': 'hello', 'token': ...} first", "seq": None})
                    await ws.close(code=1008, reason="unauthorized")
                    return
                reply = self.controller.submit(msg)
                if reply is not None:
                    await self._send(ws, reply)
        except Exception:  # connection dropped: the deadman stops the robot
            pass
        finally:
            self._clients.discard(ws)
            del acks

    @staticmethod
    async def _send(ws, obj) -> None:
        try:
            await ws.send(json.dumps(obj))
        except Exception:
            pass

    async def _main(self) -> None:
        from websockets.asyncio.server import serve

        self._stop = asyncio.Event()
        try:
            async with serve(self._handler, self.host, self.port, max_size=MAX_MESSAGE_BYTES * 2,
                             compression=None) as server:
                self._server = server
                self.port = server.sockets[0].getsockname()[1] if self.port == 0 else self.port
                for s in server.sockets:
                    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self._ready.set()
                await self._stop.wait()
        except BaseException as exc:  # bind failure etc.
            self._error = exc
            self._ready.set()

    def start(self, timeout: float = 10.0) -> "StreamingServer":
        """Start the control thread and the server thread; return when listening."""
        self.controller.start()

        def run():
            self._loop = asyncio.new_event_loop()
            self._loop.run_until_complete(self._main())
            self._loop.close()

        self._thread = threading.Thread(target=run, name="robointel-stream", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise InvalidInput("streaming server did not start in time")
        if self._error is not None:
            self.stop()
            raise InvalidInput(f"could not start the streaming server on {self.host}:{self.port}: {self._error}")
        return self

    def stop(self) -> None:
        if self._loop is not None and self._stop is not None and not self._loop.is_closed():
            try:
                self._loop.call_soon_threadsafe(self._stop.set)
            except RuntimeError:
                pass
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        self.controller.stop()

    def __enter__(self) -> "StreamingServer":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
