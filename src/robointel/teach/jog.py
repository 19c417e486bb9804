"""Jogging (as a teach pendant and MoveIt Servo do): move one joint, or the TCP along or about one axis.

Frames: ``joint`` (one joint by an angle, rad), ``world`` (the TCP along / about an axis of the robot's
base frame, m / rad), ``tool`` (along / about an axis of the TCP's own frame). A jog is a sequence of
absolute joint targets, each a small step from the last (:func:`jog_steps`), so a Cartesian jog stays
on its line and a dropped target is never an increment lost: the next one carries it.

:class:`Jogger` streams a jog to a streaming server (:mod:`robointel.teach.streaming`) with the
deadman: one target in flight at a time (the next goes out once the controller has acted on the
last), each stamped with its send time, so a busy host slows the jog down instead of letting its
targets go stale; a target refused as stale is sent again with a fresh stamp, and the result says
how often and how much the jog was slowed.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel.errors import IKFailure, InvalidInput, LimitViolation, RobointelError, SafetyStop

__all__ = ["AXES", "FRAMES", "JogResult", "Jogger", "axis_index", "jog_steps", "jog_target"]

FRAMES = ("joint", "world", "tool")
AXES = ("x", "y", "z", "rx", "ry", "rz")
MAX_JOINT_STEP = 0.5  # rad: one Cartesian step may not move a joint farther (a flip of the arm's branch)


def axis_index(frame: str, axis: str | int, n: int) -> int:
    """The index of ``axis`` in ``frame``: a joint 1..n (or its name ``J1``) or one of x y z rx ry rz.

    Raises:
        InvalidInput: an unknown frame or axis.
    """
    if frame not in FRAMES:
        raise InvalidInput(f"jog frame must be one of {FRAMES}, got {frame!r}", value=frame)
    a = str(axis).strip().lower()
    if frame == "joint":
        a = a[1:] if a.startswith("j") else a
        if not a.isdigit() or not 1 <= int(a) <= n:
            raise InvalidInput(f"a joint jog's axis is a joint 1..{n} (or J1..J{n}), got {axis!r}", value=axis)
        return int(a) - 1
    if a not in AXES:
        raise InvalidInput(f"a {frame} jog's axis is one of {', '.join(AXES)}, got {axis!r}", value=axis)
    return AXES.index(a)


def jog_target(robot: Any, q: npt.ArrayLike, frame: str, axis: int, amount: float) -> npt.NDArray[np.float64]:
    """The joint target one jog step ``amount`` away from ``q`` (rad for joints and rotations, m for translations).

    Args:
        robot: a :class:`robointel.robot.Robot`.
        q: (n,) the configuration to jog from, rad.
        frame: ``joint``, ``world`` or ``tool``.
        axis: joint index (``joint``) or 0..5 for x y z rx ry rz.
        amount: the step, rad or m (finite).

    Returns:
        (n,) the target, rad, within the joint limits (a Cartesian step: the IK solution closest to ``q``).

    Raises:
        InvalidInput: bad frame, axis or amount. LimitViolation: the target leaves the joint limits.
        IKFailure: the TCP pose is unreachable, or reachable only by moving a joint more than 0.5 rad.
    """
    q0: npt.NDArray[np.float64] = robot.check_q(np.asarray(q, float), "q")
    if not isinstance(amount, int | float | np.floating) or not math.isfinite(float(amount)):
        raise InvalidInput(f"jog amount must be a finite number, got {amount!r}", value=amount)
    if frame == "joint":
        if not 0 <= axis < robot.nq:
            raise InvalidInput(f"joint index {axis} outside 0..{robot.nq - 1}", value=axis)
        out = q0.copy()
        out[axis] += float(amount)
        if not robot.lower[axis] <= out[axis] <= robot.upper[axis]:
            raise LimitViolation(f"the jog would take {robot.joint_names[axis]} to {math.degrees(out[axis]):.2f} deg, "
                                 f"outside [{math.degrees(robot.lower[axis]):.1f}, "
                                 f"{math.degrees(robot.upper[axis]):.1f}] deg", value=out)
        return out
    if frame not in ("world", "tool") or not 0 <= axis < 6:
        raise InvalidInput(f"bad jog frame/axis {frame!r}/{axis!r}", value=(frame, axis))
    from scipy.spatial.transform import Rotation

    T = robot.fk(q0)
    d = np.zeros(3)
    d[axis % 3] = float(amount)
    G = np.eye(4)
    if axis < 3:
        G[:3, 3] = d if frame == "world" else T[:3, :3] @ d
        T2 = G @ T
    else:
        R = Rotation.from_rotvec(d).as_matrix()
        T2 = T.copy()
        T2[:3, :3] = R @ T[:3, :3] if frame == "world" else T[:3, :3] @ R  # about the TCP, in place
    try:
        sol = np.asarray(robot.ik(T2, q_ref=q0)[0], float)
    except IKFailure as exc:
        raise IKFailure(f"the jog leaves the workspace: {exc}", value=T2) from None
    if float(np.max(np.abs(sol - q0))) > MAX_JOINT_STEP:
        raise IKFailure(f"the jog step needs a joint to turn {float(np.max(np.abs(sol - q0))):.2f} rad (a flip of the "
                        "arm's configuration near a singularity); jog the joints instead", value=sol)
    return sol


def jog_steps(robot: Any, q: npt.ArrayLike, frame: str, axis: int, amount: float, *,
              step: float) -> list[npt.NDArray[np.float64]]:
    """A jog of ``amount`` as targets ``step`` apart (the last one lands on ``amount`` exactly).

    Args:
        robot: the robot.
        q: (n,) start, rad.
        frame: ``joint``, ``world`` or ``tool``.
        axis: the axis index.
        amount: the whole jog, rad or m.
        step: the largest step, rad or m (> 0).

    Returns:
        The targets, each (n,) rad.

    Raises:
        InvalidInput, LimitViolation, IKFailure: as :func:`jog_target`, for the first step that fails.
    """
    if not (math.isfinite(step) and step > 0):
        raise InvalidInput(f"jog step must be > 0, got {step!r}", value=step)
    if not math.isfinite(amount):
        raise InvalidInput(f"jog amount must be finite, got {amount!r}", value=amount)
    k = max(1, math.ceil(abs(amount) / step - 1e-9))
    out, cur = [], np.asarray(q, float)
    for _ in range(k):
        cur = jog_target(robot, cur, frame, axis, amount / k)
        out.append(cur)
    return out


@dataclass
class JogResult:
    """What a jog did.

    Attributes:
        start: (n,) the target (or the measured joints) it started from, rad.
        goal: (n,) the last target, rad.
        reached: (n,) the measured joints at the end, rad.
        sent: targets sent (a resent target counts again).
        targets: targets in the jog.
        stale: targets the server refused as stale (each was sent again).
        expired: targets accepted but never acted on before their deadman (each was sent again).
        seconds: wall time of the jog, s.
        planned_seconds: its time at the asked speed, s.
        refused: why the server refused the jog (it stopped there), or None.
    """

    start: npt.NDArray[np.float64]
    goal: npt.NDArray[np.float64]
    reached: npt.NDArray[np.float64]
    sent: int = 0
    targets: int = 0
    stale: int = 0
    expired: int = 0
    seconds: float = 0.0
    planned_seconds: float = 0.0
    refused: str | None = None
    waits_ms: list[float] = field(default_factory=list)

    @property
    def dropped(self) -> int:
        """Targets the server dropped (refused as stale or expired before it acted on them)."""
        return self.stale + self.expired

    @property
    def slowed(self) -> float:
        """How much longer the jog took than planned (1.0: on time)."""
        return self.seconds / self.planned_seconds if self.planned_seconds > 0 else 1.0


class Jogger:
    """Jog a robot through a streaming server connection (:class:`robointel.teach.stream_client.StreamClient`).

    Takes control (``acquire``) on the first jog.

    Args:
        client: a connected stream client.
        robot: the robot's model (default: ``Robot.load`` of the name the server gives).
        ack_timeout: the longest wait for the controller to act on a target, s (then it is sent again).
    """

    def __init__(self, client: Any, robot: Any = None, *, ack_timeout: float = 1.0) -> None:
        from robointel.robot import Robot

        self.client = client
        self.robot = robot or Robot.load(str(client.welcome.get("robot", "lrmate200id7l")))
        self.ack_timeout = float(ack_timeout)
        self._seq = 0
        self._acquired = False

    def _acquire(self) -> None:
        if not self._acquired:
            reply = self.client.acquire()
            if reply.get("type") == "error":
                raise SafetyStop(f"cannot take control: {reply.get('message')}", value=reply.get("code"))
            self._acquired = True

    def here(self) -> npt.NDArray[np.float64]:
        """The configuration a jog starts from: the live target, else the measured joints (n,) rad."""
        s = self.client.state()
        if s.get("type") != "state":
            raise SafetyStop(f"no state from the server: {s.get('message')}", value=s)
        return np.asarray(s["target"] if s.get("target") is not None else s["q"], float)

    def _send(self, q: npt.NDArray[np.float64], res: JogResult) -> None:
        """Send one target and wait until the controller acts on it (resent when stale or expired)."""
        while True:
            self._seq += 1
            seq = self._seq
            t0 = time.perf_counter()
            self.client.joint_target(q, seq=seq, ack=True)
            res.sent += 1
            try:
                while True:
                    m = self.client.recv("applied", timeout=self.ack_timeout)
                    if m.get("seq") == seq or (m.get("type") == "error" and m.get("seq") in (seq, None)):
                        break
            except TimeoutError:
                res.expired += 1  # accepted, then its deadman passed before the controller acted: again
                continue
            res.waits_ms.append(1e3 * (time.perf_counter() - t0))
            if m["type"] == "applied":
                return
            if m.get("code") == "stale":
                res.stale += 1
                continue
            raise SafetyStop(f"the jog was refused ({m.get('code')}): {m.get('message')}", value=m.get("code"))

    def jog(self, frame: str, axis: str | int, amount: float, *, speed: float, rate: float = 50.0,
            settle: float = 5.0, tolerance: float = 2e-4,
            progress: Callable[[int, int], None] | None = None) -> JogResult:
        """Jog by ``amount`` (rad or m) at ``speed`` (rad/s or m/s), then hold the deadman until the arm is there.

        Args:
            frame: ``joint``, ``world`` or ``tool``.
            axis: joint 1..n (``joint``) or x y z rx ry rz.
            amount: the increment, rad (joints, rotations) or m (translations).
            speed: the jog speed, rad/s or m/s (> 0).
            rate: targets per second (> 0).
            settle: the longest wait for the arm to reach the last target, s.
            tolerance: joint distance at which the arm counts as there, rad.
            progress: called with (targets sent, targets) after each target.

        Returns:
            The :class:`JogResult`; ``refused`` says why the jog stopped early, if it did.

        Raises:
            InvalidInput, LimitViolation, IKFailure: the jog cannot be made (nothing is sent then).
            SafetyStop: no control of the robot.
        """
        self._check_rates(speed, rate)
        i = axis_index(frame, axis, self.robot.nq)
        self._acquire()
        start = self.here()
        targets = jog_steps(self.robot, start, frame, i, amount, step=speed / rate)
        res = JogResult(start, targets[-1], start, targets=len(targets), planned_seconds=abs(amount) / speed)
        return self._stream(iter(targets), res, rate, settle, tolerance,
                            None if progress is None else lambda k: progress(k, len(targets)))

    def hold(self, frame: str, axis: str | int, direction: float, *, speed: float, seconds: float | None = None,
             rate: float = 50.0, settle: float = 5.0, tolerance: float = 2e-4,
             held: Callable[[], bool] | None = None) -> JogResult:
        """Jog continuously while held: at ``speed`` in the sign of ``direction`` until released.

        Released means: ``seconds`` have passed, ``held()`` returns False, or Ctrl-C. Then no new target
        goes out; the arm stops on the last one (at most one step ahead of it) under the deadman, or
        stops short at a joint limit or the edge of the workspace (``refused`` says which).

        Args:
            frame: ``joint``, ``world`` or ``tool``.
            axis: joint 1..n (``joint``) or x y z rx ry rz.
            direction: its sign gives the direction (non-zero).
            speed: rad/s or m/s (> 0).
            seconds: the longest hold, s (None: until released otherwise).
            rate: targets per second (> 0).
            settle: the longest wait for the arm to reach the last target, s.
            tolerance: joint distance at which the arm counts as there, rad.
            held: polled before each target; False releases.

        Returns:
            The :class:`JogResult`.

        Raises:
            InvalidInput: bad frame, axis, direction, speed or rate. SafetyStop: no control of the robot.
        """
        self._check_rates(speed, rate)
        if not (math.isfinite(direction) and direction != 0):
            raise InvalidInput(f"hold direction must be a non-zero number, got {direction!r}", value=direction)
        if seconds is not None and not (math.isfinite(seconds) and seconds > 0):
            raise InvalidInput(f"hold time must be > 0 s, got {seconds!r}", value=seconds)
        i = axis_index(frame, axis, self.robot.nq)
        self._acquire()
        start = self.here()
        step = math.copysign(speed / rate, direction)
        t_end = None if seconds is None else time.perf_counter() + seconds
        res = JogResult(start, start, start)

        def targets() -> Any:
            cur = start
            while (t_end is None or time.perf_counter() < t_end) and (held is None or held()):
                cur = jog_target(self.robot, cur, frame, i, step)
                res.targets += 1
                yield cur

        res = self._stream(targets(), res, rate, settle, tolerance, None)
        res.planned_seconds = res.targets / rate
        return res

    @staticmethod
    def _check_rates(speed: float, rate: float) -> None:
        if not (math.isfinite(speed) and speed > 0 and math.isfinite(rate) and rate > 0):
            raise InvalidInput(f"jog speed and rate must be > 0, got {speed!r}, {rate!r}", value=speed)

    def _stream(self, targets: Any, res: JogResult, rate: float, settle: float, tolerance: float,
                progress: Callable[[int], None] | None) -> JogResult:
        """Send the targets one at a time at ``rate`` (slower when the host is busy); then keep the last alive."""
        t0 = time.perf_counter()
        last = None
        try:
            k = 0
            try:
                for k, q in enumerate(targets, 1):
                    due = t0 + k / rate
                    self._send(q, res)
                    last = res.goal = q
                    if progress is not None:
                        progress(k)
                    time.sleep(max(0.0, due - time.perf_counter()))
            except KeyboardInterrupt:  # released: no new target; the arm stops on the last one
                pass
            except (LimitViolation, IKFailure) as exc:  # a continuous jog ran into a limit: stop there
                res.refused = str(exc)
            res.seconds = time.perf_counter() - t0
            end = time.monotonic() + settle
            while last is not None and time.monotonic() < end:  # the deadman: keep the last target alive
                s = self.client.state()
                if float(np.max(np.abs(np.asarray(s["q"]) - last))) <= tolerance:
                    break
                if s.get("target") is None:  # stopped (deadman, stop): send the last target again
                    self._send(last, res)
                else:
                    self.client.send({"type": "heartbeat"})
                time.sleep(0.02)
        except RobointelError as exc:
            res.refused = str(exc)
            res.seconds = res.seconds or time.perf_counter() - t0
        res.reached = np.asarray(self.client.state()["q"], float)
        return res
