"""The ``robointel`` command (typer + rich).

Core commands live here (``info``, ``demo``); each phase adds its commands from a module in
``robointel.commands`` exposing ``register(app)``, and its demo stage as ``demo_stage``.
"""
from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import numpy as np
import typer
from rich.console import Console
from rich.table import Table
from typer.core import TyperGroup

from robointel.commands.failure import fail
from robointel.commands.option_checks import install as install_option_checks
from robointel.errors import InvalidInput, RobointelError
from robointel.report.demo import run_demo
from robointel.robot import Robot

_USAGE_ERROR: type[Exception] = typer.BadParameter.__mro__[1]  # click's UsageError (typer vendors click)


class _Commands(TyperGroup):
    """The top-level group: errors escaping a command become one ``error: ...`` line and exit code 2.

    Caught: every :class:`RobointelError`, ``OSError`` (an unreadable or unwritable file) and every
    usage error (a bad option value, a missing argument), never shown as a traceback. Numeric options
    are checked against :mod:`robointel.commands.option_checks` before a command starts.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        install_option_checks(self)

    def invoke(self, ctx: Any) -> Any:
        try:
            return super().invoke(ctx)
        except (RobointelError, OSError) as exc:
            fail(exc)
        except _USAGE_ERROR as exc:
            if type(exc).__name__ == "NoArgsIsHelpError":  # a group called without a command: its help
                raise
            names: list[str] = []
            c = getattr(exc, "ctx", None)
            while c is not None and c.parent is not None:  # the command's path below the root
                names.insert(0, c.info_name)
                c = c.parent
            text = getattr(exc, "format_message", exc.__str__)()
            fail(text + (f" (see robointel {' '.join(names)} --help)" if names else ""))


app = typer.Typer(add_completion=False, no_args_is_help=True, cls=_Commands,
                  help="robointel: teach, learn and plan for an industrial arm (simulated in MuJoCo).")
console = Console()

# modules in robointel.commands, in demo order; each may define register(app) and demo_stage
COMMAND_MODULES = ("core", "planning", "plan_motion", "guidance", "learning", "grasp", "skills", "insertion", "teach",
                   "dataset", "batch", "program", "emulator", "view")


def _load_commands() -> list:
    mods = []
    for name in COMMAND_MODULES:
        try:
            mod = importlib.import_module(f"robointel.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"robointel.commands.{name}":
                continue
            raise
        if hasattr(mod, "register"):
            mod.register(app)
        mods.append(mod)
    return mods


@app.command()
def info(robot: str = typer.Argument("lrmate200id7l", help="built-in name, 'ur5', 'panda' or a URDF path"),
         srdf: Path | None = typer.Option(None, help="SRDF file (groups, disabled collision pairs)"),
         group: str | None = typer.Option(None, help="SRDF planning group to plan"),
         base_link: str | None = typer.Option(None, help="with --tip-link: plan the chain between them"),
         tip_link: str | None = typer.Option(None, help="the chain's last link"),
         joints: str | None = typer.Option(None, help="comma-separated joints to plan"),
         hold: list[str] = typer.Option([], help="NAME=VALUE of a joint outside the group (rad or m); repeat"),
         package_dir: list[Path] = typer.Option([], help="a directory for package:// mesh paths; repeat")) -> None:
    """Print the robot's planned joints, held joints, limits and collision-sphere model.

    A description with collision meshes gets spheres fitted to them (a few seconds the first time,
    then read from the disk cache).
    """
    try:
        held = {}
        for h in hold:
            name, sep, val = h.partition("=")
            if not sep:
                raise InvalidInput(f"--hold expects NAME=VALUE, got {h!r}", value=h)
            try:
                held[name] = float(val)
            except ValueError:
                raise InvalidInput(f"--hold {name}: {val!r} is not a number", value=val) from None
        r = Robot.load(robot, srdf=srdf, group=group, base_link=base_link, tip_link=tip_link,
                       joints=[j.strip() for j in joints.split(",")] if joints else None, held=held or None,
                       package_dirs=package_dir)
        with console.status("collision spheres (fitted to the meshes the first time, then cached)"):
            spheres = r.spheres
    except RobointelError as exc:
        fail(exc)
    t = Table(title=f"{r.name}: {r.nq} planned joints, flange frame {r.flange_frame!r}")
    for c in ("joint", "kind", "lower [deg|mm]", "upper [deg|mm]", "max speed [deg|mm/s]", "effort [N m]", "viscous",
              "Coulomb [N m]"):
        t.add_column(c, justify="right")
    for i, n in enumerate(r.joint_names):
        prismatic = r.chain[3][i + 1] == 1
        kind = "prismatic" if prismatic else ("continuous" if r.continuous[i] else "revolute")
        f = 1e3 if prismatic else np.degrees(1.0)
        t.add_row(n, kind, f"{r.lower[i] * f:.1f}", f"{r.upper[i] * f:.1f}", f"{r.velocity_limit[i] * f:.0f}",
                  f"{r.effort_limit[i]:.1f}", f"{r.viscous[i]:.2f}", f"{r.coulomb[i]:.2f}")
    console.print(t)
    if r.held:
        console.print("held: " + ", ".join(f"{k} = {v:.4g}" for k, v in r.held.items()))
    mass = sum(float(i.mass) for i in r.model.inertias)
    console.print(f"total link mass {mass:.2f} kg")
    how = "fitted inside the collision meshes" if r.fitted_spheres else "covering the collision primitives"
    s = Table(title=f"collision model: {len(spheres)} spheres ({how}), {len(spheres.self_pairs)} self-collision pairs")
    for c in ("#", "link", "centre (link frame) [m]", "radius [m]"):
        s.add_column(c)
    for i, (l, c, rad) in enumerate(zip(spheres.links, spheres.centers, spheres.radii)):
        s.add_row(str(i), l, np.array2string(c, precision=3), f"{rad:.3f}")
    console.print(s)


@app.command()
def demo(out: Path = typer.Option(Path("robointel-report"), help="report folder"),
         quick: bool = typer.Option(False, help="smaller problems (for tests)"),
         stages: str = typer.Option("", help="comma-separated stages to run, e.g. 'core,planning' (default: all)"),
         ) -> None:
    """Run the main job on the built-in simulated workcell and write an HTML report."""
    mods = _load_commands()
    found = {m.__name__.rsplit(".", 1)[-1]: m.demo_stage for m in mods if hasattr(m, "demo_stage")}
    chosen = [s.strip() for s in stages.split(",") if s.strip()] or list(found)
    unknown = [s for s in chosen if s not in found]
    if unknown:
        fail(InvalidInput(f"unknown demo stage {unknown[0]!r}; stages: {', '.join(found)}", value=unknown[0]))
    try:
        index = run_demo([found[s] for s in chosen], out, quick=quick, console=console)
    except RobointelError as exc:
        fail(exc)
    console.print(f"report: [bold]{index}[/bold]")


_load_commands()

if __name__ == "__main__":  # pragma: no cover
    app()
