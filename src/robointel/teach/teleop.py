"""Browser teleoperation (Ch. 3.4): a ``viser`` page replaces the VR headset.

The page (:mod:`robointel.teach.teleop_page`) shows the robot, the table and the obstacles. A
transform gizmo is the operator's hand: every move is solved by IK (closest to the current target);
a reachable pose is streamed to the robot through the same validated path as the WebSocket
interface (:class:`~robointel.teach.streaming.StreamingController`), an unreachable one is shown in
red and **not sent**. The hand can also be typed as a position (m) and roll/pitch/yaw (deg), single
joints moved with sliders, and the arm jogged (joint, world or tool frame, by a step or while a
button is held) at a jog speed. Waypoints are recorded, listed, edited, deleted, replayed on the
robot and saved as a YAML scene that ``robointel plan`` loads (:func:`save_program` /
:func:`load_program`).

Sessions: every browser is its own session. With a token, a session sees a login prompt only --
nothing about the robot, no command -- until the token is typed into it; the token is checked on
the server, never echoed and never shown to another session. Without a token (loopback binds only)
each browser session is logged in.

While a target is live and a logged-in page is connected, the app keeps streaming it at
``stream_hz``, so the controller's deadman (100 ms) stops the robot when the last such page closes
or its link stalls. A jog is streamed as steps at the jog speed: a busy host delays the steps (the
jog slows down, the page says so); none is dropped.
"""
from __future__ import annotations

import collections
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel._extras import needs_extra
from robointel._validate import as_array
from robointel.errors import IKFailure, InvalidInput, RobointelError
from robointel.robot import Robot
from robointel.teach.jog import jog_steps
from robointel.teach.stream_session import same_token
from robointel.teach.streaming import StreamingController, check_bind
from robointel.teach.teleop_page import PageSession, quat_matrix
from robointel.teach.teleop_program import (  # noqa: F401 (the page's file API)
    PROGRAM_FORMAT,
    load_program,
    save_program,
    shape_to_dict,
)

__all__ = ["PROGRAM_FORMAT", "TeleopApp", "load_program", "save_program", "shape_to_dict"]

class TeleopApp:
    """The teleoperation page on a streaming controller.

    Args:
        controller: a started or not yet started :class:`StreamingController` (owns the robot).
        host: where the page is served (127.0.0.1 by default; others need ``token``, which each
            browser session must then type before it sees or commands the robot).
        port: the page's port.
        obstacles: robointel.geometry shapes drawn in the scene and saved with the program.
        program_path: where "Save program" writes.
        stream_hz: keep-alive streaming rate of the live target.
        reach_tol: joint distance [rad] at which a replayed waypoint counts as reached.
        token: the shared secret (>= 16 printable characters).

    Raises:
        InvalidInput: a non-loopback host without a token, a malformed token or a bad port.
    """

    def __init__(self, controller: StreamingController, *, host: str = "127.0.0.1", port: int = 8080,
                 obstacles: Sequence[Any] = (), program_path: str | Path = "teleop_program.yaml",
                 stream_hz: float = 50.0, reach_tol: float = 2e-3, token: str | None = None) -> None:
        check_bind(host, token)
        if isinstance(port, bool) or not isinstance(port, int | np.integer) or not 0 <= int(port) <= 65535:
            raise InvalidInput(f"port must be an integer in 0..65535, got {port!r}", value=port)
        self.controller = controller
        r = controller.robot
        self.robot = Robot(r.urdf, name=r.name, urdf_path=r.urdf_path, flange_frame=r.flange_frame, tool=r.tool)
        self.host, self.port, self.token = host, int(port), token
        self.obstacles = list(obstacles)
        self.program_path = Path(program_path)
        self.stream_hz = float(stream_hz)
        self.reach_tol = float(reach_tol)
        self.waypoints: list[np.ndarray] = []
        self.desired: np.ndarray | None = None
        self.reachable = True
        self.sent = 0
        self.unreachable_moves = 0
        self.replaying = False
        self._lock = threading.RLock()
        self._running = False
        self._threads: list[threading.Thread] = []
        self.server: Any = None  # the viser.ViserServer once started
        self.sessions: dict[int, Any] = {}  # viser client id -> PageSession
        self.client = "teleop-page"  # the page's client id at the controller (it acquires control to move)
        self.refused = 0
        self.last_error: str | None = None
        self.status = "ready"
        self._ramp: collections.deque[np.ndarray] = collections.deque()  # jog steps still to stream
        self.jog_late = 0  # jog steps streamed more than 0.1 s late (a busy host)

    # ------------------------------------------------------------------ logic (no browser needed)
    def check_token(self, given: Any) -> bool:
        """True when ``given`` is the page's token (always without one); constant-time."""
        return self.token is None or (isinstance(given, str) and same_token(given, self.token))

    def reference(self) -> np.ndarray:
        """Where the next move starts from: the live target, else the controller's reference (n,) rad."""
        with self._lock:
            return (self._ramp[-1] if self._ramp else self.desired if self.desired is not None
                    else self.controller.q_ref).copy()

    def move_hand(self, position: npt.ArrayLike, wxyz: npt.ArrayLike) -> bool:
        """The operator's hand moved: IK closest to the current target; stream it when reachable.

        Args:
            position: (3,) hand position, m, robot root frame.
            wxyz: (4,) hand orientation quaternion [w, x, y, z].

        Returns:
            Whether the pose is reachable and was accepted (unreachable poses are never sent).

        Raises:
            ShapeError, NotFinite: bad position or quaternion.
        """
        p = as_array(position, "position", (3,))
        R = quat_matrix(as_array(wxyz, "wxyz", (4,)))
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, p
        with self._lock:
            try:
                q = self.robot.ik(T, q_ref=self.reference())[0]
            except IKFailure:
                self.reachable = False
                self.unreachable_moves += 1
                self._say("UNREACHABLE: not sent")
                return False
            self.reachable = True
            if self.replaying:
                return True
            self._ramp.clear()
            if not self._send(q):  # refused (table, floor, self-collision, control): not kept either
                return False
            self.desired = q
        self._say("reachable: streaming")
        return True

    def move_joint(self, index: int, value: float) -> bool:
        """Move one joint to ``value`` rad (the others keep the current target); True when accepted.

        Raises:
            InvalidInput: a joint index outside 0..n-1 or a value that is not finite.
        """
        if not (isinstance(index, int | np.integer) and 0 <= index < self.robot.nq):
            raise InvalidInput(f"joint index must be in 0..{self.robot.nq - 1}, got {index!r}", value=index)
        if not np.isfinite(value):
            raise InvalidInput(f"joint value must be finite, got {value!r}", value=value)
        with self._lock:
            if self.replaying:
                return False
            q = self.reference()
            q[int(index)] = float(value)
            self._ramp.clear()
            if not self._send(q):
                return False
            self.desired = q
        return True

    def jog(self, frame: str, axis: int, amount: float, *, speed: float, lead: float | None = None) -> int:
        """Jog by ``amount`` (rad or m) from the current target at ``speed`` (rad/s or m/s).

        The jog's steps (one per keep-alive period) are streamed by the page's stream thread; more
        steps queue behind those not yet streamed (a button held down keeps adding them).

        Args:
            frame: ``joint``, ``world`` or ``tool``.
            axis: the joint index, or 0..5 for x y z rx ry rz.
            amount: the increment, rad or m.
            speed: rad/s or m/s (> 0).
            lead: with a queue already this many seconds of steps long, nothing is added (a held
                button: the arm stops at most ``lead`` after the release); None: no bound.

        Returns:
            The number of steps queued.

        Raises:
            InvalidInput, LimitViolation, IKFailure: the jog cannot be made (nothing is queued then).
        """
        if not (np.isfinite(speed) and speed > 0):
            raise InvalidInput(f"jog speed must be > 0, got {speed!r}", value=speed)
        with self._lock:
            if self.replaying or (lead is not None and len(self._ramp) >= lead * self.stream_hz):
                return 0
            steps = jog_steps(self.robot, self.reference(), frame, axis, amount, step=speed / self.stream_hz)
            self._ramp.extend(steps)
            self._say(f"jogging: {len(self._ramp)} steps to go")
        return len(steps)

    def _send(self, q: npt.ArrayLike) -> bool:
        """Stream a joint target through the controller's checks; True when the controller accepted it.

        The checks: control, latch, limits, table, floor and self-collision; a refusal is shown on
        the page and nothing moves.
        """
        if self.controller.owner != self.client:
            reply = self.controller.submit({"type": "acquire"}, client=self.client)
            if reply is not None and reply["type"] == "error":
                self.last_error = reply["message"]
                self._say(f"not sent: {reply['message']}")
                return False
        reply = self.controller.submit({"type": "joint_target", "q": [float(v) for v in np.asarray(q, float)]},
                                       client=self.client)
        if reply is None:
            self.sent += 1
            return True
        self.refused += 1
        self.last_error = reply["message"]
        self._say(f"not sent ({reply['code']}): {reply['message']}")
        return False

    def emergency_stop(self) -> None:
        """Stop the robot now and latch (any session may; :meth:`resume` clears it)."""
        with self._lock:
            self._ramp.clear()
            self.desired = None
        self.controller.emergency_stop()
        self._say("STOPPED: press Resume to move again")

    def resume(self) -> bool:
        """Clear a stop (the robot stays where it stopped until a new target); True when cleared."""
        if self.controller.owner != self.client:
            self.controller.submit({"type": "acquire"}, client=self.client)
        reply = self.controller.submit({"type": "resume"}, client=self.client)
        ok = reply is not None and reply["type"] == "ok"
        self._say("resumed" if ok else f"not resumed: {reply and reply.get('message')}")
        return ok

    def record(self) -> int:
        """Record the current target (or the robot's pose) as a waypoint; returns the count."""
        with self._lock:
            q = self.desired if self.desired is not None else self.controller.measured()[1]
            self.waypoints.append(np.array(q, float))
            n = len(self.waypoints)
        self._refresh()
        return n

    def _index(self, i: int) -> int:
        if not (isinstance(i, int | np.integer) and 0 <= i < len(self.waypoints)):
            raise InvalidInput(f"no waypoint {i!r}: there are {len(self.waypoints)}", value=i)
        return int(i)

    def edit(self, i: int, q: npt.ArrayLike) -> None:
        """Replace waypoint ``i`` with ``q`` (n,) rad (within the limits, clear of the table and the robot).

        Raises:
            InvalidInput: no such waypoint; a bad, out-of-limit or colliding configuration.
        """
        q = self.robot.check_q(np.asarray(q, float), f"waypoint {i}", limits=True)
        try:
            with self.controller._guard_lock:
                self.controller.guard.check(q, f"waypoint {i}")
        except RobointelError as exc:
            raise InvalidInput(str(exc), value=q) from None
        with self._lock:
            self.waypoints[self._index(i)] = q.copy()
        self._refresh()

    def delete(self, i: int) -> None:
        """Delete waypoint ``i``.

        Raises:
            InvalidInput: no such waypoint.
        """
        with self._lock:
            del self.waypoints[self._index(i)]
        self._refresh()

    def go_to(self, i: int) -> bool:
        """Stream waypoint ``i`` as the live target; True when accepted.

        Raises:
            InvalidInput: no such waypoint.
        """
        with self._lock:
            q = self.waypoints[self._index(i)].copy()
            self._ramp.clear()
            if not self._send(q):
                return False
            self.desired = q
        return True

    def clear(self) -> None:
        """Forget the recorded waypoints."""
        with self._lock:
            self.waypoints.clear()
        self._refresh()

    def save(self, path: str | Path | None = None) -> Path:
        """Save the recorded program with :func:`save_program` (default: ``program_path``); returns the path.

        Raises:
            InvalidInput: fewer than 2 waypoints.
        """
        p = save_program(path or self.program_path, self.robot, self.waypoints, obstacles=self.obstacles)
        self._say(f"saved {len(self.waypoints)} waypoints to {p} (robointel plan {p})")
        return p

    def replay(self, *, timeout_per_waypoint: float = 10.0, dwell: float = 0.2) -> list[float]:
        """Drive the robot through the recorded waypoints (streaming each until reached).

        Args:
            timeout_per_waypoint: the longest time spent streaming one waypoint, s.
            dwell: time a waypoint must stay reached before the next, s.

        Returns:
            The joint error (max over joints), rad, at each waypoint when it was left.
        """
        with self._lock:
            program = [w.copy() for w in self.waypoints]
            self.replaying = True
            self._ramp.clear()
        errors = []
        try:
            for i, w in enumerate(program):
                self._say(f"replay: waypoint {i + 1}/{len(program)}")
                t_end = time.monotonic() + timeout_per_waypoint
                reached_at = None
                while time.monotonic() < t_end:
                    with self._lock:
                        self.desired = w
                    self._send(w)
                    err = float(np.max(np.abs(self.controller.measured()[1] - w)))
                    if err < self.reach_tol and reached_at is None:
                        reached_at = time.monotonic()
                    if reached_at is not None and time.monotonic() - reached_at >= dwell:
                        break
                    time.sleep(1.0 / self.stream_hz)
                errors.append(float(np.max(np.abs(self.controller.measured()[1] - w))))
            self._say(f"replayed {len(program)} waypoints, max error {max(errors, default=0.0):.2e} rad")
        finally:
            with self._lock:
                self.replaying = False
        return errors

    # ------------------------------------------------------------------ sessions
    def _say(self, text: str) -> None:
        self.status = text
        for s in list(self.sessions.values()):
            s.show_status(text)

    def _refresh(self) -> None:
        for s in list(self.sessions.values()):
            s.show_waypoints()

    def logged_in(self) -> list[Any]:
        """The sessions that have authenticated."""
        return [s for s in list(self.sessions.values()) if s.authed]

    def _display_loop(self) -> None:
        while self._running:
            sessions = self.logged_in()
            if sessions:
                q = self.controller.measured()[1]
                poses = self.robot.link_poses(q)
                with self._lock:
                    target = self.desired
                for s in sessions:
                    s.show_robot(poses, q, target)
            time.sleep(1 / 30)

    def _stream_loop(self) -> None:
        """Keep the live target alive (and stream jog steps) while a logged-in browser is connected.

        When the last such page closes (or its link dies) the stream stops and the controller's
        deadman brings the robot to rest.
        """
        period = 1.0 / self.stream_hz
        due = time.perf_counter()
        while self._running:
            due += period
            late = time.perf_counter() - due
            q: np.ndarray | None
            with self._lock:
                if self._ramp and not self.replaying:
                    if late > 0.1:
                        self.jog_late += 1
                        self._say(f"jog slowed: the host is busy ({1e3 * late:.0f} ms late)")
                    step = self._ramp.popleft()
                    if self._send(step):
                        self.desired = step
                    else:
                        self._ramp.clear()
                    q = None
                else:
                    q = None if (self.replaying or self.desired is None) else self.desired.copy()
            if q is not None and self.logged_in():
                self._send(q)
            due = max(due, time.perf_counter() - period)
            time.sleep(max(0.0, due + period - time.perf_counter()))

    def start(self) -> TeleopApp:
        """Serve the page (viser), start the controller's control thread and the display and stream threads."""
        with needs_extra("teleop", "browser teleoperation"):
            import viser

        self.server = viser.ViserServer(host=self.host, port=self.port, verbose=False)
        self.port = self.server.get_port()

        @self.server.on_client_connect
        def _connect(client: Any) -> None:
            session = PageSession(self, client)
            self.sessions[client.client_id] = session
            session.begin()

        @self.server.on_client_disconnect
        def _disconnect(client: Any) -> None:
            self.sessions.pop(client.client_id, None)

        self.controller.start()
        self._running = True
        for fn in (self._display_loop, self._stream_loop):
            t = threading.Thread(target=fn, daemon=True)
            t.start()
            self._threads.append(t)
        return self

    @property
    def url(self) -> str:
        """The page's address."""
        return f"http://{self.host}:{self.port}"

    def stop(self) -> None:
        """Stop the display and stream threads and the page server (the controller keeps running)."""
        self._running = False
        for t in self._threads:
            t.join(timeout=2.0)
        self._threads.clear()
        if self.server is not None:
            self.server.stop()
            self.server = None
        self.sessions.clear()
        self.controller.release(self.client)
