"""``open_robot``: a robot interface from a URL (``sim``, ``sim?process=1`` or ``fanuc://HOST[:RMI_PORT][?sm_port=N]``).

:func:`parse_robot_url` is the one parser of the ``--robot`` option of every CLI command: the commands
ask it (or :func:`is_sim`) what a URL names rather than comparing strings.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any
from urllib.parse import parse_qs, urlsplit

from robointel._extras import needs_extra
from robointel.errors import InvalidInput
from robointel.interface.backend import Backend, Recorder

ROBOT_FORMS = ("'sim' (the MuJoCo workcell), 'sim?process=1' (the paced sim stepped in a streaming process "
               "of its own) or 'fanuc://HOST[:RMI_PORT][?sm_port=N]'")
"""The ``--robot`` forms, for the commands' help and error messages."""
_SIM_KEYS = ("process",)
_TRUE, _FALSE = ("1", "true", "yes", "on"), ("0", "false", "no", "off")


@dataclass(frozen=True)
class RobotURL:
    """What a robot URL names.

    Attributes:
        kind: ``"sim"`` or ``"fanuc"``.
        stream_process: sim: the physics in a streaming process of its own (``sim?process=1``).
        host: fanuc: the controller's host name or address.
        rmi_port: fanuc: the RMI port.
        sm_port: fanuc: the Stream Motion port.
    """

    kind: str
    stream_process: bool = False
    host: str = ""
    rmi_port: int = 0
    sm_port: int = 0


def parse_robot_url(url: str) -> RobotURL:
    """Parse ``sim``, ``sim?process=0|1`` or ``fanuc://HOST[:RMI_PORT][?sm_port=N]``.

    Raises:
        InvalidInput: not a string, an unknown scheme or query key, a malformed port or flag.
        MissingExtra: a ``fanuc://`` URL without airo-fanuc (the ``fanuc`` extra).
    """
    if not isinstance(url, str):
        raise InvalidInput(f"robot URL must be a string, got {url!r}", value=url)
    if url == "sim" or url.startswith(("sim?", "sim:")):
        query = url[4:] if url.startswith("sim?") else ""
        try:
            q = parse_qs(query, keep_blank_values=True, strict_parsing=bool(query))
        except ValueError as exc:
            raise InvalidInput(f"malformed robot URL {url!r}: {exc}", value=url) from None
        unknown = sorted(set(q) - set(_SIM_KEYS))
        if unknown:
            raise InvalidInput(f"unknown option {unknown[0]!r} in robot URL {url!r}: the sim takes 'process=0|1'",
                               value=url)
        flag = q.get("process", ["0"])[-1].lower()
        if flag not in _TRUE + _FALSE:
            raise InvalidInput(f"malformed robot URL {url!r}: process must be 0 or 1, got {flag!r}", value=url)
        return RobotURL("sim", stream_process=flag in _TRUE)
    parts = urlsplit(url)
    if parts.scheme != "fanuc" or not parts.hostname:
        raise InvalidInput(f"unknown robot {url!r}: use {ROBOT_FORMS}", value=url)
    with needs_extra("fanuc", f"the FANUC robot {url!r}"):
        from robointel.interface.fanuc import DEFAULT_RMI_PORT, DEFAULT_SM_PORT

    try:
        rmi_port = parts.port or DEFAULT_RMI_PORT
        sm_port = int(parse_qs(parts.query).get("sm_port", [DEFAULT_SM_PORT])[0])
    except ValueError as exc:
        raise InvalidInput(f"malformed robot URL {url!r}: {exc}", value=url) from None
    return RobotURL("fanuc", host=parts.hostname, rmi_port=rmi_port, sm_port=sm_port)


def is_sim(url: str) -> bool:
    """True when ``url`` names the simulated cell (either form); False for anything else, a bad URL included."""
    try:
        return parse_robot_url(url).kind == "sim"
    except InvalidInput:
        return False


def open_robot(url: str = "sim", *, recorder: Recorder | None = None, **kwargs: Any) -> Backend:
    """Open a robot interface.

    Args:
        url: ``"sim"`` (the MuJoCo workcell, :class:`~robointel.interface.sim.SimRobot`),
            ``"sim?process=1"`` (the paced workcell stepped in a streaming process of its own,
            :class:`~robointel.interface.sim_stream.SimStreamRobot`) or
            ``"fanuc://HOST[:RMI_PORT][?sm_port=N]"`` (a FANUC controller over RMI + Stream Motion;
            ports default to 16001 and 60015).
        recorder: optional recorder of the run (e.g. :class:`robointel.io.mcap_log.McapRecorder`).
        **kwargs: passed to the backend's class; ``open_robot("sim", stream_process=True, ...)`` is
            ``"sim?process=1"`` (``stream_process=False`` or none: as the URL says).

    Returns:
        The backend (a :class:`~robointel.interface.protocol.RobotInterface`).

    Raises:
        InvalidInput: an unknown scheme or a malformed URL.
        MissingExtra: a ``fanuc://`` URL without airo-fanuc (the ``fanuc`` extra).
        ConnectionLost: the FANUC controller cannot be brought up.
    """
    u = parse_robot_url(url)
    if u.kind == "sim":
        if kwargs.pop("stream_process", False) or u.stream_process:
            if not kwargs.pop("paced", True):
                raise InvalidInput("the sim's streaming process is paced: stream_process=True needs paced=True",
                                   value=url)
            from robointel.interface.sim_stream import SimStreamRobot

            return SimStreamRobot(recorder=recorder, **kwargs)
        from robointel.interface.sim import SimRobot

        return SimRobot(recorder=recorder, **kwargs)
    with needs_extra("fanuc", f"the FANUC robot {url!r}"):
        from robointel.interface.fanuc import FanucRobot

    return FanucRobot(u.host, rmi_port=u.rmi_port, sm_port=u.sm_port, recorder=recorder, **kwargs)
