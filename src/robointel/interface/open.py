"""``open_robot``: a robot interface from a URL (``sim`` or ``fanuc://HOST[:RMI_PORT][?sm_port=N]``)."""
from __future__ import annotations

from typing import Any
from urllib.parse import parse_qs, urlsplit

from robointel.errors import InvalidInput
from robointel.interface.backend import Backend, Recorder


def open_robot(url: str = "sim", *, recorder: Recorder | None = None, **kwargs: Any) -> Backend:
    """Open a robot interface.

    Args:
        url: ``"sim"`` (the MuJoCo workcell) or ``"fanuc://HOST[:RMI_PORT][?sm_port=N]"`` (a FANUC
            controller over RMI + Stream Motion; ports default to 16001 and 60015).
        recorder: optional recorder of the run (e.g. :class:`robointel.io.mcap_log.McapRecorder`).
        **kwargs: passed to :class:`~robointel.interface.sim.SimRobot` or
            :class:`~robointel.interface.fanuc.FanucRobot`; ``open_robot("sim", stream_process=True, ...)``
            opens a :class:`~robointel.interface.sim_stream.SimStreamRobot` (the physics in a process of
            its own, paced against wall time; ``stream_process=False`` or none: ``SimRobot``).

    Returns:
        The backend (a :class:`~robointel.interface.protocol.RobotInterface`).

    Raises:
        InvalidInput: an unknown scheme or a malformed URL.
        ConnectionLost: the FANUC controller cannot be brought up.
    """
    if not isinstance(url, str):
        raise InvalidInput(f"robot URL must be a string, got {url!r}", value=url)
    if url == "sim" or url.startswith("sim:"):
        if kwargs.pop("stream_process", False):
            if not kwargs.pop("paced", True):
                raise InvalidInput("the sim's streaming process is paced: stream_process=True needs paced=True",
                                   value=url)
            from robointel.interface.sim_stream import SimStreamRobot

            return SimStreamRobot(recorder=recorder, **kwargs)
        from robointel.interface.sim import SimRobot

        return SimRobot(recorder=recorder, **kwargs)
    parts = urlsplit(url)
    if parts.scheme != "fanuc" or not parts.hostname:
        raise InvalidInput(f"unknown robot {url!r}: use 'sim' or 'fanuc://HOST[:RMI_PORT][?sm_port=N]'", value=url)
    from robointel.interface.fanuc import DEFAULT_RMI_PORT, DEFAULT_SM_PORT, FanucRobot

    try:
        rmi_port = parts.port or DEFAULT_RMI_PORT
        query = parse_qs(parts.query)
        sm_port = int(query.get("sm_port", [DEFAULT_SM_PORT])[0])
    except ValueError as exc:
        raise InvalidInput(f"malformed robot URL {url!r}: {exc}", value=url) from None
    return FanucRobot(parts.hostname, rmi_port=rmi_port, sm_port=sm_port, recorder=recorder, **kwargs)
