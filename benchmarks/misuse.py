"""Safe when attacked, crashed or fed garbage: the streaming server, the teleoperation page, recordings,
imports and the command line tried as an attacker, a careless client and a crash would, on loopback.

    python benchmarks/misuse.py            # a table
    python benchmarks/misuse.py --json     # one JSON object
    python benchmarks/misuse.py --json --only deadman,lockout   # some parts

Real parts only: a real WebSocket client against ``StreamingServer``, a real browser (headless
Chromium) against the teleoperation page, the FANUC controller emulator, the CLI through
``subprocess``. Keys (targets in brackets):

- ``deadman_fast_clock_ms`` / ``deadman_slow_clock_ms`` [<= 250]: how long after the client's last send
  a target still drove the arm, with the client's clock 1000x fast / slow; the worst of a flooding
  client (its own process, a backlog) and a steadily streaming one; negative: the arm had stopped before.
- ``operator_locked_out_s`` [<= 0.1]: with 64 idle unauthenticated connections open, how long from the
  operator's connect to the answer of its ``stop`` (authenticated with the token).
- ``state_before_auth`` [0]: messages about the robot an unauthenticated socket and an unauthenticated
  browser page received. ``token_broadcast`` [0]: frames holding the token that went to any page or socket.
- ``robot_packets_before_refusal`` [0]: packets that reached a (listening) controller's ports while
  refused configurations (a remote bind without a token, bad files) were started against it.
- ``recording_lost_after_sigkill_s`` [<= 1.0, file readable]: ``robointel run --robot fanuc://... --record``
  killed with SIGKILL: the kill's time minus the last message in the file.
- ``recording_messages_after_sigint`` [> 0, report written]: ``robointel run example --record`` stopped
  with Ctrl-C (SIGINT) during the run.
- ``corrupt_imports_raw_exceptions`` [0 of >= 30]: corrupt LeRobot v3 / robomimic files read.
- ``partial_imports`` [0]: failed ``dataset import --demonstrations`` runs that changed the file.
- ``cli_tracebacks`` [0 of >= 100]: bad-input cases of every command (``robointel.testing.cli_misuse``).
- ``get_state_p99_ms_20_flooders`` [<= 50]: another client's ``get_state`` round trips while 20 clients
  flood the server (one in control sending unreachable poses, 19 sending junk), the server at a lower
  CPU priority (niceness +5) than the flooders; the flooders' kernel send buffers are 64 kB (what an
  attacker on another computer has in flight). ``..._system_buffers`` repeats it with Linux's own
  (up to 4 MB each: the flooders then burn the shared CPUs filling their own buffers).

The machine is shared: every timing is printed beside the load average.
"""
from __future__ import annotations

import argparse
import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

PY = [sys.executable, "-m", "robointel.cli"]
TOKEN = "misuse-" + secrets.token_urlsafe(18)
READY = [0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0]
LEFT = [-2.5, 0.0, 0.0, 0.0, -np.pi / 2, 0.0]
RIGHT = [2.5, 0.0, 0.0, 0.0, -np.pi / 2, 0.0]


def _child_env(**extra: str) -> dict[str, str]:
    """The environment of a child process: the robointel this process runs first on its path."""
    import robointel

    src = str(Path(robointel.__file__).resolve().parents[1])
    return {**os.environ, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")]), **extra}


def _free_port(kind: int = socket.SOCK_STREAM) -> int:
    s = socket.socket(socket.AF_INET, kind)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def _load() -> float:
    return round(os.getloadavg()[0], 2)


# ----------------------------------------------------------------------------- the deadman
def _settle_left(url: str) -> None:
    from robointel.teach.stream_client import StreamClient

    with StreamClient(url) as a:
        a.acquire()
        for _ in range(150):
            a.joint_target(LEFT)
            time.sleep(0.01)
        a.request({"type": "release"}, "ok")


def _flood_stop_delay(url: str, ctrl: Any, clock: float) -> float:
    """A flooding client with a scaled clock in its own process: stop began minus its last send, s."""
    _settle_left(url)
    ctrl.stop_began = None
    p = subprocess.Popen([sys.executable, "-m", "robointel.teach.stream_client", url, "command", "0.5", "0.3",
                          str(clock)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=_child_env())
    assert p.stdout.readline().strip() == "ready"
    p.stdin.write("go\n")
    p.stdin.flush()
    last = json.loads(p.stdout.readline())["last_send"]
    p.wait(timeout=30)
    t_end = time.monotonic() + 3.0
    while ctrl.mode not in ("stopped", "idle") and time.monotonic() < t_end:
        time.sleep(0.005)
    return (ctrl.stop_began if ctrl.stop_began is not None else last) - last


def _steady_stop_delay(url: str, ctrl: Any, clock: float) -> float:
    """A client streaming at 100 Hz for 1 s with a scaled clock, then silent: stop began minus its last send, s."""
    from robointel.teach.stream_client import StreamClient

    _settle_left(url)
    ctrl.stop_began = None
    with StreamClient(url) as c:
        c.acquire()
        last = time.perf_counter()
        t_end = last + 1.0
        k = 0
        while time.perf_counter() < t_end:
            last = time.perf_counter()
            c.send({"type": "joint_target", "q": RIGHT, "t": last * clock, "seq": k})
            k += 1
            time.sleep(0.01)
        t_wait = time.monotonic() + 3.0
        while ctrl.mode not in ("stopped", "idle") and time.monotonic() < t_wait:
            time.sleep(0.005)
    return (ctrl.stop_began if ctrl.stop_began is not None else last) - last


def deadman() -> dict[str, Any]:
    from robointel.robot import Robot
    from robointel.teach.streaming import StreamingController, StreamingServer

    srv = StreamingServer(StreamingController(Robot.load("lrmate200id7l")), port=0).start()
    out: dict[str, Any] = {}
    try:
        for name, clock in (("fast", 1000.0), ("slow", 0.001), ("honest", 1.0)):
            flood = _flood_stop_delay(srv.url, srv.controller, clock)
            steady = _steady_stop_delay(srv.url, srv.controller, clock)
            out[f"deadman_{name}_clock_ms"] = round(1e3 * max(flood, steady), 1)
            out[f"deadman_{name}_clock_flood_ms"] = round(1e3 * flood, 1)
            out[f"deadman_{name}_clock_steady_ms"] = round(1e3 * steady, 1)
    finally:
        srv.stop()
    out["deadman_load_average"] = _load()
    return out


# ----------------------------------------------------------------------------- slots and authentication
def lockout(idle: int = 64) -> dict[str, Any]:
    from websockets.sync.client import connect

    from robointel.robot import Robot
    from robointel.teach.stream_client import StreamClient
    from robointel.teach.streaming import StreamingController, StreamingServer

    srv = StreamingServer(StreamingController(Robot.load("lrmate200id7l")), port=0, token=TOKEN, max_clients=32)
    srv.start()
    socks = []
    out: dict[str, Any] = {}
    try:
        for _ in range(idle):
            ws = connect(srv.url, open_timeout=10)
            ws.recv(timeout=10)
            socks.append(ws)
        t0 = time.perf_counter()
        with StreamClient(srv.url, token=TOKEN) as op:
            ok = op.request({"type": "stop"}, "ok")
            waited = time.perf_counter() - t0
        out["operator_locked_out_s"] = round(waited, 4) if ok.get("type") == "ok" else float("inf")
        time.sleep(2.6)
        closed = 0
        for ws in socks:
            try:
                while True:
                    ws.recv(timeout=0.5)
            except Exception:
                closed += 1
        out["idle_unauthenticated_closed"] = f"{closed}/{idle}"
    finally:
        for ws in socks:
            ws.close()
        srv.stop()
    out["lockout_load_average"] = _load()
    return out


def _socket_before_auth(url: str) -> tuple[int, int]:
    """(messages about the robot, messages holding the token) an unauthenticated socket got."""
    from websockets.sync.client import connect

    about = with_token = 0
    for msgs in ([{"type": "get_state"}], [{"type": "acquire"}, {"type": "joint_target", "q": READY, "t": 0.0}],
                 [{"type": "hello", "token": TOKEN[:-1] + "x"}], [{"type": "hello"}], ["null"]):
        ws = connect(url)
        got = []
        try:
            got.append(ws.recv(timeout=5))
            for m in msgs:
                ws.send(m if isinstance(m, str) else json.dumps(m))
            while True:
                got.append(ws.recv(timeout=3))
        except Exception:
            pass
        finally:
            ws.close()
        for raw in got:
            d = json.loads(raw)
            about += any(k in d for k in ("robot", "q", "joint_names", "lower", "upper", "target"))
            with_token += TOKEN in raw or (TOKEN[:-1] + "x") in raw
    with connect(url) as ws:  # the right token: the answer must not repeat it either
        ws.recv(timeout=5)
        ws.send(json.dumps({"type": "hello", "token": TOKEN}))
        with_token += TOKEN in ws.recv(timeout=5)
    return about, with_token


def _page_before_auth(chromium: str) -> tuple[int, int, int]:
    """A page with a token, two browsers: B never logs in, A logs in. (about-robot to B, token frames, A logged in)."""
    from playwright.sync_api import sync_playwright

    from robointel.robot import Robot
    from robointel.teach.streaming import StreamingController
    from robointel.teach.teleop import TeleopApp
    from robointel.testing.page_frames import about_robot, mentions

    folder = tempfile.mkdtemp(prefix="robointel-page-")
    app = TeleopApp(StreamingController(Robot.load("lrmate200id7l")), port=_free_port(), token=TOKEN,
                    program_path=Path(folder) / "p.yaml").start()
    frames: dict[str, list] = {"A": [], "B": []}
    args = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync"]
    try:
        with sync_playwright() as pw:
            ctx = pw.chromium.launch_persistent_context(os.path.join(folder, "profile"), executable_path=chromium,
                                                         args=args, headless=True)
            try:
                pages = {}
                for name in ("B", "A"):
                    pg = ctx.new_page()
                    pg.set_default_timeout(60000)
                    pg.on("websocket", lambda ws, n=name: ws.on("framereceived", lambda f, n=n: frames[n].append(f)))
                    pg.goto(app.url)
                    pg.get_by_role("button", name="Log in").wait_for()
                    pages[name] = pg
                A = pages["A"]
                A.get_by_text("Token", exact=True).locator("xpath=ancestor::div[.//input][1]").locator(
                    "input").fill(TOKEN)
                A.get_by_role("button", name="Log in").click()
                A.get_by_text("Record waypoint").wait_for()
                time.sleep(2.0)
                logged = sum(s.authed for s in app.sessions.values())
            finally:
                ctx.close()
    finally:
        app.stop()
        shutil.rmtree(folder, ignore_errors=True)
    return about_robot(frames["B"]), mentions(frames["A"], TOKEN) + mentions(frames["B"], TOKEN), logged


def authentication() -> dict[str, Any]:
    from robointel.robot import Robot
    from robointel.teach.streaming import StreamingController, StreamingServer

    srv = StreamingServer(StreamingController(Robot.load("lrmate200id7l")), port=0, token=TOKEN).start()
    try:
        about_sock, token_sock = _socket_before_auth(srv.url)
    finally:
        srv.stop()
    chromium = os.environ.get("ROBOINTEL_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
    about_page, token_page, logged = _page_before_auth(chromium)
    return {"state_before_auth": about_sock + about_page, "state_before_auth_socket": about_sock,
            "state_before_auth_page": about_page, "token_broadcast": token_sock + token_page,
            "page_sessions_logged_in": f"{logged}/2 (one typed the token)"}


# ----------------------------------------------------------------------------- refusals before bring-up
class _Listener:
    """A controller's ports that count what reaches them: TCP (RMI) connections and bytes, UDP datagrams."""

    def __init__(self) -> None:
        self.tcp = socket.socket()
        self.tcp.bind(("127.0.0.1", 0))
        self.tcp.listen(8)
        self.tcp.settimeout(0.1)
        self.udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.udp.bind(("127.0.0.1", 0))
        self.udp.settimeout(0.1)
        self.rmi_port, self.sm_port = self.tcp.getsockname()[1], self.udp.getsockname()[1]
        self.packets = 0
        self._stop = threading.Event()
        self._threads = [threading.Thread(target=f, daemon=True) for f in (self._accept, self._datagrams)]
        for t in self._threads:
            t.start()

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self.tcp.accept()
            except OSError:
                continue
            self.packets += 1
            conn.settimeout(0.2)
            try:
                while conn.recv(65536):
                    self.packets += 1
            except OSError:
                pass
            conn.close()

    def _datagrams(self) -> None:
        while not self._stop.is_set():
            try:
                self.udp.recv(65536)
                self.packets += 1
            except OSError:
                continue

    def close(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=2)
        self.tcp.close()
        self.udp.close()


def refusals() -> dict[str, Any]:
    lis = _Listener()
    folder = Path(tempfile.mkdtemp(prefix="robointel-refuse-"))
    url = f"fanuc://127.0.0.1:{lis.rmi_port}?sm_port={lis.sm_port}"
    rec = folder / "teleop.mcap"
    cases = [
        ["teleop", "--host", "0.0.0.0", "--robot", url, "--record", str(rec), "--duration", "1"],
        ["teleop", "--host", "0.0.0.0", "--token", "short", "--robot", url, "--duration", "1"],
        ["teleop", "--robot", url, "--record", str(folder / "nofolder" / "x.mcap"), "--duration", "1"],
        ["teleop", "--robot", url, "--program", str(folder / "nofolder" / "p.yaml"), "--duration", "1"],
        ["run", "moves", "--robot", url, "--record", str(folder / "x.txt")],
        ["run", str(folder / "missing.yaml"), "--robot", url],
        ["jog", "--robot", url, "--joint", "9", "--by", "5"],
        ["jog", "--robot", url, "--joint", "1", "--by", "nan"],
    ]
    refused = 0
    try:
        for argv in cases:
            r = subprocess.run([*PY, *argv], capture_output=True, text=True, timeout=120, cwd=folder, env=_child_env())
            refused += r.returncode == 2
        time.sleep(0.3)
    finally:
        lis.close()
    files = sorted(p.name for p in folder.iterdir())
    shutil.rmtree(folder, ignore_errors=True)
    return {"robot_packets_before_refusal": lis.packets, "refusals": f"{refused}/{len(cases)}",
            "files_created_by_refusals": files}


# ----------------------------------------------------------------------------- recordings
MOVES = """format: robointel.program/1
name: moves_only
scene: table71
waypoints:
  a: {q_deg: [0, 10, -20, 0, -60, 0]}
  b: {q_deg: [40, 25, -10, 0, -55, 20]}
  c: {q_deg: [-40, 5, -30, 0, -65, -20]}
steps:
  - move: a
  - move: b
  - move: c
  - move: a
  - move: b
  - move: c
  - move: a
"""


def sigkill() -> dict[str, Any]:
    from robointel.io.mcap_log import read_recording
    from robointel.testing.emulator import fanuc_url, running_fake

    folder = Path(tempfile.mkdtemp(prefix="robointel-kill-"))
    prog = folder / "moves.yaml"
    prog.write_text(MOVES)
    rec = folder / "run.mcap"
    out: dict[str, Any] = {}
    try:
        with running_fake(np.radians([0, 10, -20, 0, -60, 0])) as fake:
            p = subprocess.Popen([*PY, "run", str(prog), "--robot", fanuc_url(fake), "--record", str(rec),
                                  "--report", str(folder / "report")], stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL, env=_child_env())
            t_end = time.monotonic() + 300
            while time.monotonic() < t_end and p.poll() is None:  # recording: then 2 s into it
                if rec.exists() and rec.stat().st_size > 4096:
                    break
                time.sleep(0.1)
            time.sleep(2.0)
            running = p.poll() is None
            kill_ns = time.time_ns()
            p.send_signal(signal.SIGKILL)
            p.wait()
        msgs = read_recording(rec)
        last = max((v[-1][0] for v in msgs.values() if v), default=None)
        out["recording_lost_after_sigkill_s"] = round((kill_ns - last) / 1e9, 3) if last is not None else None
        out["recording_after_sigkill_messages"] = sum(len(v) for v in msgs.values())
        out["recording_after_sigkill_readable"] = True
        out["recording_killed_while_running"] = running
    except Exception as exc:  # noqa: BLE001 - the figure says what failed
        out["recording_lost_after_sigkill_s"] = None
        out["recording_after_sigkill_readable"] = f"{type(exc).__name__}: {exc}"
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return out


def sigint(program: str = "example") -> dict[str, Any]:
    from robointel.io.mcap_log import read_recording

    folder = Path(tempfile.mkdtemp(prefix="robointel-int-"))
    rec, report = folder / "run.mcap", folder / "report"
    out: dict[str, Any] = {}
    try:
        p = subprocess.Popen([*PY, "run", program, "--record", str(rec), "--report", str(report)],
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=_child_env())
        t_end = time.monotonic() + 600
        while time.monotonic() < t_end and p.poll() is None and not rec.exists():  # the run has started
            time.sleep(0.2)
        while time.monotonic() < t_end and p.poll() is None:  # ... and recorded a step
            if rec.stat().st_size > 2048:
                break
            time.sleep(0.2)
        time.sleep(3.0)
        running = p.poll() is None
        p.send_signal(signal.SIGINT)
        text, _ = p.communicate(timeout=120)
        msgs = read_recording(rec)
        out["recording_messages_after_sigint"] = sum(len(v) for v in msgs.values())
        out["report_written_after_sigint"] = (report / "index.html").exists()
        out["sigint_exit_code"] = p.returncode
        out["sigint_while_running"] = running
        out["sigint_traceback"] = "Traceback" in text
        if not out["report_written_after_sigint"]:
            out["sigint_output_tail"] = text.strip().splitlines()[-4:]
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return out


# ----------------------------------------------------------------------------- imports
def imports() -> dict[str, Any]:
    from robointel.errors import RobointelError
    from robointel.io.demonstrations import DemonstrationFile
    from robointel.io.lerobot import read_lerobot, write_lerobot
    from robointel.io.robomimic import read_robomimic, write_robomimic
    from robointel.learning.demonstration_episode import episode_to_demonstration
    from robointel.testing.corrupt_data import corrupt_lerobot, corrupt_robomimic, device_episodes

    folder = Path(tempfile.mkdtemp(prefix="robointel-imports-"))
    raw, unnamed, n = 0, 0, 0
    try:
        for reader, cases in ((read_lerobot, corrupt_lerobot(folder / "lerobot")),
                              (read_robomimic, corrupt_robomimic(folder / "robomimic"))):
            for _, path in cases:
                n += 1
                try:
                    reader(path)
                    raw += 1  # accepted: as bad as a raw exception for a corrupt file
                except RobointelError as exc:
                    unnamed += str(path) not in str(exc)
                except Exception:  # noqa: BLE001 - what is being counted
                    raw += 1
        # partial imports through the CLI: each fails; the demonstration file must be unchanged
        eps = device_episodes(3)
        three = write_robomimic(folder / "three.hdf5", eps)
        bad_rot = [e for e in eps]
        st = bad_rot[2].observations["state"].copy()
        st[5, 3:] = 7.0  # not a rotation: the conversion of the third demonstration fails
        from robointel.io.episode import Episode

        bad_rot[2] = Episode.create(eps[2].t, {**eps[2].observations, "state": st}, eps[2].action,
                                    names=eps[2].names, kind=eps[2].kind, name=eps[2].name, meta=eps[2].meta)
        scenarios = []
        store = folder / "taken.h5"
        DemonstrationFile(store).append(episode_to_demonstration(eps[1]))
        scenarios.append((three, store))                                          # a name already taken
        scenarios.append((write_lerobot(folder / "twice", [eps[0], eps[0]]), folder / "twice.h5"))  # repeated
        scenarios.append((write_robomimic(folder / "badrot.hdf5", bad_rot), folder / "badrot.h5"))  # 3rd bad
        partial = failed = 0
        for src, target in scenarios:
            before = DemonstrationFile(target).names() if target.exists() else []
            r = subprocess.run([*PY, "dataset", "import", str(src), "--demonstrations", str(target)],
                               capture_output=True, text=True, timeout=300, env=_child_env())
            failed += r.returncode != 0
            after = DemonstrationFile(target).names() if target.exists() else []
            partial += r.returncode != 0 and after != before
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return {"corrupt_imports_raw_exceptions": raw, "corrupt_import_files": n,
            "corrupt_import_errors_without_the_file": unnamed, "partial_imports": partial,
            "failed_import_scenarios": f"{failed}/{len(scenarios)}"}


# ----------------------------------------------------------------------------- the command line
def cli(workers: int = 2) -> dict[str, Any]:
    from concurrent.futures import ThreadPoolExecutor

    from robointel.testing.cli_misuse import cli_cases, judge

    folder = Path(tempfile.mkdtemp(prefix="robointel-cli-"))
    cases = cli_cases(folder)

    def run(case: tuple[str, list[str]]) -> tuple[str, Any, str]:
        name, argv = case
        try:
            r = subprocess.run([*PY, *argv], capture_output=True, text=True, timeout=240, cwd=folder, env=_child_env())
            return name, judge(r.returncode, r.stdout + r.stderr), ""
        except subprocess.TimeoutExpired:
            return name, None, "timeout"

    try:
        with ThreadPoolExecutor(workers) as ex:
            results = list(ex.map(run, cases))
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    tb = [n for n, v, _ in results if v is not None and v.traceback]
    not_refused = [n for n, v, why in results if v is None or not v.refused]
    multi = [n for n, v, _ in results if v is not None and v.refused and not v.one_line]
    return {"cli_tracebacks": len(tb), "cli_cases": len(cases), "cli_refused_rc2": len(cases) - len(not_refused),
            "cli_one_line": len(cases) - len(not_refused) - len(multi), "cli_traceback_cases": tb,
            "cli_not_refused_cases": not_refused, "cli_multi_line_cases": multi}


# ----------------------------------------------------------------------------- flooders
SERVER = """
import os, sys
from robointel.teach.streaming import StreamingController, StreamingServer
srv = StreamingServer(StreamingController(), port=0, token=os.environ["ROBOINTEL_STREAM_TOKEN"]).start()
print(srv.url, flush=True)
sys.stdin.readline()
print(f"{srv.controller.overruns}", flush=True)
srv.stop()
"""


def flooders(n: int = 20, seconds: float = 5.0, send_buffer: int | None = 64 * 1024, niceness: int = 5) -> dict:
    from robointel.teach.stream_client import StreamClient

    env = _child_env(ROBOINTEL_STREAM_TOKEN=TOKEN)
    srv = subprocess.Popen(["nice", "-n", str(niceness), sys.executable, "-c", SERVER], stdin=subprocess.PIPE,
                           stdout=subprocess.PIPE, text=True, env=env)
    url = srv.stdout.readline().strip()
    modes = ["command_poses"] + ["junk"] * (n - 1)
    buf = "-" if send_buffer is None else str(send_buffer)
    procs = [subprocess.Popen([sys.executable, "-m", "robointel.teach.stream_client", url, m, str(seconds + 1.0),
                               "0.5", "1", buf], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
             for m in modes]
    lat: list[float] = []
    try:
        for p in procs:
            assert p.stdout.readline().strip() == "ready"
        with StreamClient(url, token=TOKEN, timeout=60) as c:
            for p in procs:
                p.stdin.write("go\n")
                p.stdin.flush()
            time.sleep(0.3)
            load = _load()
            t_end = time.monotonic() + seconds
            while time.monotonic() < t_end:
                t0 = time.perf_counter()
                c.state()
                lat.append(time.perf_counter() - t0)
                time.sleep(0.01)
    finally:
        for p in procs:
            p.kill()
            p.wait()
        srv.stdin.write("\n")
        srv.stdin.flush()
        overruns = srv.stdout.readline().strip()
        srv.wait(timeout=30)
    ms = 1e3 * np.array(lat)
    return {"p99_ms": round(float(np.percentile(ms, 99)), 1), "p50_ms": round(float(np.percentile(ms, 50)), 1),
            "max_ms": round(float(ms.max()), 1), "requests": len(ms), "control_loop_overruns": overruns,
            "load_average": load}


def flood() -> dict[str, Any]:
    a = flooders()
    b = flooders(send_buffer=None)
    return {"get_state_p99_ms_20_flooders": a["p99_ms"], "get_state_20_flooders": a,
            "get_state_p99_ms_20_flooders_system_buffers": b["p99_ms"], "get_state_20_flooders_system_buffers": b}


PARTS = {"deadman": deadman, "lockout": lockout, "auth": authentication, "refusals": refusals, "sigkill": sigkill,
         "sigint": sigint, "imports": imports, "cli": cli, "flood": flood}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--only", default="", help=f"comma-separated parts: {', '.join(PARTS)}")
    args = ap.parse_args()
    names = [p for p in args.only.split(",") if p] or list(PARTS)
    out: dict[str, Any] = {}
    for name in names:
        t0 = time.monotonic()
        out.update(PARTS[name]())
        if not args.json:
            print(f"[{name}: {time.monotonic() - t0:.0f} s, load {_load()}]", file=sys.stderr, flush=True)
    if args.json:
        print(json.dumps(out))
    else:
        for k, v in out.items():
            print(f"{k:48s} {v}")


if __name__ == "__main__":
    main()
