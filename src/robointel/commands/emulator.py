"""``robointel emulator``: a FANUC controller emulator on 127.0.0.1, for every ``--robot fanuc://`` command.

airo-fanuc's ``FakeCRXController`` (RMI over TCP, Stream Motion over UDP, strict Stream Motion conformance,
wall-clock paced) runs in a process of its own (:class:`robointel.testing.emulator.EmulatorProcess`). The
command prints the URL to pass to ``--robot`` and serves until Ctrl-C (or ``--for`` seconds), then stops it and
prints the strict-conformance violations it saw (docs/guides/fanuc.md).
"""
from __future__ import annotations

import signal
import threading
import time
from types import FrameType

import numpy as np
import typer

from robointel.commands.failure import fail
from robointel.errors import RobointelError
from robointel.testing.emulator import ARRIVAL_GAP_FLAG, EmulatorProcess, protocol_violations


def _q0(text: str | None) -> np.ndarray | None:
    """Six joint angles from ``"a,b,c,d,e,f"`` in deg -> rad (None: zeros)."""
    if text is None:
        return None
    try:
        v = np.array([float(x) for x in text.replace(" ", "").split(",") if x], dtype=float)
    except ValueError:
        fail(f"--q0-deg must be six comma-separated angles in deg, got {text!r}")
    if v.shape != (6,) or not np.all(np.isfinite(v)):
        fail(f"--q0-deg must be six finite angles in deg, got {text!r}")
    return np.radians(v)


def emulator(q0_deg: str = typer.Option(None, "--q0-deg", help="the emulated arm's start joints, deg, "
                                         "comma-separated (default: all 0)"),
             rmi_port: int = typer.Option(0, "--rmi-port", min=0, max=65535,
                                          help="TCP port of RMI (0: a free port; 16001 is a controller's)"),
             sm_port: int = typer.Option(0, "--sm-port", min=0, max=65535,
                                         help="UDP port of Stream Motion (0: a free port; 60015 is a controller's)"),
             duration: float = typer.Option(None, "--for", help="stop after this many seconds (default: Ctrl-C)")
             ) -> None:
    """Start airo-fanuc's FANUC controller emulator on 127.0.0.1 and print the URL for --robot; Ctrl-C stops it.

    Any command that takes --robot fanuc://HOST runs against it, e.g.
    robointel run moves_fanuc --robot 'fanuc://127.0.0.1:PORT?sm_port=PORT'.
    """
    if duration is not None and not (np.isfinite(duration) and duration > 0):
        fail(f"--for must be > 0 s, got {duration!r}")
    q0 = _q0(q0_deg)
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        try:
            emu = EmulatorProcess(q0, rmi_port=rmi_port, sm_port=sm_port)
        except RobointelError as exc:
            fail(exc)
        try:
            typer.echo("FANUC controller emulator (airo-fanuc FakeCRXController, strict Stream Motion conformance) "
                       "on 127.0.0.1")
            typer.echo(f"RMI (TCP) port {emu.rmi_port}, Stream Motion (UDP) port {emu.sm_port}")
            typer.echo(f"robot URL: {emu.url}")
            typer.echo(f"try: robointel run moves_fanuc --robot '{emu.url}'")
            typer.echo("Ctrl-C stops it." if duration is None else f"stops in {duration:g} s (or Ctrl-C).")
            t_end = time.monotonic() + duration if duration is not None else None
            while not stop.wait(0.2):
                if t_end is not None and time.monotonic() >= t_end:
                    break
        finally:
            violations = emu.close()
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
    strict = protocol_violations(violations)
    flags = len(violations) - len(strict)
    typer.echo(f"stopped: {len(strict)} conformance violations" +
               (f" ({flags} arrival-gap flags: '{ARRIVAL_GAP_FLAG}', host jitter, see docs/guides/fanuc.md)"
                if flags else ""))
    for v in strict[:10]:
        typer.echo(f"  {' '.join(str(v).split())}")


def register(app: typer.Typer) -> None:
    """Add ``robointel emulator`` to the application.

    Args:
        app: The top-level typer application.
    """
    app.command("emulator")(emulator)
