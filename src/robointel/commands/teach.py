"""Teaching interfaces (Ch. 3.2, 3.4): ``robointel imitate``, ``teleop``, ``jog`` and the imitation demo stage.

The demo stage drives the LR Mate by kinematic imitation in MuJoCo and the SCARA by LQ tracking
from a synthetic skeleton.
"""
from __future__ import annotations

import contextlib
import json
import secrets
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from robointel.commands.failure import fail
from robointel.commands.robot_run import run_on_robot
from robointel.errors import InvalidInput, RobointelError
from robointel.interface import Backend, open_robot
from robointel.interface.open import is_sim, parse_robot_url
from robointel.io.mcap_log import McapRecorder
from robointel.io.reference import data_path
from robointel.report.demo import Figure, StageContext, StageResult
from robointel.robot import Robot
from robointel.teach.imitation import kinematic_imitation, plot_imitation, simulate_imitation
from robointel.teach.jog import AXES, Jogger
from robointel.teach.scara import (
    PAPER_RMS,
    PAPER_RMS_COMPENSATED,
    SMOOTH_HZ,
    ScaraSettings,
    delay_aligned_rms,
    fit_predictor,
    plot_scara,
    simulate_scara,
    training_predictor,
)
from robointel.teach.skeleton import Skeleton, clean, load_skeleton, synthetic_wave
from robointel.teach.streaming import StreamingController, StreamingServer, check_bind
from robointel.teach.teleop import TeleopApp

console = Console()


def resolve_recording(name: str) -> Skeleton:
    """Load the skeleton recording named on the command line.

    Args:
        name: A path (.csv Kinect / .bvh), a recording name in the reference data
            (``Ges01_wavehand``, ``joints``), or ``synthetic`` (generated arm wave).

    Returns:
        The skeleton recording.

    Raises:
        RobointelError: the file is missing or unreadable (see :func:`load_skeleton`).
    """
    if name == "synthetic":
        return synthetic_wave()
    p = Path(name).expanduser()
    if p.exists():
        return load_skeleton(p)
    stem = name[:-4] if name.endswith(".csv") else name
    return load_skeleton(data_path("kinect", f"{stem}.csv"))


def register(app: typer.Typer) -> None:
    """Add the ``imitate``, ``teleop`` and ``jog`` commands to ``app``.

    Args:
        app: The top-level typer application.
    """

    @app.command()
    def imitate(recording: str = typer.Argument(..., help="Kinect .csv or .bvh path, a reference recording name "
                                                          "(e.g. Ges01_wavehand) or 'synthetic'"),
                scara: bool = typer.Option(False, "--scara", help="also run dynamic imitation on the 2-link SCARA"),
                out: Path = typer.Option(Path("imitation"), help="folder for the plots"),
                latency: float = typer.Option(0.1, help="Kinect latency for the SCARA run [s]"),
                robot_url: str = typer.Option("sim", "--robot", help="also execute the imitation on this robot: "
                                              "'sim' (with --record), 'sim?process=1' or 'fanuc://HOST[:RMI_PORT][?sm_port=N]'"),
                record: Path = typer.Option(None, help="record the execution as a ROS 2 bag (.mcap)")) -> None:
        """Imitate a recorded human arm: LR Mate kinematic imitation (3.1) in MuJoCo, optionally the SCARA.

        With ``--robot fanuc://...`` (or ``--record``) the jerk-limited joint reference is then
        executed through the robot interface (the arm first moves to its start).

        The SCARA runs computed-torque LQ tracking (3.7)-(3.9): live with the Kinect latency, with and
        without delay compensation, and offline replay of the recording; writes plots.
        """
        if not (np.isfinite(latency) and 0.0 <= latency <= 2.0):
            fail(f"--latency must be in [0, 2] s (the Kinect's delay), got {latency}")
        try:
            parse_robot_url(robot_url)  # the robot and the recording path are checked before any work
            if record is not None:
                McapRecorder(record, [f"joint_{i + 1}" for i in range(6)])
            skel = resolve_recording(recording)
            out.mkdir(parents=True, exist_ok=True)
            robot = Robot.load("lrmate200id7l")
            with console.status("LR Mate imitation in MuJoCo"):
                run = simulate_imitation(kinematic_imitation(skel, robot), robot)
            plot_imitation(run, out / "lrmate_imitation.png")
            t = Table(title=f"LR Mate imitation of {skel.source}")
            for c in ("joint", "RMS vs IK target [rad]", "controller RMS [rad]", "limit hits [frames]"):
                t.add_column(c, justify="right")
            for j in range(robot.nq):
                t.add_row(robot.joint_names[j], f"{run.rms[j]:.4f}", f"{run.tracking_rms[j]:.2e}",
                          str(int(run.plan.limit_hits[j])))
            console.print(t)
            console.print(f"TCP RMS to the scaled hand path: {run.tcp_rms * 1000:.1f} mm; "
                          f"unreachable frames: {int((~run.plan.reachable).sum())}; "
                          f"plot: {out / 'lrmate_imitation.png'}")
            if robot_url != "sim" or record is not None:
                run_on_robot(run.plan.trajectory, robot_url, record, console)
            if scara:
                with console.status("SCARA LQ tracking in MuJoCo"):
                    ar, fitted_on = training_predictor(skel.source, latency=latency)
                    r0 = simulate_scara(skel, latency=latency)
                    r1 = simulate_scara(skel, latency=latency, compensate=True, predictor=ar, smooth_hz=SMOOTH_HZ)
                    r2 = simulate_scara(skel, offline=True, follower=False)
                    aligned = delay_aligned_rms(r0, skel, delay=latency)
                    # the dissertation's system: the whole loop `latency` late, the reference aimed at t - latency
                    rd = simulate_scara(skel, ScaraSettings.delayed_tracking(latency))
                    aligned_d = delay_aligned_rms(rd, skel, delay=latency)
                plot_scara([r0, r1, r2], out / "scara_imitation.png")
                s = Table(title=f"SCARA dynamic imitation, latency {latency:.2f} s")
                for c in ("", "q1 RMS [rad]", "q2 RMS [rad]", "dissertation", "controller RMS q1/q2", "torque sat."):
                    s.add_column(c, justify="right")
                for r, paper, lab in ((r0, PAPER_RMS, "live, no compensation"),
                                      (r1, PAPER_RMS_COMPENSATED, "live, predicted"),
                                      (r2, None, "offline replay")):
                    s.add_row(lab, f"{r.rms[0]:.4f}", f"{r.rms[1]:.4f}", f"{paper[0]} / {paper[1]}" if paper else "-",
                              f"{r.tracking_rms[0]:.4f} / {r.tracking_rms[1]:.4f}", f"{100 * r.saturated:.1f} %")
                    if r is r0:
                        s.add_row(f"{latency:g} s system, vs human(t - {latency:g} s)", f"{aligned_d[0]:.4f}",
                                  f"{aligned_d[1]:.4f}", f"{PAPER_RMS_COMPENSATED[0]} / {PAPER_RMS_COMPENSATED[1]}",
                                  f"{rd.tracking_rms[0]:.4f} / {rd.tracking_rms[1]:.4f}",
                                  f"{100 * rd.saturated:.1f} %")
                        s.add_row(f"live, no compensation, vs human(t - {latency:g} s)", f"{aligned[0]:.4f}",
                                  f"{aligned[1]:.4f}", "-", "-", "-")
                console.print(s)
                console.print(f"RMS vs the true (undelayed) human angles, except 'vs human(t - {latency:g} s)': "
                              "against the recorded angles (dropouts bridged, not smoothed) delayed by the known "
                              f"latency; the {latency:g} s system: frames on their own clock, measured {latency:g} s "
                              f"after capture, the reference aimed at t - {latency:g} s; predictor fitted on "
                              f"{fitted_on}; "
                              "controller RMS = robot vs the reference it was given (live: after the torque-feasible "
                              "follower)")
                console.print(f"plot: {out / 'scara_imitation.png'}")
        except RobointelError as exc:
            fail(exc)

    @app.command()
    def teleop(host: str = typer.Option("127.0.0.1", help="bind address (others need --token)"),
               port: int = typer.Option(8080, help="port of the browser page"),
               stream_port: int = typer.Option(8765, help="port of the WebSocket streaming interface"),
               token: str = typer.Option(None, help="shared secret (>= 16 characters), required for non-loopback "
                                                    "binds; each browser session and each WebSocket client must "
                                                    "give it before it sees or commands the robot"),
               program: Path = typer.Option(Path("teleop_program.yaml"), help="where 'Save program' writes"),
               duration: float = typer.Option(0.0, help="stop after this many seconds (0: until Ctrl-C)"),
               robot: str = typer.Option("sim", help="'sim', 'sim?process=1' or 'fanuc://HOST[:RMI_PORT][?sm_port=N]': "
                                                     "the robot "
                                                     "the stream drives (through the robot interface)"),
               record: Path = typer.Option(None, help="record the run as a ROS 2 bag (.mcap)")) -> None:
        """Serve the teleoperation page (viser) and the robot streaming interface (WebSocket).

        Both drive the LR Mate: the 1 kHz simulated cell by default, or with ``--robot`` (or
        ``--record``) the robot interface at its controller period (``sim`` or a FANUC controller).
        Every option is checked before the robot is connected or a file is created. Programs saved
        from the page load with `robointel plan`.
        """
        if port == stream_port:
            fail(f"--port and --stream-port must differ, both are {port}")
        try:  # everything that can be refused, before anything is brought up
            check_bind(host, token)
            parse_robot_url(robot)
            if program.exists() and program.is_dir():
                raise InvalidInput(f"--program {program} is a folder; give a .yaml file", value=str(program))
            if not program.parent.is_dir():
                raise InvalidInput(f"--program {program}: its folder does not exist", value=str(program))
            lr = Robot.load("lrmate200id7l")
            rec = McapRecorder(record, list(lr.joint_names)) if record is not None else None  # no file yet
        except RobointelError as exc:
            fail(exc)
        iface = None
        try:
            if robot != "sim" or record is not None:
                kw = {"q0": TELEOP_START} if is_sim(robot) else {}
                iface = open_robot(robot, recorder=rec, **kw)
                ctrl = StreamingController(lr, interface=iface)
            else:
                ctrl = StreamingController(lr)
            srv = StreamingServer(ctrl, host=host, port=stream_port, token=token)
            page = TeleopApp(ctrl, host=host, port=port, program_path=program, token=token)
            srv.start()
            page.start()
        except RobointelError as exc:
            _close_robot(iface, rec)
            fail(exc)
        console.print(f"teleoperation page: [bold]{page.url}[/bold]   streaming interface: [bold]{srv.url}[/bold]"
                      + ("   (sessions must give the token)" if token else ""))
        try:
            t0 = time.monotonic()
            while duration <= 0 or time.monotonic() - t0 < duration:
                time.sleep(0.1)
        except KeyboardInterrupt:
            pass
        finally:
            page.stop()
            srv.stop()
            fault = ctrl.fault
            _close_robot(iface, rec)
            console.print("stopped" + (f" (the robot faulted: {fault})" if fault else "")
                          + (f"; recorded to {record}" if record is not None else ""))
        if fault:  # the arm stopped following the operator: not a successful run
            fail(f"the robot stopped during teleoperation: {fault}")

    @app.command()
    def jog(joint: int = typer.Option(None, "--joint", help="jog this joint (1..6); --by in deg"),
            axis: str = typer.Option(None, "--axis", help="jog the TCP along x, y, z (--by in mm) or about rx, ry, rz "
                                                          "(--by in deg)"),
            frame: str = typer.Option("world", "--frame", help="the frame of --axis: world (the robot's base) or tool"),
            by: float = typer.Option(None, "--by", help="the increment: deg (joints, rotations) or mm (translations); "
                                                        "with --hold its sign gives the direction"),
            hold: float = typer.Option(None, "--hold", help="jog continuously for this many seconds (Ctrl-C releases "
                                                            "earlier) instead of by an increment"),
            speed: float = typer.Option(None, "--speed", help="deg/s or mm/s (default 10 deg/s, 20 mm/s)"),
            rate: int = typer.Option(50, "--rate", help="targets per second"),
            server: str = typer.Option(None, "--server", help="jog through a running streaming interface "
                                                              "(ws://HOST:PORT of `robointel teleop`)"),
            token: str = typer.Option(None, "--token", help="the --server's token"),
            robot: str = typer.Option("sim", "--robot", help="without --server: 'sim', 'sim?process=1' or "
                                                             "'fanuc://HOST[:RMI_PORT][?sm_port=N]'"),
            as_json: bool = typer.Option(False, "--json", help="print the result as one JSON line")) -> None:
        """Jog the arm: one joint, or the TCP along / about a world or tool axis, by an increment or while held.

        The jog streams small absolute targets with the deadman (one in flight at a time): a busy
        host slows the jog down, it says so, and a target the server refused as stale is sent again.
        Without ``--server`` the robot (``--robot``) is brought up behind a streaming interface on
        127.0.0.1 for the jog and released after it.
        """
        from robointel.teach.jog import axis_index

        try:  # everything that can be refused, before anything is brought up
            if (joint is None) == (axis is None):
                raise InvalidInput("give --joint N or --axis x|y|z|rx|ry|rz", value=(joint, axis))
            if by is None and hold is None:
                raise InvalidInput("give --by (an increment) or --hold SECONDS (continuously)", value=(by, hold))
            if by is not None and by == 0:
                raise InvalidInput("--by must not be 0", value=by)
            fr = "joint" if joint is not None else frame
            ax = axis_index(fr, joint if joint is not None else axis, 6)
            angular = fr == "joint" or ax >= 3
            unit = np.radians(1.0) if angular else 1e-3
            v = (speed if speed is not None else (10.0 if angular else 20.0)) * unit
            if server is None:
                parse_robot_url(robot)
            elif not server.startswith(("ws://", "wss://")):
                raise InvalidInput(f"--server must be a ws://HOST:PORT URL, got {server!r}", value=server)
        except RobointelError as exc:
            fail(exc)
        with contextlib.ExitStack() as stack:
            try:
                url, tok = server, token
                if server is None:
                    url, tok = stack.enter_context(_local_stream(robot))
                client = stack.enter_context(_connect(url, tok))
                jogger = Jogger(client)
                what = f"J{ax + 1}" if fr == "joint" else f"{AXES[ax]} ({fr})"
                with console.status(f"jogging {what}"):
                    if hold is not None:
                        res = jogger.hold(fr, AXES[ax] if fr != "joint" else ax + 1, by if by is not None else 1.0,
                                          speed=v, seconds=hold, rate=rate)
                    else:
                        res = jogger.jog(fr, AXES[ax] if fr != "joint" else ax + 1, by * unit, speed=v, rate=rate)
                tcp = [jogger.robot.fk(q)[:3, 3] for q in (res.start, res.reached)]
            except RobointelError as exc:
                fail(exc)
        _print_jog(res, tcp, what, as_json)
        if res.refused:
            fail(f"the jog stopped early: {res.refused}")


def _print_jog(res: Any, tcp: list[np.ndarray], what: str, as_json: bool) -> None:
    """The jog's result: a table, or one JSON line."""
    if as_json:
        print(json.dumps({"start": res.start.tolist(), "goal": res.goal.tolist(), "reached": res.reached.tolist(),
                          "tcp_start": tcp[0].tolist(), "tcp_reached": tcp[1].tolist(), "targets": res.targets,
                          "sent": res.sent, "dropped": res.dropped, "stale": res.stale, "expired": res.expired,
                          "seconds": res.seconds, "planned_seconds": res.planned_seconds, "refused": res.refused}))
        return
    t = Table(title=f"jog of {what}")
    for c in ("", *[f"J{i + 1} [deg]" for i in range(len(res.start))], "TCP x, y, z [mm]"):
        t.add_column(c, justify="right")
    for label, q, p in (("start", res.start, tcp[0]), ("reached", res.reached, tcp[1])):
        t.add_row(label, *[f"{v:.3f}" for v in np.degrees(q)], ", ".join(f"{1e3 * v:.2f}" for v in p))
    console.print(t)
    note = (f"; the host was busy: {res.slowed:.1f}x the planned time" if res.slowed > 1.5 else "")
    console.print(f"{res.targets} targets in {res.seconds:.2f} s (planned {res.planned_seconds:.2f} s){note}; "
                  f"dropped by the server and sent again: {res.dropped}")


@contextlib.contextmanager
def _local_stream(url: str) -> Iterator[tuple[str, str]]:
    """The robot at ``url`` behind a streaming interface on 127.0.0.1 (a random port and token)."""
    lr = Robot.load("lrmate200id7l")
    kw: dict[str, Any] = {"q0": TELEOP_START} if is_sim(url) else {}
    iface = open_robot(url, **kw)
    try:
        ctrl = StreamingController(lr, interface=iface)
        tok = secrets.token_urlsafe(24)
        srv = StreamingServer(ctrl, port=0, token=tok).start()
        try:
            yield srv.url, tok
        finally:
            srv.stop()
    finally:
        iface.close()


@contextlib.contextmanager
def _connect(url: str, token: str | None) -> Iterator[Any]:
    """A stream client of ``url`` (a refused or failed connection is an InvalidInput naming it)."""
    from robointel.teach.stream_client import StreamClient

    try:
        client = StreamClient(url, token=token)
    except (OSError, TimeoutError, ValueError) as exc:
        raise InvalidInput(f"cannot connect to the streaming interface {url}: {exc}", value=url) from None
    if client.welcome.get("type") == "error" or ("robot" not in client.welcome):
        client.close()
        raise InvalidInput(f"the streaming interface {url} refused the session: "
                           f"{client.welcome.get('message', 'give its --token')}", value=url)
    try:
        yield client
    finally:
        client.close()


TELEOP_START = np.array([0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0])
"""Where the simulated LR Mate starts for teleoperation, rad (the streaming controller's ready pose)."""


def _close_robot(iface: Backend | None, rec: McapRecorder | None) -> None:
    """Release the robot interface and write the recording (either may be None)."""
    try:
        if iface is not None:
            iface.close()
    finally:
        if rec is not None:
            rec.close()


def demo_stage(ctx: StageContext) -> StageResult:
    """Run the imitation stage on a SYNTHETIC arm-waving skeleton.

    The skeleton is a generated BVH with a simulated Kinect dropout, so the stage runs without the
    reference data.

    Args:
        ctx: The demo stage context (output folder, quick flag, progress).

    Returns:
        The stage's figures, images and text.
    """
    dur = 4.0 if ctx.quick else 8.0
    ctx.advance(0.02, "synthetic skeleton")
    skel = synthetic_wave(dur, dropout_at=dur / 2)
    c = clean(skel)
    assert c.bridged is not None  # clean() always marks the bridged frames
    bridged = int(c.bridged[:, c.index("HandRight")].sum())
    robot = Robot.load("lrmate200id7l")
    ctx.advance(0.1, "LR Mate imitation (IK + ruckig)")
    t0 = time.perf_counter()
    plan = kinematic_imitation(skel, robot)
    ctx.advance(0.3, "LR Mate in MuJoCo")
    run = simulate_imitation(plan, robot)
    plot_imitation(run, ctx.out / "lrmate_imitation.png")
    t_lr = time.perf_counter() - t0
    ctx.advance(0.55, "SCARA LQ tracking")
    scara = Robot.load("scara2")
    r0 = simulate_scara(skel, robot=scara, latency=0.1)
    ctx.advance(0.75, "SCARA with delay compensation")
    # the learned predictor is fitted on other synthetic takes (seeds 1-3; the demo's is seed 0)
    ar = fit_predictor([synthetic_wave(6.0, seed=s, dropout_at=None) for s in (1, 2, 3)], robot=scara)
    r1 = simulate_scara(skel, robot=scara, latency=0.1, compensate=True, predictor=ar, smooth_hz=SMOOTH_HZ)
    r2 = simulate_scara(skel, robot=scara, offline=True, follower=False)
    plot_scara([r0, r1, r2], ctx.out / "scara_imitation.png")
    ctx.advance(1.0, "done")
    f = lambda a: " / ".join(f"{v:.4f}" for v in a)  # noqa: E731
    figs = [
        Figure("input", f"synthetic arm wave {dur:g} s at 30 Hz, {bridged} hand frames bridged", None,
               "generated BVH + simulated 0.2 s Kinect dropout (not a recording)"),
        Figure("LR Mate imitation RMS vs per-frame IK [rad]", f(run.rms), None,
               "J1..J6; jerk-limited within velocity/acceleration limits"),
        Figure("LR Mate controller tracking RMS [rad]", f(run.tracking_rms), None, "PID + feed-forward, 1 kHz"),
        Figure("LR Mate TCP RMS to hand path [mm]", f"{run.tcp_rms * 1000:.1f}", None,
               f"{int(plan.limit_hits.sum())} joint-frame limit hits, {int((~plan.reachable).sum())} unreachable"),
        Figure("SCARA RMS q1 / q2, 0.1 s latency [rad]", f(r0.rms), f"{PAPER_RMS[0]} / {PAPER_RMS[1]}",
               "vs the true (undelayed) human angles"),
        Figure("SCARA RMS q1 / q2, 0.1 s latency, vs human(t - 0.1 s) [rad]",
               f(delay_aligned_rms(r0, skel, robot=scara)),
               f"{PAPER_RMS_COMPENSATED[0]} / {PAPER_RMS_COMPENSATED[1]}",
               "the same uncompensated run, the known delay taken out of the comparison: vs the recorded angles "
               "0.1 s earlier (dropouts bridged, not smoothed)"),
        Figure("SCARA RMS q1 / q2, live predicted [rad]", f(r1.rms),
               f"{PAPER_RMS_COMPENSATED[0]} / {PAPER_RMS_COMPENSATED[1]}",
               "vs the true human angles; live: ridge autoregressive predictor fitted on other takes, "
               "the reference crossfaded to each new prediction over one frame period, then a "
               "torque-feasible ruckig follower"),
        Figure("SCARA RMS q1 / q2, offline replay [rad]", f(r2.rms), None,
               "recording known in advance: no sensor latency in the loop"),
        Figure("SCARA controller RMS q1 / q2 vs its reference, compensated [rad]", f(r1.tracking_rms), None,
               "computed torque (3.9) + DARE LQ (3.7)-(3.8); robot vs the reference it was given"),
        Figure("LR Mate plan + simulation time", f"{t_lr:.1f} s", None, ""),
    ]
    return StageResult("Imitation from human motion (Ch. 3.2)", figures=figs,
                       images=[ctx.out / "lrmate_imitation.png", ctx.out / "scara_imitation.png"],
                       text="A synthetic, generated arm-waving skeleton (BVH, with a simulated Kinect dropout "
                            "bridged by the filter) drives the LR Mate by TCP imitation (3.1) and the 2-link SCARA "
                            "by computed torque + discrete LQ tracking with a 0.1 s sensor latency. The recorded "
                            "Kinect results are in benchmarks/teach.py.")
