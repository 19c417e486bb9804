"""Join a running Ray cluster through ``ray://`` (Ray Client), run inside a loopback-only namespace.

    unshare --net sh -c 'ip link set lo up && python tests/batch/ray_client_scenario.py OUT_DIR'

Starts a head node (``ray start --head --block``, 2 CPUs, client server on 127.0.0.1:10001), runs a
small sweep with ``address="ray://127.0.0.1:10001"``, stops the head and prints one JSON object.
"""
import json
import os
import secrets
import signal
import subprocess
import sys
import time
from pathlib import Path

from robointel.batch import ResultStore, TaskSpec, run_batch

PORT = 10001


def main(root: Path) -> None:
    # Ray Client sends the cluster's token only when told to; Ray >= 2.60's `ray start` no longer makes a
    # token itself, so the scenario makes one for its own cluster (never written to ~/.ray).
    os.environ["RAY_AUTH_MODE"] = "token"
    os.environ.setdefault("RAY_AUTH_TOKEN", secrets.token_hex(32))
    env = dict(os.environ)
    ray_cli = str(Path(sys.executable).with_name("ray"))
    log = open(root / "head.log", "w")
    head = subprocess.Popen([ray_cli, "start", "--head", "--block", "--node-ip-address", "127.0.0.1", "--port", "6390",
                             "--ray-client-server-port", str(PORT), "--num-cpus", "2", "--include-dashboard", "false",
                             "--disable-usage-stats"], stdout=log, stderr=subprocess.STDOUT, env=env)
    try:
        t0 = time.monotonic()
        while "Ray runtime started" not in (root / "head.log").read_text() and time.monotonic() - t0 < 120:
            if head.poll() is not None:
                raise RuntimeError("ray start failed: " + (root / "head.log").read_text()[-2000:])
            time.sleep(0.5)
        specs = [TaskSpec("synthetic", s, {"work_s": 0.1}) for s in range(6)]
        r = run_batch(specs, root / "client", engine="ray", address=f"ray://127.0.0.1:{PORT}", progress=False)
        run_batch(specs, root / "local", progress=False)
        rows = ResultStore(root / "client").rows()
        same = [(r_["success"], r_["detail"]) for r_ in rows] == \
            [(r_["success"], r_["detail"]) for r_ in ResultStore(root / "local").rows()]
        print("RESULT " + json.dumps({"done": r.counts.done, "engines": sorted({x["engine"] for x in rows}),
                                      "driver_pid": os.getpid(), "workers": sorted({x["worker"] for x in rows}),
                                      "same_as_inprocess": same}))
    finally:
        head.send_signal(signal.SIGTERM)
        try:
            head.wait(60)
        except subprocess.TimeoutExpired:
            head.kill()
            head.wait()


if __name__ == "__main__":
    main(Path(sys.argv[1]))
