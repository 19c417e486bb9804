"""Re-run a benchmark inside a loopback-only network namespace before it starts a local Ray.

A local Ray binds the machine's routable address even when asked for 127.0.0.1; in a fresh network
namespace holding only ``lo`` it can reach nothing but the loopback (as root: ``unshare --net``).
"""
from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys


def reexec_in_loopback_netns(without: str = "use --workers 1") -> None:
    """Re-run this script in a new network namespace with only ``lo`` up; return if already inside.

    Exits the calling process with the child's exit code (the arguments passed on quoted as given).
    ``without``: what the user can do instead, said when ``unshare`` is missing.
    """
    if os.environ.get("ROBOINTEL_NETNS") == "1":
        return
    if shutil.which("unshare") is None:
        sys.exit(f"unshare not found: run as root on Linux, or {without}")
    env = {**os.environ, "ROBOINTEL_NETNS": "1", "RAY_USAGE_STATS_ENABLED": "0"}
    cmd = "ip link set lo up && exec " + " ".join(shlex.quote(str(a)) for a in [sys.executable, *sys.argv])
    sys.exit(subprocess.call(["unshare", "--net", "sh", "-c", cmd], env=env))
