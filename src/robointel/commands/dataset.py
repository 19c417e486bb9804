"""``robointel dataset export|import``: demonstrations in the ecosystem's formats (LeRobot v3, robomimic).

Sources of ``export`` (one or more; one LeRobot dataset holds one schema, so export the kinds
separately):

- ``FILE.h5``: a robointel demonstration file (``robointel learn insertion --save FILE.h5``);
- ``imitation:REC``: LR Mate kinematic imitation of a recording (name, path or ``synthetic``);
- ``scara:REC``: SCARA dynamic imitation of a recording (live, 0.1 s latency, uncompensated);
- ``guidance:N``: a guided run of scenario N (Table 4.1) with the QP controller;
- ``teleop:PROGRAM.yaml``: a teleoperated program executed through the streaming interface.
"""
from __future__ import annotations

from pathlib import Path
from typing import Annotated

import h5py
import typer
from rich.console import Console
from rich.progress import Progress
from rich.table import Table

from robointel._extras import require_extra
from robointel.commands.failure import fail
from robointel.commands.teach import resolve_recording
from robointel.errors import InvalidInput, RobointelError
from robointel.io.demonstrations import DemonstrationFile
from robointel.io.episode import Episode
from robointel.io.lerobot import read_lerobot, write_lerobot
from robointel.io.robomimic import read_robomimic, write_robomimic
from robointel.learning.demonstration import load_demonstrations
from robointel.learning.demonstration_episode import demonstration_to_episode, episode_to_demonstration
from robointel.robot import Robot
from robointel.teach.imitation import kinematic_imitation, simulate_imitation
from robointel.teach.recording_episodes import (
    guidance_episode,
    imitation_episode,
    scara_episode,
    teleop_episode,
)
from robointel.teach.scara import simulate_scara
from robointel.teach.scenarios import run_scenario
from robointel.teach.teleop import load_program

console = Console()
FORMATS = ("lerobot", "robomimic")


def episodes_from(source: str, *, guidance_seconds: float | None = None) -> list[Episode]:
    """Record or load the episodes of one export source (see the module docstring).

    Args:
        source: ``FILE.h5``, ``imitation:REC``, ``scara:REC``, ``guidance:N`` or ``teleop:FILE.yaml``.
        guidance_seconds: simulated duration of a guided run [s] (default: the operator's whole path).

    Returns:
        The episodes.

    Raises:
        InvalidInput: an unknown source.
    """
    kind, _, arg = source.partition(":")
    if kind == "imitation" and arg:
        robot = Robot.load("lrmate200id7l")
        run = simulate_imitation(kinematic_imitation(resolve_recording(arg), robot), robot)
        return [imitation_episode(run, robot)]
    if kind == "scara" and arg:
        return [scara_episode(simulate_scara(resolve_recording(arg)))]
    if kind == "guidance" and arg.isdigit():
        robot = Robot.load("lrmate200id7l")
        return [guidance_episode(run_scenario(int(arg), duration=guidance_seconds, robot=robot), robot)]
    if kind == "teleop" and arg:
        program = load_program(arg)
        return [teleop_episode(program["waypoints"], robot=Robot.load(program["robot"]), name=Path(arg).stem)]
    path = Path(source)
    if path.suffix in (".h5", ".hdf5") and path.exists():
        return [demonstration_to_episode(d) for d in load_demonstrations(path)]
    raise InvalidInput(f"unknown source {source!r}: give a demonstration file (.h5), imitation:REC, scara:REC, "
                       "guidance:N or teleop:PROGRAM.yaml", value=source)


def read_dataset(path: Path) -> list[Episode]:
    """Read a LeRobot v3 folder or a robomimic HDF5 file (chosen by what ``path`` is).

    Args:
        path: a folder with ``meta/info.json`` or an HDF5 file with a ``data`` group.

    Returns:
        The episodes.

    Raises:
        InvalidInput: neither format.
    """
    if (path / "meta" / "info.json").exists():
        return read_lerobot(path)
    if path.is_file() and h5py.is_hdf5(path):
        return read_robomimic(path)
    raise InvalidInput(f"{path} is neither a LeRobot dataset folder nor a robomimic HDF5 file", value=str(path))


def register(app: typer.Typer) -> None:
    """Add ``robointel dataset export|import`` to ``app``.

    Args:
        app: The top-level typer application.
    """
    dataset = typer.Typer(no_args_is_help=True, help="export/import demonstrations as LeRobot v3 or robomimic data")

    @dataset.command("export")
    def export(sources: Annotated[list[str], typer.Argument(help="FILE.h5, imitation:REC, scara:REC, guidance:N "
                                                                 "or teleop:PROGRAM.yaml")],
               out: Annotated[Path, typer.Option("--out", help="dataset folder (lerobot) or .hdf5 file (robomimic)")],
               fmt: Annotated[str, typer.Option("--format", help="lerobot or robomimic")] = "lerobot",
               robot_type: Annotated[str, typer.Option(help="LeRobot info.json robot_type")] = "",
               guidance_seconds: Annotated[float | None, typer.Option(help="duration of guided runs [s]")] = None,
               overwrite: Annotated[bool, typer.Option(help="replace an existing output")] = False) -> None:
        """Export recordings as a LeRobot v3 dataset or a robomimic-style HDF5 file."""
        try:
            if fmt not in FORMATS:
                raise InvalidInput(f"--format must be one of {FORMATS}, got {fmt!r}", value=fmt)
            if fmt == "lerobot":
                require_extra("datasets", "a LeRobot dataset", "pyarrow")  # before recording anything
            episodes: list[Episode] = []
            with Progress(console=console) as prog:
                task = prog.add_task("recording episodes", total=len(sources))
                for s in sources:
                    prog.update(task, description=f"episodes of {s}")
                    episodes += episodes_from(s, guidance_seconds=guidance_seconds)
                    prog.advance(task)
            if fmt == "lerobot":
                path = write_lerobot(out, episodes, robot_type=robot_type, overwrite=overwrite)
            else:
                path = write_robomimic(out, episodes, overwrite=overwrite)
        except RobointelError as exc:
            fail(exc)
        frames = sum(len(e) for e in episodes)
        console.print(f"wrote {len(episodes)} episode(s), {frames} frames as {fmt}: [bold]{path}[/bold]")

    @dataset.command("import")
    def import_(path: Annotated[Path, typer.Argument(help="LeRobot dataset folder or robomimic .hdf5 file")],
                demonstrations: Annotated[Path | None, typer.Option(
                    help="append the device demonstrations to this robointel demonstration file (.h5)")] = None
                ) -> None:
        """Read a LeRobot v3 dataset or a robomimic file: list its episodes, optionally save demonstrations.

        The whole dataset is checked before anything is written: a malformed file is refused naming the
        file and the field, and ``--demonstrations`` appends all of the device demonstrations or none.
        """
        try:
            episodes = read_dataset(path)
            table = Table(title=f"{path}: {len(episodes)} episode(s)")
            for c in ("#", "name", "kind", "task", "frames", "duration [s]", "observations", "action"):
                table.add_column(c)
            for i, e in enumerate(episodes):
                obs = ", ".join(f"{k} {v.shape[1]}" for k, v in e.observations.items())
                table.add_row(str(i), e.name, e.kind, e.task, str(len(e)), f"{e.t[-1] - e.t[0]:.2f}", obs,
                              str(e.action.shape[1]))
            console.print(table)
            if demonstrations is not None:
                try:
                    demos = [episode_to_demonstration(e) for e in episodes if e.kind == "device"]
                except InvalidInput as exc:
                    raise InvalidInput(f"{path}: {exc}; nothing was appended", value=str(path)) from None
                if not demos:
                    raise InvalidInput(f"{path} holds no device demonstrations", value=str(path))
                names = DemonstrationFile(demonstrations).extend(demos)  # all or none
                console.print(f"appended {len(names)} demonstration(s) to [bold]{demonstrations}[/bold]")
        except RobointelError as exc:
            fail(exc)

    app.add_typer(dataset, name="dataset")
