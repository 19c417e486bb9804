"""Why a FANUC controller could not be brought up or stopped a stream: one line naming the cause.

A controller is brought up over two options (``docs/guides/fanuc.md``): RMI, *Remote Motion Interface*
(R912, TCP port 16001: the session, the status, the registers, starting the ``STREAM_MOTN`` program) and
*Stream Motion* (J519, UDP port 60015: a joint target every 8 ms, the status back). :func:`probe_rmi`
tells an unreachable host from a closed port before the driver is started; :func:`bringup_cause`
turns the driver's bring-up failure into a sentence naming the cause and what to do.
"""
from __future__ import annotations

import errno
import re
import socket
from typing import Any

__all__ = ["RMI_OPTION", "STREAM_MOTION_OPTION", "alarm_codes", "bringup_cause", "probe_rmi", "read_alarms"]

RMI_OPTION = "R912 (Remote Motion Interface, RMI)"
"""The controller option the RMI session needs."""
STREAM_MOTION_OPTION = "J519 (Stream Motion)"
"""The controller option streaming needs."""
PROBE_TIMEOUT_S = 3.0
"""How long :func:`probe_rmi` waits for the TCP connection, s."""
_ALARM = re.compile(r"\b([A-Z]{3,4}-\d{3})\b")
_UNREACHABLE = (errno.EHOSTUNREACH, errno.ENETUNREACH, errno.EHOSTDOWN, errno.ETIMEDOUT)


def alarm_codes(text: str) -> list[str]:
    """The FANUC alarm codes (``SRVO-002``, ``SYST-348``...) named in ``text``, first occurrence order."""
    seen: list[str] = []
    for code in _ALARM.findall(text):
        if code not in seen:
            seen.append(code)
    return seen


def probe_rmi(host: str, port: int, *, timeout: float = PROBE_TIMEOUT_S) -> str | None:
    """Open (and close) a TCP connection to the controller's RMI port; the cause when it cannot.

    Args:
        host: Controller host name or address.
        port: RMI port (16001 on a controller).
        timeout: Connect timeout, s.

    Returns:
        None when the port accepts a connection; else one sentence: the host name does not resolve,
        the host is unreachable, or the port is closed.
    """
    try:
        socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError):
        return f"host {host!r} not found (the name does not resolve): check the controller's address"
    try:
        with socket.create_connection((host, port), timeout=timeout):
            return None
    except ConnectionRefusedError:
        return (f"port {port} closed on {host}: no RMI server listens there; check that option {RMI_OPTION} is "
                "installed and the controller is in AUTO, and that the port is RMI's (16001 on a controller)")
    except TimeoutError:
        return (f"host {host} unreachable: no answer on TCP port {port} within {timeout:g} s; check the address, "
                "the network cable and that the controller is powered on")
    except OSError as exc:
        if exc.errno in _UNREACHABLE:
            return (f"host {host} unreachable ({exc.strerror}); check the address, the network cable and that the "
                    "controller is powered on")
        return f"cannot connect to {host}:{port}: {exc.strerror or exc}"


def bringup_cause(message: str, *, host: str, rmi_port: int, sm_port: int) -> str:
    """One sentence naming why the driver's bring-up failed, from its error message.

    Args:
        message: The driver's error (``airo_fanuc`` bring-up, preflight or connection error, or the
            streaming process's report of any other exception).
        host: Controller address.
        rmi_port: RMI port.
        sm_port: Stream Motion port.

    Returns:
        The cause and what to do (alarm codes named when the message carries them).
    """
    m = " ".join(str(message).split())
    low = m.lower()
    codes = alarm_codes(m)
    alarms = f" (alarms: {', '.join(codes)})" if codes else ""
    if "syst-348" in low:
        return ("alarm SYST-348: the payload monitor is active; confirm the payload on the teach pendant "
                "(RESET does not clear it)")
    if "syst-322" in low:
        return "alarm SYST-322: auto status-check timeout; power-cycle the controller (and acknowledge DCS)"
    if "t1/t2" in low or "tpmode" in low or "not in auto" in low:
        return "teach pendant in T1/T2: turn the key switch to AUTO and disable the teach pendant"
    if "e-stop" in low or "estop" in low or "drives off" in low or "servo not ready" in low:
        return (f"e-stop pressed or drives off{alarms}: release the e-stop, then RESET on the teach pendant")
    if "already connected" in low or "2556954" in low or "already owned" in low:
        return ("the controller already has an RMI session (another program is connected): close it and retry")
    if ("expecting value" in low or "jsondecodeerror" in low or "not json" in low or "closed the connection" in low
            or "connection reset" in low or "eof" in low.split() or "unexpected reply" in low):
        return (f"{host}:{rmi_port} answered but not as a FANUC RMI server (no RMI reply); check that this is the "
                f"controller's RMI port (16001) and that option {RMI_OPTION} is installed")
    if "connection refused" in low:
        return (f"port {rmi_port} closed on {host}: check that option {RMI_OPTION} is installed and the controller "
                "is in AUTO")
    if "timed out" in low and ("rmi" in low or "connect" in low) and "preroll" not in low:
        return (f"host {host} unreachable: the RMI connection on port {rmi_port} timed out; check the address, the "
                "network cable and that the controller is powered on")
    if ("stream motion" in low or "preroll" in low or "motion_possible" in low or "stream_motn" in low
            or "no controller status" in low):
        return (f"Stream Motion did not start on UDP port {sm_port}{alarms}: check that option {STREAM_MOTION_OPTION} "
                "is installed, the STREAM_MOTN program is loaded, and that the port is not blocked")
    if codes:
        return f"controller alarm {', '.join(codes)}: clear it on the teach pendant (RESET)"
    first = m.split(" — ")[0].removeprefix("airo_fanuc: ")
    return first or "the driver gave no reason"


def read_alarms(driver: Any, *, streaming: bool, count: int = 3) -> list[str]:
    """The controller's most recent alarm texts over RMI (``FRC_ReadError``), best effort.

    Args:
        driver: The ``airo_fanuc`` driver, or the streaming process that owns it.
        streaming: ``driver`` is a :class:`~robointel.interface.stream_process.StreamProcess`.
        count: How many recent alarms to read (1-5).

    Returns:
        The texts, one line each (``SRVO-002 Teach pendant E-stop``...); [] when they cannot be read.
    """
    try:
        if streaming:
            texts = driver.call("alarms", count)
        else:
            rmi = getattr(driver, "rmi", None)
            texts = [] if rmi is None else list(rmi.read_error(count).messages)
    except Exception:  # noqa: BLE001 - a diagnostic: the fault is reported whether or not it is read
        return []
    return [" ".join(str(t).split()) for t in texts if str(t).strip()]
