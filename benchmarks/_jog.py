"""The jog on a loaded host: ``robointel jog`` through ``robointel teleop``'s streaming interface with two
busy loops beside them, everything through ``subprocess`` as a user runs it.

``jog_dropped`` counts the jog's targets the server dropped (refused as stale, or expired before the
controller acted on them); the jog sends each such target again, so ``jog_error_deg`` (the arm's end
minus start, against the increment asked) shows that nothing was lost, and ``jog_slowed`` how much
longer than planned the jog took on the busy host.
"""
from __future__ import annotations

import json
import os
import secrets
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

BUSY = "while True: pass"


def _child_env(**extra: str) -> dict[str, str]:
    """The environment of a child process: the robointel this process runs first on its path."""
    import robointel

    src = str(Path(robointel.__file__).resolve().parents[1])
    return {**os.environ, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")]), **extra}


def _free_port() -> int:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def jog_dropped(targets: int = 500, busy_loops: int = 2, rate: float = 50.0,
                speed_deg_s: float = 10.0) -> dict[str, Any]:
    """A ``targets``-target joint jog of J1 on a host with ``busy_loops`` busy loops; the figures as a dict."""
    py = [sys.executable, "-m", "robointel.cli"]
    token = secrets.token_urlsafe(18)
    page, stream = _free_port(), _free_port()
    folder = tempfile.mkdtemp(prefix="robointel-jog-")
    server = subprocess.Popen([*py, "teleop", "--port", str(page), "--stream-port", str(stream), "--token", token,
                               "--duration", "600", "--program", os.path.join(folder, "program.yaml")],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=_child_env())
    busy: list[subprocess.Popen] = []
    try:
        line = ""
        while "streaming interface" not in line:
            line = server.stdout.readline()
            if not line and server.poll() is not None:
                raise RuntimeError("robointel teleop did not start")
        busy = [subprocess.Popen([sys.executable, "-c", BUSY], env=_child_env()) for _ in range(busy_loops)]
        time.sleep(1.0)
        step = speed_deg_s / rate
        by = targets * step
        load0 = os.getloadavg()[0]
        r = subprocess.run([*py, "jog", "--server", f"ws://127.0.0.1:{stream}", "--token", token, "--joint", "1",
                            "--by", f"{by:g}", "--speed", f"{speed_deg_s:g}", "--rate", f"{rate:g}", "--json"],
                           capture_output=True, text=True, timeout=600, env=_child_env())
        if r.returncode != 0:
            raise RuntimeError(f"robointel jog failed: {r.stdout[-500:]} {r.stderr[-500:]}")
        out = json.loads(r.stdout.strip().splitlines()[-1])
    finally:
        for p in busy:
            p.kill()
            p.wait()
        server.terminate()
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
        shutil.rmtree(folder, ignore_errors=True)
    moved = float(np.degrees(np.asarray(out["reached"])[0] - np.asarray(out["start"])[0]))
    return {"jog_dropped": int(out["dropped"]), "jog_targets": int(out["targets"]), "jog_sent": int(out["sent"]),
            "jog_stale": int(out["stale"]), "jog_expired": int(out["expired"]),
            "jog_error_deg": round(moved - by, 4), "jog_seconds": round(out["seconds"], 2),
            "jog_planned_seconds": round(out["planned_seconds"], 2),
            "jog_slowed": round(out["seconds"] / max(out["planned_seconds"], 1e-9), 3),
            "jog_load_average": round(load0, 2), "jog_busy_loops": busy_loops}
