"""The robot side of the streaming interface: a 1 kHz control thread over the MuJoCo workcell.

It has the jerk-limited follower of :mod:`robointel.control` (``ruckig``), one commanding client, a
latched stop and a deadman that counts from the client's send time (protocol:
:mod:`robointel.teach.streaming`).

Between targets the generator moves the reference within the joint velocity, acceleration and jerk
limits; the workcell's joint controller tracks it. A target reaches the generator only after the
checks of :meth:`StreamingController.command`: the sender holds control, the stop is not latched,
the target is fresh (sent less than ``deadman`` ago), inside the joint limits and the straight
joint-space move to it is clear of the table, the floor and the robot itself
(:class:`~robointel.teach.collision_guard.CollisionGuard`).

With a robot interface (``interface=open_robot("sim" | "fanuc://HOST")``) the loop runs at the
interface's period and streams the follower's reference to it instead of stepping a workcell: the
same teleoperation stream drives the simulated cell or a FANUC controller. A fault the interface
reports (e-stop, stalled link, refused command) stops the commanding at once and latches; the
state says why, and ``resume`` recovers the interface once the cause is cleared.
"""
from __future__ import annotations

import atexit
import contextlib
import threading
import time
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robointel.control import JerkLimitedFollower
from robointel.errors import IKFailure, InvalidInput, RobointelError, SafetyStop, SolverFailure, TargetInCollision
from robointel.interface.realtime import realtime_thread
from robointel.robot import Robot
from robointel.sim import Workcell
from robointel.teach.collision_guard import CollisionGuard
from robointel.teach.stream_protocol import Rejected, flag, numbers, pose, sequence

if TYPE_CHECKING:  # pragma: no cover
    from robointel.interface.protocol import RobotInterface

_LIVE: weakref.WeakSet[StreamingController] = weakref.WeakSet()
LOCAL = "local"  # the client id of in-process callers (the teleoperation page uses its own)


@atexit.register
def _release_generators() -> None:
    """Join the control threads still running at exit, drop the followers (ruckig) of live controllers.

    A daemon thread left inside MuJoCo when the interpreter finalises would crash it.
    """
    for c in list(_LIVE):
        c.stop()
        with contextlib.suppress(AttributeError):
            del c.follower


@dataclass
class Target:
    """A checked joint target on its way to the generator.

    Attributes:
        q: (n,) joint positions, rad.
        seq: the client's sequence number (None if not given).
        ack: send an ``applied`` reply when the controller first acts on it.
        sent: the client's send time on the server clock (``time.perf_counter``), s.
        client: id of the client that sent it.
    """

    q: npt.NDArray[np.float64]
    seq: int | None
    ack: bool
    sent: float
    client: str


class StreamingController:
    """A real-time 1 kHz loop over a ``Workcell``: ruckig generator, deadman, one owner, latched stop.

    Usable without the network (:meth:`submit`, :meth:`advance`).

    Args:
        robot: a :class:`robointel.robot.Robot` (default: the LR Mate).
        workcell: a ``robointel.sim.Workcell`` of the robot (default: built here, with its table).
        deadman: the longest time [s] a target or heartbeat keeps the robot moving after the client
            sent it; then the robot decelerates to a stop.
        q0: (n,) initial configuration, rad (default: a ready pose within limits).
        jerk_factor: jerk limit = jerk_factor * acceleration limit.
        realtime: pace the simulation with the wall clock (False: step only via :meth:`advance`).
        guard: the environment check of every target (default: the workcell's table and floor and
            self-collision, :class:`CollisionGuard`).
        interface: a robot interface to stream to at its period instead of stepping ``workcell``
            (:func:`robointel.interface.open_robot`); the robot starts where the interface reports it.
            A paced interface (a controller) is streamed to only while a target moves the arm; idle
            or stopped it is told to hold once.

    Raises:
        InvalidInput: ``deadman`` outside (0, 5] s, ``q0`` outside the limits or in collision, both a
            workcell and an interface, ``q0`` with an interface, or an interface with another joint count.
    """

    def __init__(self, robot: Any = None, workcell: Any = None, *, deadman: float = 0.1,
                 q0: npt.ArrayLike | None = None, jerk_factor: float = 20.0, realtime: bool = True,
                 guard: CollisionGuard | None = None, interface: RobotInterface | None = None) -> None:
        if not (0.0 < deadman <= 5.0):
            raise InvalidInput(f"deadman must be in (0, 5] s, got {deadman}", value=deadman)
        self.robot = robot or Robot.load("lrmate200id7l")
        r = self.robot
        # IK and collision checks run in worker threads: their own Pinocchio data, never the control thread's
        self._ik_robot = Robot(r.urdf, name=r.name, urdf_path=r.urdf_path, flange_frame=r.flange_frame, tool=r.tool)
        self._ik_lock = threading.Lock()
        self.guard = guard or CollisionGuard(r)
        self._guard_lock = threading.Lock()
        self.interface = interface
        self.fault: str | None = None  # why the interface stopped the robot (latched until resume)
        n = self.n = self.robot.nq
        if interface is not None:
            if workcell is not None or q0 is not None:
                raise InvalidInput("give a workcell and q0, or a robot interface (the robot starts where it is), "
                                   "not both", value=q0)
            if len(interface.joint_names) != n:
                raise InvalidInput(f"the robot interface has {len(interface.joint_names)} joints, the robot {n}",
                                   value=interface.joint_names)
            workcell = getattr(interface, "workcell", None)  # the sim backend's workcell (None on a real robot)
            st = interface.state()
            q0 = st.q_cmd if st.q_cmd is not None else st.q
        elif workcell is None:
            workcell = Workcell(self.robot, ft_sensor=False)
        self.wc = workcell
        self.deadman = float(deadman)
        if q0 is None:
            q0 = np.clip(np.array([0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0][:n] + [0.0] * max(0, n - 6)),
                         self.robot.lower, self.robot.upper)
        q0 = self.robot.check_q(q0, "q0", limits=True)
        with self._guard_lock:
            self.guard.check(q0, "q0")
        if interface is None:
            self.wc.reset(q0)
        self.dt = 0.001 if interface is None else float(interface.period)
        self.follower = JerkLimitedFollower(self.robot.velocity_limit, self.robot.acceleration_limit,
                                            jerk_factor * self.robot.acceleration_limit, dt=self.dt,
                                            lower=self.robot.lower, upper=self.robot.upper)
        self.follower.reset(q0)
        self.q_ref, self.qd_ref, self.qdd_ref = q0.copy(), np.zeros(n), np.zeros(n)
        self.mode = "idle"
        self._lock = threading.Lock()
        self._pending: Target | None = None
        self._target: Target | None = None
        self._deadline = -np.inf       # server time after which the current target no longer moves the robot
        self._drop_target = False      # begin a stop at the next control period
        self.owner: str | None = None  # the client in control
        self.latched = False           # a stop holds until the owner sends resume
        self.accepted = 0
        self.rejected = 0
        self.stop_began: float | None = None  # perf_counter time the last stop began
        self.rest_at: float | None = None     # ... and when the robot was at rest again
        self.on_applied: Callable[[Target, float], None] | None = None  # (target, sim time), control thread
        self.realtime = realtime
        self._paced = bool(getattr(interface, "paced", False))  # a controller holds by itself between streams
        self._held = False  # the interface was told to hold (idle or stopped): streaming resumes with a target
        self._thread: threading.Thread | None = None
        self._running = False
        self.steps = 0
        self.overruns = 0
        _LIVE.add(self)

    # ------------------------------------------------------------------ control of the robot
    def acquire(self, client: str) -> None:
        """Make ``client`` the one commanding client.

        Raises:
            Rejected: ``control_held`` when another client holds control.
        """
        with self._lock:
            if self.owner not in (None, client):
                raise Rejected("control_held", "another client holds control; this connection is read-only until "
                                               "it sends release or disconnects")
            self.owner = client

    def release(self, client: str) -> None:
        """Give up control (nothing if ``client`` does not hold it); the robot decelerates to a stop."""
        with self._lock:
            if self.owner == client:
                self.owner = None
                self._pending = None
                self._drop_target = True

    def drop(self, client: str) -> None:
        """Forget the target of ``client`` when it holds control (its stream can no longer be trusted)."""
        with self._lock:
            if self.owner == client:
                self._pending = None
                self._drop_target = True

    def emergency_stop(self) -> None:
        """Decelerate to a stop now and latch.

        No target, heartbeat or client moves the robot until the client in control sends :meth:`resume`.
        """
        with self._lock:
            self.latched = True
            self._pending = None
            self._drop_target = True

    def resume(self, client: str) -> None:
        """Clear a latched stop. The robot stays where it stopped until a new target arrives.

        After a fault of the robot interface, the interface is recovered first.

        Raises:
            Rejected: ``not_in_control`` when ``client`` does not hold control; ``fault`` when the robot
                interface still reports the fault.
        """
        with self._lock:
            if self.owner != client:
                raise Rejected("not_in_control", "only the client in control may resume; send acquire first")
            if self.fault is not None and self.interface is not None:
                try:
                    self.interface.recover()
                except RobointelError as exc:
                    raise Rejected("fault", f"the robot still reports a fault: {exc}") from None
                st = self.interface.state()
                q = st.q_cmd if st.q_cmd is not None else st.q
                self.follower.reset(q)
                self.q_ref, self.qd_ref, self.qdd_ref = q.copy(), np.zeros(self.n), np.zeros(self.n)
                self.fault, self.mode = None, "stopped"
            self.latched = False

    def may_command(self, client: str, sent: float, now: float) -> None:
        """Cheap checks of a target or heartbeat before any heavy work.

        Args:
            client: the sender's id.
            sent: its send time on the server clock, s.
            now: the server time, s.

        Raises:
            Rejected: ``stopped`` (latched), ``not_in_control`` or ``stale`` (older than the deadman).
        """
        if self.latched:
            raise Rejected("stopped", "the robot is stopped (latched): the client in control must send resume")
        if self.owner != client:
            raise Rejected("not_in_control", "send acquire first (one client commands the robot at a time)")
        if now - sent > self.deadman:
            raise Rejected("stale", f"target sent {1e3 * (now - sent):.0f} ms ago, older than the deadman "
                                    f"({1e3 * self.deadman:.0f} ms): dropped")

    def solve_pose(self, T: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """IK of a TCP pose (4x4, robot root frame) closest to the current target (worker thread).

        Raises:
            Rejected: ``unreachable``.
        """
        with self._lock:
            cur = self._pending or self._target
            ref = cur.q if cur is not None else self.q_ref
        try:
            with self._ik_lock:
                return np.asarray(self._ik_robot.ik(T, q_ref=ref)[0], float)
        except IKFailure as exc:
            raise Rejected("unreachable", str(exc)) from None

    def command(self, q: npt.NDArray[np.float64], *, client: str, sent: float, seq: int | None = None,
                ack: bool = False, guard: CollisionGuard | None = None) -> None:
        """Hand a joint target (n,) rad to the generator after every check (worker thread).

        Args:
            q: (n,) joint target, rad, finite.
            client: the sender's id; it must hold control.
            sent: the client's send time on the server's ``perf_counter`` clock, s.
            seq: the client's sequence number.
            ack: reply ``applied`` when the controller first acts on it.
            guard: a collision guard owned by the calling thread (default: the controller's, locked).

        Raises:
            Rejected: ``stopped``, ``not_in_control``, ``stale``, ``out_of_limits`` or ``collision``
                (naming the link); nothing reaches the controller then.
        """
        self.may_command(client, sent, time.perf_counter())
        bad = np.flatnonzero((q < self.robot.lower) | (q > self.robot.upper))
        if bad.size:
            i = int(bad[0])
            raise Rejected("out_of_limits", f"q[{i}] ({self.robot.joint_names[i]}) = {q[i]:.4g} is outside "
                                            f"[{self.robot.lower[i]:.4g}, {self.robot.upper[i]:.4g}]")
        with self._lock:
            cur = self._pending or self._target
            same = cur is not None and np.array_equal(cur.q, q)  # the move to it is being checked/followed
        if not same:
            try:
                if guard is not None:
                    guard.check_motion(self.q_ref.copy(), q)
                else:
                    with self._guard_lock:
                        self.guard.check_motion(self.q_ref.copy(), q)
            except TargetInCollision as exc:
                raise Rejected("collision", str(exc)) from None
        with self._lock:
            self.may_command(client, sent, time.perf_counter())  # again: a stop may have come meanwhile
            self._pending = Target(q, seq, ack, sent, client)
            self._deadline = sent + self.deadman
        self.accepted += 1

    def heartbeat(self, client: str, sent: float) -> None:
        """Keep the current target alive until ``sent + deadman``; never restarts a stopped robot.

        Raises:
            Rejected: ``stopped``, ``not_in_control`` or ``stale``.
        """
        with self._lock:
            self.may_command(client, sent, time.perf_counter())
            if self._target is not None or self._pending is not None:
                self._deadline = max(self._deadline, sent + self.deadman)

    def submit(self, msg: Any, *, client: str = LOCAL, sent: float | None = None) -> dict[str, Any] | None:
        """Handle one decoded message in-process (IK inline): the reply (``error``/``state``/``ok``) or None.

        Args:
            msg: the decoded JSON message.
            client: the sender's id (acquire control with ``{"type": "acquire"}`` first).
            sent: its send time on the ``perf_counter`` clock (default: now).
        """
        sent = time.perf_counter() if sent is None else sent
        seq = msg.get("seq") if isinstance(msg, dict) and isinstance(msg.get("seq"), int) else None
        try:
            if not isinstance(msg, dict):
                raise Rejected("malformed", "a message must be a JSON object")
            typ = msg.get("type")
            seq = sequence(msg)
            if typ in ("joint_target", "pose_target"):
                ack = flag(msg, "ack")
                if typ == "joint_target":
                    q = numbers(msg.get("q"), self.n, "q")
                else:
                    T = pose(msg)
                    self.may_command(client, sent, time.perf_counter())
                    q = self.solve_pose(T)
                self.command(q, client=client, sent=sent, seq=seq, ack=ack)
                return None
            if typ == "heartbeat":
                self.heartbeat(client, sent)
                return None
            if typ == "get_state":
                return self.state(client)
            if typ == "stop":
                self.emergency_stop()
            elif typ == "resume":
                self.resume(client)
            elif typ == "acquire":
                self.acquire(client)
            elif typ == "release":
                self.release(client)
            elif typ == "hello":
                pass
            elif typ is None:
                raise Rejected("malformed", "a message needs a 'type'")
            else:
                raise Rejected("unknown_type", f"unknown message type {str(typ)[:40]!r}")
            return {"type": "ok", "of": typ, "seq": seq, "in_control": self.owner == client, "latched": self.latched}
        except Rejected as exc:
            self.rejected += 1
            return {"type": "error", "code": exc.code, "message": str(exc), "seq": seq}

    def measured(self) -> tuple[float, npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The robot's time (s), joint positions (n,) rad and velocities (n,) rad/s: workcell or interface."""
        if self.interface is not None:
            st = self.interface.state()
            return st.t, np.asarray(st.q, float), np.asarray(st.qd, float)
        return self.wc.time, self.wc.q, self.wc.qd

    def state(self, client: str | None = None) -> dict[str, Any]:
        """The ``state`` reply: time, joints, target, mode, latch, control, counters and the fault if any."""
        with self._lock:
            tgt = None if self._target is None else self._target.q.tolist()
            owner = self.owner
        t, q, qd = self.measured()
        return {"type": "state", "t": t, "q": q.tolist(), "qd": qd.tolist(),
                "target": tgt, "mode": self.mode, "latched": self.latched, "in_control": owner is not None
                and owner == client, "controlled": owner is not None, "accepted": self.accepted,
                "rejected": self.rejected, "fault": self.fault}

    # ------------------------------------------------------------------ 1 kHz loop
    def advance(self, steps: int = 1) -> None:
        """Run ``steps`` 1 kHz control periods (the control thread calls this)."""
        for _ in range(steps):
            applied = None
            now = time.perf_counter()
            with self._lock:
                if self._pending is not None:
                    self._target, self._pending = self._pending, None
                    applied = self._target
                if self._target is not None and (self._drop_target or now > self._deadline or self.latched):
                    self._target = applied = None  # a stop forgets the target: only a new target moves again
                    self.stop_began, self.rest_at = now, None
                self._drop_target = False
                target = self._target
            if target is not None:
                self.mode = "tracking"
            elif self.mode in ("tracking", "stopping"):
                self.mode = "stopping"
            if self.mode in ("tracking", "stopping"):
                try:
                    q, qd, qdd = (self.follower.step_position(target.q) if target is not None
                                  else self.follower.brake())
                except SolverFailure:  # pragma: no cover - defensive: brake instead
                    self.mode = "stopping"
                    q, qd, qdd = self.follower.brake()
                if self.mode == "stopping" and self.follower.at_rest:
                    self.mode = "stopped"
                    self.rest_at = now
                self.q_ref, self.qd_ref, self.qdd_ref = q, qd, qdd
            else:
                self.qd_ref, self.qdd_ref = np.zeros(self.n), np.zeros(self.n)
            if self.interface is None:
                self.wc.track(self.q_ref, self.qd_ref, self.qdd_ref)
                t_robot = self.wc.time
            elif self.fault is None:
                if self.mode not in ("tracking", "stopping") and self._paced:
                    if not self._held:  # at rest with no target: the controller holds, nothing to stream
                        self.interface.hold()
                        self._held = True
                    self.steps += 1
                    continue
                try:
                    t_robot = self.interface.stream(self.q_ref).t
                    self._held = False
                except SafetyStop as exc:  # e-stop, fault, lost link, refused target: stop commanding now
                    self._interface_fault(str(exc))
                    continue
            else:
                continue  # faulted: nothing is sent until resume() recovers the interface
            self.steps += 1
            if applied is not None and applied.ack and self.on_applied is not None:
                self.on_applied(applied, t_robot)

    def _interface_fault(self, why: str) -> None:
        """Latch a fault the robot interface reported; the reference rests where the robot is."""
        assert self.interface is not None
        with self._lock:
            self.latched = True
            self._pending = self._target = None
        self.fault = why
        q = np.asarray(self.interface.state().q, float)
        self.follower.reset(q)
        self.q_ref, self.qd_ref, self.qdd_ref = q.copy(), np.zeros(self.n), np.zeros(self.n)
        self.mode = "faulted"
        self.stop_began, self.rest_at = time.perf_counter(), None

    def _loop(self) -> None:
        if self.interface is None:
            self._run_loop()
            return
        # not low_latency(): this thread shares the interpreter lock with the server's and the page's threads,
        # and the interface's look-ahead queue is what absorbs their stalls (docs/design/streaming.md)
        with realtime_thread():
            self._run_loop()

    def _run_loop(self) -> None:
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
        """Stop (join) the control thread; the simulated robot stays where it is."""
        self._running = False
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
