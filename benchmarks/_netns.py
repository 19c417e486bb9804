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


def reexec_in_loopback_netns(hint: str = "use --workers 1") -> None:
    """Re-run this script in a new network namespace with only ``lo`` up; return if already inside.

    Args:
        hint: what the user can do instead when ``unshare`` is missing (ends the error message).

    Exits the calling process with the child's exit code.
    """
    if os.environ.get("ROBOINTEL_NETNS") == "1":
        return
    if shutil.which("unshare") is None:
        sys.exit(f"unshare not found: run as root on Linux, or {hint}")
    env = {**os.environ, "ROBOINTEL_NETNS": "1", "RAY_USAGE_STATS_ENABLED": "0"}
    cmd = "ip link set lo up && exec " + shlex.join([sys.executable, *map(str, sys.argv)])
    sys.exit(subprocess.call(["unshare", "--net", "sh", "-c", cmd], env=env))
