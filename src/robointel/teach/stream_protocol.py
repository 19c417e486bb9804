"""Message checks of the streaming protocol (see :mod:`robointel.teach.streaming`).

Numbers, poses and flags of one decoded JSON message, the client's send clock and per-client rate
limits.

Everything here is cheap (no kinematics) and runs on the server's event loop; inverse kinematics
and collision checks run in the controller's worker thread.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

#: Version of the message schema; the only thing a server with a token tells before ``hello``.
PROTOCOL_VERSION = 2
#: Largest accepted text frame, bytes.
MAX_MESSAGE_BYTES = 64 * 1024
#: Message types a client may send.
MESSAGE_TYPES = ("hello", "acquire", "release", "joint_target", "pose_target", "heartbeat", "get_state", "stop",
                 "resume")
#: Types that need the client's send time ``t``.
TIMED_TYPES = ("joint_target", "pose_target", "heartbeat")


class Rejected(Exception):
    """A message that must not reach the robot; carries the error code for the reply.

    Args:
        code: the protocol error code (``malformed``, ``bad_shape``, ``not_finite``, ...).
        message: what was wrong and what to do.
    """

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code


def number(x: Any, what: str) -> float:
    """A finite JSON number as float.

    Raises:
        Rejected: ``bad_shape`` for a non-number (booleans included), ``not_finite`` for NaN, inf or
            an integer too large for a float (``10**400``).
    """
    if not isinstance(x, (int, float)) or isinstance(x, bool):
        raise Rejected("bad_shape", f"{what} must be a number, got {type(x).__name__}")
    try:
        v = float(x)
    except OverflowError:
        raise Rejected("not_finite", f"{what} is too large for a float") from None
    if not math.isfinite(v):
        raise Rejected("not_finite", f"{what} contains NaN or inf")
    return v


def numbers(x: Any, n: int, what: str) -> npt.NDArray[np.float64]:
    """A JSON list of ``n`` finite numbers as an (n,) float array.

    Raises:
        Rejected: ``bad_shape`` (not a list of n numbers) or ``not_finite``.
    """
    if not isinstance(x, list) or len(x) != n:
        raise Rejected("bad_shape", f"{what} must be a list of {n} numbers")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in x):
        raise Rejected("bad_shape", f"{what} must contain numbers only")
    return np.array([number(v, what) for v in x], dtype=float)


def flag(msg: dict, key: str) -> bool:
    """An optional JSON boolean (absent: False).

    Raises:
        Rejected: ``malformed`` when present and not ``true``/``false`` (``"false"`` is not a boolean).
    """
    v = msg.get(key, False)
    if not isinstance(v, bool):
        raise Rejected("malformed", f"{key!r} must be true or false, got {v!r}")
    return v


def sequence(msg: dict) -> int | None:
    """The optional integer ``seq`` of a message.

    Raises:
        Rejected: ``malformed`` when present and not an integer (or beyond 64 bits).
    """
    seq = msg.get("seq")
    if seq is None:
        return None
    if not isinstance(seq, int) or isinstance(seq, bool) or abs(seq) >= 2 ** 63:
        raise Rejected("malformed", "seq must be an integer below 2**63")
    return seq


def quaternion_matrix(wxyz: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Rotation matrix (3, 3) of a quaternion [w, x, y, z] of norm within (0.5, 1.5) (normalised).

    Raises:
        Rejected: ``bad_shape`` when the norm is far from 1.
    """
    nrm = float(np.linalg.norm(wxyz))
    if not (0.5 < nrm < 1.5):
        raise Rejected("bad_shape", f"quaternion must be unit length, got norm {nrm:.3g}")
    w, x, y, z = wxyz / nrm
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def pose(msg: dict) -> npt.NDArray[np.float64]:
    """The 4x4 TCP pose of a ``pose_target`` (position m, quaternion [w, x, y, z] or rotation 3x3).

    Raises:
        Rejected: ``bad_shape`` / ``not_finite`` for a malformed pose.
    """
    p = numbers(msg.get("position"), 3, "position")
    if "quaternion" in msg:
        R = quaternion_matrix(numbers(msg.get("quaternion"), 4, "quaternion"))
    elif "rotation" in msg:
        rot = msg.get("rotation")
        if not isinstance(rot, list) or len(rot) != 3:
            raise Rejected("bad_shape", "rotation must be a 3x3 list")
        R = np.array([numbers(r, 3, "rotation row") for r in rot])
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-4) or np.linalg.det(R) < 0:
            raise Rejected("bad_shape", "rotation must be a proper rotation matrix")
    else:
        raise Rejected("bad_shape", "pose_target needs 'quaternion' [w, x, y, z] or 'rotation' 3x3")
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


@dataclass
class SendClock:
    """Maps a client's send times to the server clock and checks that the client's clock keeps time.

    The offset is the smallest (arrival - send) seen on the connection, so it absorbs the clock
    offset and the smallest network delay; a backlog (messages arriving late) does not move it, so
    a late message is recognised as old. The estimate drifts up by ``leak`` s/s to follow a slightly
    slow client clock. A mapped send time is never later than the arrival.

    A client clock that runs fast would make every message look fresh (its offset keeps falling), so
    the fall of the offset since an anchor (the connection's first timed message) is bounded: at
    most ``slack`` plus ``tolerance`` times the server time since the anchor. A message beyond that
    is refused (``clock_rate``) and the anchor moves to it (an honest client whose first message was
    late gets one refusal at most); after ``strikes`` refusals every timed message of the connection
    is refused. A clock that runs slow makes every message look old (``stale``); such refusals name
    the rate when the client's clock advanced less than half the server's over at least a second.

    Attributes:
        leak: allowed clock drift, s per s (1e-4 = 100 ppm).
        tolerance: allowed rate error of the client's clock beyond ``slack`` (0.01 = 1 %).
        slack: allowed fall of the offset beyond ``tolerance`` (the first message's extra delay), s.
        strikes: fast-clock refusals after which the connection's clock is refused for good.
    """

    leak: float = 1e-4
    tolerance: float = 0.01
    slack: float = 0.25
    strikes: int = 3
    _offset: float | None = None
    _last: float = 0.0
    _anchor: tuple[float, float, float] | None = None  # (arrival, client time, arrival - client time)
    fast: int = 0

    def to_server(self, t_client: float, now: float) -> float:
        """The server time (same clock as ``now``, s) at which a message stamped ``t_client`` was sent.

        Raises:
            Rejected: ``clock_rate`` when the client's clock runs fast (beyond the tolerance).
        """
        if self.fast >= self.strikes:
            raise Rejected("clock_rate", "this connection's send times ran faster than the server's clock: send "
                                         "'t' in seconds of a steady clock; reconnect to try again")
        cand = now - t_client
        if self._anchor is None:
            self._anchor = (now, t_client, cand)
        a_now, _, a_off = self._anchor
        allowed = self.slack + self.tolerance * (now - a_now)
        if cand < a_off - allowed:
            self.fast += 1
            rate = (t_client - self._anchor[1]) / max(now - a_now, 1e-9)
            self._anchor = (now, t_client, cand)
            self._offset, self._last = cand, now
            raise Rejected("clock_rate", f"'t' advanced {a_off - cand:.3g} s more than the server's clock "
                                         f"(rate {rate:.4g} s per s): send 't' in seconds of a steady clock")
        if self._offset is None:
            self._offset = cand
        else:
            self._offset = min(self._offset + self.leak * (now - self._last), cand)
        self._last = now
        return t_client + self._offset

    def rate_note(self, t_client: float, now: float) -> str:
        """A hint for a stale message: names the client's clock rate when it runs slow (else '')."""
        if self._anchor is None:
            return ""
        a_now, a_t, _ = self._anchor
        if now - a_now < 1.0:
            return ""
        rate = (t_client - a_t) / (now - a_now)
        if rate >= 0.5:
            return ""
        return (f"; the send times advanced {rate:.3g} s per s of the server's clock: send 't' in seconds "
                "of a steady clock")


@dataclass
class RateLimit:
    """A token bucket: ``rate`` messages per second sustained, bursts of ``burst``.

    A client over its rate is not read from until it is back under it: the server waits, the
    connection's receive queue fills, and TCP backpressure slows the sender at no cost to the server.

    Attributes:
        rate: sustained messages per second.
        burst: bucket size (messages).
    """

    rate: float = 1000.0
    burst: float = 200.0
    _tokens: float | None = None
    _last: float = 0.0

    def take(self, now: float) -> bool:
        """Take one token at time ``now`` (s) if there is one; False (nothing taken) when the bucket is empty."""
        if self._tokens is None:
            self._tokens, self._last = self.burst, now
        self._tokens = min(self.burst, self._tokens + (now - self._last) * self.rate)
        self._last = now
        if self._tokens < 1.0:
            return False
        self._tokens -= 1.0
        return True

    def delay(self, now: float) -> float:
        """Take one token at time ``now`` (s); the seconds to wait before handling the message."""
        if self._tokens is None:
            self._tokens, self._last = self.burst, now
        self._tokens = min(self.burst, self._tokens + (now - self._last) * self.rate) - 1.0
        self._last = now
        return 0.0 if self._tokens >= 0 else -self._tokens / self.rate
