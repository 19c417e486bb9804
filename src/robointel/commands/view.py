"""``robointel view TRAJ --robot URDF``: play a planned trajectory of any arm in the browser (viser, 127.0.0.1)."""
from __future__ import annotations

import signal
import threading
import time
from pathlib import Path
from types import FrameType

import numpy as np
import typer

from robointel.commands.failure import fail
from robointel.commands.plan_motion import load_obstacles
from robointel.errors import RobointelError
from robointel.io.trajectory import load_trajectory
from robointel.planning.scene import load_scene
from robointel.report.viewer import TrajectoryViewer
from robointel.robot import Robot


def view(trajectory: Path = typer.Argument(..., help="trajectory file (.npz or .json) from `robointel plan`"),
         robot: str = typer.Option("lrmate200id7l", "--robot", "--urdf", help="the arm: a URDF path, or "
                                   "lrmate200id7l, ur5, panda"),
         scene: str = typer.Option(None, help="draw this scene's obstacles (a scene file or name, or a YAML list "
                                   "of obstacles)"),
         port: int = typer.Option(8081, min=0, max=65535, help="port on 127.0.0.1 (0: a free port)"),
         speed: float = typer.Option(1.0, help="playback speed (1: real time)"),
         duration: float = typer.Option(None, "--for", help="stop after this many seconds (default: Ctrl-C)")) -> None:
    """Play a trajectory of any arm in the browser (viser's URDF viewer on 127.0.0.1); prints the URL, Ctrl-C stops."""
    if not (np.isfinite(speed) and speed > 0):
        fail(f"--speed must be > 0, got {speed!r}")
    if duration is not None and not (np.isfinite(duration) and duration > 0):
        fail(f"--for must be > 0 s, got {duration!r}")
    try:
        tr = load_trajectory(trajectory)
        arm = Robot.load(robot)
        obstacles: list = []
        if scene is not None:
            p = Path(scene)
            try:
                obstacles = list(load_scene(scene).obstacles)
            except RobointelError:
                if not p.is_file():
                    raise
                obstacles = load_obstacles(p)
        viewer = TrajectoryViewer(arm, tr, obstacles=obstacles, port=port, speed=speed)
    except (RobointelError, OSError) as exc:
        fail(exc)
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        typer.echo(f"{arm.name}: {tr.duration:.2f} s of motion, {len(tr.joint_names)} joints")
        typer.echo(f"open {viewer.url} in a browser" + (" (Ctrl-C stops)" if duration is None else
                                                         f" (stops in {duration:g} s)"))
        t_end = time.monotonic() + duration if duration is not None else None
        while not stop.wait(0.2):
            if t_end is not None and time.monotonic() >= t_end:
                break
    finally:
        viewer.close()
        for s, h in previous.items():
            signal.signal(s, h)
    typer.echo(f"stopped after {viewer.frames} frames")


def register(app: typer.Typer) -> None:
    """Add ``robointel view`` to the application.

    Args:
        app: The top-level typer application.
    """
    app.command("view")(view)
