"""Sessions of the streaming server: binding rules, authentication and the per-client budgets.

A connection is a *session* once it is authenticated (at once without a token, on loopback only;
with a token, by a ``hello`` carrying it). Until then it is *pending*: it is told the protocol
version and nothing else, it does not count against the server's session slots, it is closed when it
has not authenticated within :data:`AUTH_TIMEOUT`, and when more than :data:`MAX_PENDING` connections
are pending the oldest is closed to make room. So idle or hostile connections can neither fill the
server nor keep an operator out.

Each client session has its own token buckets (:class:`~robointel.teach.stream_protocol.RateLimit`): the
session in control streams at up to :data:`RATE_CONTROL` messages per second, the others at
:data:`RATE_OTHER` (``get_state`` polling, ``stop``); a session over its rate is not read from until it
is back under it, so flooding sessions cannot starve the others or the control loop.
"""
from __future__ import annotations

import asyncio
import collections
import hmac
import ipaddress
import time
from dataclasses import dataclass, field
from typing import Any

from robointel.errors import InvalidInput
from robointel.teach.stream_protocol import RateLimit, SendClock

__all__ = ["AUTH_DELAY", "AUTH_FAILURES", "AUTH_TIMEOUT", "AUTH_WINDOW", "ERROR_REPLIES", "MAX_PENDING",
           "RATE_CONTROL", "RATE_OTHER", "Gatekeeper", "Session", "check_bind", "check_token", "is_loopback",
           "same_token"]

AUTH_FAILURES = 5        # failed hellos per address ...
AUTH_WINDOW = 60.0       # ... within this many seconds lock the address out
AUTH_DELAY = 0.5         # s before a wrong token is answered
AUTH_TIMEOUT = 2.0       # s a connection may stay unauthenticated
MAX_PENDING = 128        # unauthenticated connections at once (the oldest is closed beyond)
ERROR_REPLIES = 20.0     # error replies per second and session (more are counted, not sent)
RATE_CONTROL = (1000.0, 200.0)  # messages/s and burst of the session in control (the stream)
RATE_OTHER = (100.0, 50.0)      # ... of each client that does not command
MIN_TOKEN = 16           # characters of a token


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and 'localhost'."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def check_token(token: str | None) -> None:
    """Refuse a token that is given but too short or not printable.

    Raises:
        InvalidInput: a token of fewer than 16 characters, or with whitespace or control characters.
    """
    if token is None:
        return
    if not isinstance(token, str) or len(token) < MIN_TOKEN:
        raise InvalidInput(f"the token must have at least {MIN_TOKEN} characters (got {len(token or '')})",
                           value="<token>")
    if any(ch.isspace() or not ch.isprintable() for ch in token):
        raise InvalidInput("the token must be printable characters without spaces", value="<token>")


def check_bind(host: str, token: str | None) -> None:
    """Refuse a non-loopback bind without a token (checked before any socket is opened).

    Raises:
        InvalidInput: ``host`` is not a loopback address and no (>= 16 character) token is given,
            or the token is malformed.
    """
    if not isinstance(host, str) or not host:
        raise InvalidInput(f"the bind address must be a host name or IP address, got {host!r}", value=host)
    if not is_loopback(host):
        if not token or len(token) < MIN_TOKEN:
            raise InvalidInput(
                f"refusing to bind {host!r} without a token: the streaming interface moves a robot. "
                f"Bind 127.0.0.1 (default) or pass a token of at least {MIN_TOKEN} characters", value=host)
    check_token(token)


def same_token(given: str, token: str) -> bool:
    """Constant-time comparison of two tokens of any characters."""
    return hmac.compare_digest(given.encode("utf-8", "surrogatepass"), token.encode("utf-8", "surrogatepass"))


@dataclass
class Session:
    """One connection of the streaming server and its budgets.

    Attributes:
        id: the connection's client id at the controller.
        ws: the WebSocket connection.
        authed: authenticated (a session) or pending.
        opened: ``time.monotonic()`` when it connected, s.
    """

    id: str
    ws: Any
    authed: bool
    opened: float = field(default_factory=time.monotonic)
    clock: SendClock = field(default_factory=SendClock)
    limit: RateLimit = field(default_factory=lambda: RateLimit(*RATE_OTHER))
    slot: tuple | None = None  # the newest unprocessed target: (kind, payload, seq, ack, sent)
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    limited_reply: float = -1e9
    throttled: int = 0
    error_budget: RateLimit = field(default_factory=lambda: RateLimit(rate=ERROR_REPLIES, burst=ERROR_REPLIES))
    suppressed: int = 0

    def use_rate(self, in_control: bool) -> None:
        """Take the rate of the session in control or of the others."""
        self.limit.rate, self.limit.burst = RATE_CONTROL if in_control else RATE_OTHER


class Gatekeeper:
    """Authentication state of one server: the token, failures per address, the pending connections.

    Args:
        token: the shared secret (None: every connection is a session at once).
    """

    def __init__(self, token: str | None) -> None:
        check_token(token)
        self.token = token
        self.failures: dict[str, collections.deque[float]] = collections.defaultdict(collections.deque)
        self.pending: dict[str, Session] = {}
        self.timeouts = 0   # pending connections closed for not authenticating in time
        self.evicted = 0    # ... closed to make room for newer ones

    def admit_pending(self, s: Session) -> Session | None:
        """Register a pending connection; return the oldest pending one to close when over the cap."""
        self.pending[s.id] = s
        if len(self.pending) > MAX_PENDING:
            oldest = min(self.pending.values(), key=lambda p: p.opened)
            self.pending.pop(oldest.id, None)
            self.evicted += 1
            return oldest
        return None

    def locked_out(self, peer: str, now: float) -> float | None:
        """Seconds until ``peer`` may try again after too many failures, or None when it may try now."""
        fails = self.failures[peer]
        while fails and now - fails[0] > AUTH_WINDOW:
            fails.popleft()
        if len(fails) >= AUTH_FAILURES:
            return AUTH_WINDOW - (now - fails[0])
        return None

    def accepts(self, msg: Any) -> bool:
        """True when ``msg`` is a ``hello`` carrying the token."""
        tok = msg.get("token") if isinstance(msg, dict) and msg.get("type") == "hello" else None
        return self.token is None or (isinstance(tok, str) and same_token(tok, self.token))

    def fail(self, peer: str, now: float) -> None:
        """Count a failed authentication from ``peer``."""
        self.failures[peer].append(now)
