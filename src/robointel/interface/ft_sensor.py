"""An F/T sensor beside the controller: the wrench a ``fanuc`` backend reports when Stream Motion has none.

Stream Motion through ``airo-fanuc`` carries no force block (the driver never sends a
ForceSensorConfig packet), so a FANUC arm is guided by hand through a separate F/T sensor on the
wrist. :class:`NetFTSensor` reads one over the ATI Net F/T Raw Data Transfer protocol (RDT, UDP port
49152, the protocol of ATI's Net F/T and of the sensors that copy it); any object with a ``read()``
returning a (6,) wrench (:class:`WrenchSource`) can be given instead.

RDT: the host sends ``struct.pack(">HHI", 0x1234, 2, 0)`` (start real-time streaming, unlimited
samples) and receives 36-byte records ``>IIIiiiiii``: RDT sequence, F/T sequence, status, and
Fx Fy Fz Tx Ty Tz in counts (``counts_per_force`` per N, ``counts_per_torque`` per N m).
"""
from __future__ import annotations

import socket
import struct
import time
from typing import Protocol, runtime_checkable
from urllib.parse import parse_qs, urlsplit

import numpy as np
import numpy.typing as npt

from robointel.errors import ConnectionLost, InvalidInput

RDT_PORT = 49152
RDT_HEADER = 0x1234
RDT_START = 2
RDT_STOP = 0
RDT_RECORD = struct.Struct(">IIIiiiiii")


@runtime_checkable
class WrenchSource(Protocol):
    """Anything that gives the latest wrench of a wrist F/T sensor."""

    def read(self) -> npt.NDArray[np.float64] | None:
        """The latest (6,) [fx, fy, fz, tx, ty, tz] in the sensor (flange) frame, N and N m; None if none."""
        ...


class NetFTSensor:
    """An F/T sensor streaming over ATI's Net F/T RDT protocol (UDP), read without a thread.

    :meth:`read` drains the datagrams that arrived since the last call and returns the newest
    wrench; a record whose status word is non-zero (a sensor fault), or no record for
    ``max_age_s``, reads as None (the caller then holds, as with a lost reading).

    Args:
        host: the sensor's address.
        port: its RDT port (49152).
        counts_per_force: counts per N (the sensor's calibration; 1e6 on Net F/T by default).
        counts_per_torque: counts per N m.
        max_age_s: a reading older than this is stale, s.

    Raises:
        InvalidInput: non-positive calibration or age.
        ConnectionLost: the socket cannot be opened.
    """

    def __init__(self, host: str, port: int = RDT_PORT, *, counts_per_force: float = 1e6,
                 counts_per_torque: float = 1e6, max_age_s: float = 0.05) -> None:
        if not (counts_per_force > 0 and counts_per_torque > 0 and max_age_s > 0):
            raise InvalidInput("F/T calibration counts and max_age_s must be positive",
                               value=(counts_per_force, counts_per_torque, max_age_s))
        self.address = (host, int(port))
        self._scale = np.array([counts_per_force] * 3 + [counts_per_torque] * 3, dtype=float)
        self.max_age_s = float(max_age_s)
        try:
            self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self._sock.setblocking(False)
            self._sock.sendto(struct.pack(">HHI", RDT_HEADER, RDT_START, 0), self.address)
        except OSError as exc:
            raise ConnectionLost(f"cannot reach the F/T sensor at {host}:{port}: {exc}", reason=str(exc)) from exc
        self._wrench: npt.NDArray[np.float64] | None = None
        self._status = 0
        self._stamp = -np.inf
        self.records = 0
        """RDT records received so far."""

    def read(self) -> npt.NDArray[np.float64] | None:
        """The newest (6,) wrench in the sensor frame, N and N m, or None (stale, faulted, none yet)."""
        while True:
            try:
                data = self._sock.recv(256)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                break
            if len(data) < RDT_RECORD.size:
                continue
            rec = RDT_RECORD.unpack_from(data)
            self._status = rec[2]
            self._wrench = np.asarray(rec[3:], dtype=float) / self._scale
            self._stamp = time.perf_counter()
            self.records += 1
        if self._wrench is None or self._status != 0 or time.perf_counter() - self._stamp > self.max_age_s:
            return None
        return self._wrench.copy()

    def close(self) -> None:
        """Stop the sensor's stream and close the socket (idempotent)."""
        if self._sock.fileno() >= 0:
            try:
                self._sock.sendto(struct.pack(">HHI", RDT_HEADER, RDT_STOP, 0), self.address)
            except OSError:
                pass
            self._sock.close()


def open_ft_sensor(url: str) -> NetFTSensor:
    """An F/T sensor from a URL: ``netft://HOST[:PORT][?cpf=COUNTS&cpt=COUNTS]``.

    Raises:
        InvalidInput: an unknown scheme or a malformed URL.
        ConnectionLost: the socket cannot be opened.
    """
    parts = urlsplit(url) if isinstance(url, str) else None
    if parts is None or parts.scheme != "netft" or not parts.hostname:
        raise InvalidInput(f"unknown F/T sensor {url!r}: use 'netft://HOST[:PORT][?cpf=N&cpt=N]'", value=url)
    try:
        q = parse_qs(parts.query)
        return NetFTSensor(parts.hostname, parts.port or RDT_PORT, counts_per_force=float(q.get("cpf", [1e6])[0]),
                           counts_per_torque=float(q.get("cpt", [1e6])[0]))
    except ValueError as exc:
        raise InvalidInput(f"malformed F/T sensor URL {url!r}: {exc}", value=url) from None
