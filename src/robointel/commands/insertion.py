"""Insertion, one path: ``robointel learn insertion`` writes a skill file, ``robointel skill insert`` runs it.

``learn insertion`` (default ``--strategy felt``) has the scripted person demonstrate the feel-align-insert
strategy with the hand-held device, learns the felt skill (the rotation as GMR, the speeds as the
demonstrations' medians), writes it to a skill file and runs a few trials at the learning benchmark's task
(20 um diametral clearance, chamferless, starts up to +-2 mm and 5 deg off). ``--strategy gmr`` is the
Sec. 5.5 pipeline (DTW, Algorithm 1 decomposition, the wrench -> twist GMR, Figs. 5.10-5.12).

``skill insert --skill FILE`` runs a skill file at the same task by default (``--robot sim``: the LR Mate
under torque-level impedance in MuJoCo), with the time the skill needs (15 s felt, 10 s GMR); the baselines
stay reachable by name (``--strategy constant-push|hand-tuned|position-only``). On a position-streamed
controller (``--robot fanuc://HOST`` or ``'sim?process=1'``) the GMR skill runs as an admittance over streamed
joint positions (:func:`robointel.skills.insertion.run_insertion`).
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from robointel.commands.failure import fail
from robointel.commands.learning import learn_app, plot_trials, run_insertion
from robointel.commands.skills import _CELLS, _check_url, _go_to, _open, _progress, _recorder, _source, skill_app
from robointel.errors import InvalidInput, RobointelError
from robointel.io.demonstrations import DemonstrationFile
from robointel.learning import insertion as ins
from robointel.learning.demonstration import save_demonstrations
from robointel.learning.insertion import STRATEGIES, TIME_LIMIT_S, InsertionTrial
from robointel.program.skill_file import insertion_model, load_skill, save_skill
from robointel.skills.cells import HoleTask, PegTool, ik_near
from robointel.skills.insertion import run_insertion as run_streamed

console = Console()

BENCH_CLEARANCE = 20e-6
"""The learning benchmark's diametral clearance, m (``benchmarks/rltt.py``)."""
STREAMED_CLEARANCE = 0.5e-3
"""The streamed cell's default clearance, m (admittance over streamed positions: a looser fit)."""
STRATEGY_HELP = ("felt (feel the face, turn square with the learned rotation, push in: the skill the "
                 "benchmark measures) or gmr (the Sec. 5.5 wrench -> twist GMR, Figs. 5.10-5.12)")
RUN_STRATEGY_HELP = ("without --skill: felt or gmr (learned first from --demos demonstrations) or a baseline: "
                     "constant-push, hand-tuned, position-only (default: felt on 'sim', gmr on a streamed controller)")


def trial_rows(trials: list[InsertionTrial]) -> list[dict[str, Any]]:
    """One JSON-ready row per trial: success, reason, time (s), max force (N), wall penetration (m)."""
    return [{"trial": k, "success": bool(r.success), "reason": r.reason if not r.success else "",
             "time_s": float(r.time), "max_force_n": float(r.max_force),
             "max_penetration_m": float(r.max_penetration)} for k, r in enumerate(trials)]


def _trial_table(title: str, trials: list[InsertionTrial]) -> Table:
    t = Table(title=title)
    for c in ("trial", "result", "time [s]", "max force [N]", "penetration [um]"):
        t.add_column(c, justify="right")
    for k, r in enumerate(trials):
        t.add_row(str(k), "seated" if r.success else f"[red]{r.reason}[/red]", f"{r.time:.2f}",
                  f"{r.max_force:.1f}", f"{r.max_penetration * 1e6:.1f}")
    return t


def _run_cell(strategy: Any, trials: int, *, seed: int, clearance: float, time_limit: float | None,
              label: str) -> list[InsertionTrial]:
    """The trials of ``strategy`` at the robot cell with a progress bar (one step per trial)."""
    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                  TimeElapsedColumn(), console=console) as bar:
        task = bar.add_task(label, total=trials)

        def tick(k: int, prev: InsertionTrial | None) -> None:
            done = "" if prev is None else (" (last: seated)" if prev.success else f" (last: {prev.reason})")
            bar.update(task, completed=k, description=f"{label}: trial {k + 1}/{trials}{done}")

        res = ins.run_trials(strategy, trials, seed=seed, clearance=clearance, time_limit=time_limit, on_trial=tick)
        bar.update(task, completed=trials, description=label)
    return res


def _write_json(path: Path | None, payload: dict[str, Any]) -> None:
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(payload, indent=1))


def learn_insertion(out: Path = typer.Option(Path("robointel-learn"), help="folder for the plots (and the skill "
                                              "file, unless --skill-out)"),
                    strategy: str = typer.Option("felt", help=STRATEGY_HELP),
                    demos: int = typer.Option(None, min=2, help="demonstrations (default: felt 10, gmr 12)"),
                    labelled: int = typer.Option(4, min=1, help="gmr: hand-labelled demonstrations (the rest "
                                                 "decomposed)"),
                    trials: int = typer.Option(3, min=0, help="robot insertion trials after learning (20 um "
                                               "clearance, +-2 mm, 5 deg; 0: only learn)"),
                    time_limit: float = typer.Option(None, help="s per trial (default: the skill's, felt 15, gmr 10)"),
                    seed: int = typer.Option(0, help="seed of the demonstrations; seed + 1 draws the trials' starts"),
                    save: Path = typer.Option(None, help="append the demonstrations to this HDF5 file"),
                    skill_out: Path = typer.Option(None, "--skill-out", help="the skill file to write (default "
                                                   "OUT/insertion.skill.h5)")) -> None:
    """Learn the tight peg-in-hole (20 um, chamferless) from HDD demonstrations; write the skill file; try it.

    felt (default): the person feels the face beside the hole, turns the peg square and pushes in; the robot
    learns the rotation (GMR) and the speeds. gmr: the Sec. 5.5 pipeline (Figs. 5.10-5.12). Run the file with
    `robointel skill insert --skill FILE`.
    """
    if strategy not in STRATEGIES[:2]:
        fail(f"--strategy must be 'felt' or 'gmr' (the baselines need no learning: `robointel skill insert "
             f"--strategy NAME`), got {strategy!r}")
    n_demos = demos if demos is not None else (10 if strategy == "felt" else 12)
    if strategy == "gmr" and labelled >= n_demos:
        fail("--labelled must be smaller than --demos")
    if save is not None and save.exists():  # a corrupt or foreign file is refused before the work
        try:
            DemonstrationFile(save).names()
        except RobointelError as exc:
            fail(exc)
    skill_path = skill_out if skill_out is not None else out / "insertion.skill.h5"
    try:
        if strategy == "gmr":
            with Progress(console=console) as prog:
                task_id = prog.add_task("insertion", total=1.0)
                r = run_insertion(out, demos=n_demos, labelled=labelled, trials=trials, seed=seed, save=save,
                                  time_limit=time_limit,
                                  progress=lambda f, m: prog.update(task_id, completed=f, description=m))
            skill_path.parent.mkdir(parents=True, exist_ok=True)
            save_skill(skill_path, r["learned"].skill, meta={"task": "insertion", "strategy": "gmr",
                                                              "demos": n_demos, "seed": seed})
            results = r["results"]
            t = Table(title="insertion (gmr), clearance 20 um")
            for c in ("trial", "result", "time [s]", "max force [N]", "penetration [um]", "position-only"):
                t.add_column(c, justify="right")
            for k, (a, b) in enumerate(zip(results, r["baseline"])):
                t.add_row(str(k), "seated" if a.success else f"[red]{a.reason}[/red]", f"{a.time:.2f}",
                          f"{a.max_force:.1f}", f"{a.max_penetration * 1e6:.1f}",
                          "seated" if b.success else f"fail ({b.reason})")
            console.print(t)
            console.print(f"position-only {r['success_pos']}/{len(r['baseline'])}; decomposition median boundary "
                          f"error {r['boundary_ms']:.0f} ms; plots in {out}")
        else:
            with Progress(console=console) as prog:
                task_id = prog.add_task("felt demonstrations", total=1.0)
                ds, skill = ins.learn_felt_skill(n_demos, seed, progress=lambda f, m: prog.update(
                    task_id, completed=f, description=m))
            if save is not None:
                save_demonstrations(save, ds)
            skill_path.parent.mkdir(parents=True, exist_ok=True)
            save_skill(skill_path, skill, meta={"task": "insertion", "strategy": "felt", "demos": n_demos,
                                                "seed": seed, "rotation_r2_held_out": skill.r2_.tolist(),
                                                "demonstrations_seated": int(sum(d.meta["seated"] for d in ds))})
            console.print(f"felt skill from {n_demos} demonstrations ({sum(d.meta['seated'] for d in ds)} seated); "
                          f"rotation held-out R^2 {skill.r2_[0]:.3f} / {skill.r2_[1]:.3f}")
            results = (_run_cell(skill, trials, seed=seed + 1, clearance=BENCH_CLEARANCE, time_limit=time_limit,
                                 label="insertion") if trials else [])
            if results:
                out.mkdir(parents=True, exist_ok=True)
                plot_trials(results, [], ins.PegHole(), out / "insertion_trials.png")
                console.print(_trial_table("insertion (felt), clearance 20 um", results))
    except RobointelError as exc:
        fail(exc)
    if results:
        console.print(f"seated {sum(r.success for r in results)}/{len(results)} at 20 um")
    console.print(f"skill file: {skill_path}  (run it: robointel skill insert --skill {skill_path})")


def _streamed(robot: str, kind: str, skill: Any, *, trials: int, clearance: float, time_limit: float,
              seed: int, demos: int, wrench: str, record: Path | None, stall_ms: float) -> list[dict[str, Any]]:
    """The GMR skill as an admittance over streamed joint positions (``sim?process=1`` or ``fanuc://``)."""
    peg, hole = PegTool(), HoleTask(clearance=clearance)
    if skill is None:  # learn the GMR skill from seated demonstrations now
        task = ins.PegHole()
        rng = np.random.default_rng(seed)
        with Progress(TextColumn("seated demonstrations"), BarColumn(), console=console) as bar:
            t = bar.add_task("demos", total=demos)
            ds = []
            scene = ins.HDDScene(task)
            for _ in range(demos):
                ds += ins.seated_demonstrations(task, rng, 1, scene=scene)
                bar.advance(t)
        skill = ins.InsertionSkill(4, centre=peg.centre).fit(ds)
    arm_robot = peg.robot()
    starts = np.random.default_rng(seed + 1)
    rows: list[dict[str, Any]] = []
    rec = _recorder(record, arm_robot)
    try:
        for k in range(trials):
            lat = starts.uniform(-1.5e-3, 1.5e-3, 2) if kind != "fanuc" else np.zeros(2)
            tilt = ((starts.uniform(0, 2 * np.pi), starts.uniform(0, np.radians(3))) if kind != "fanuc"
                    else (0.0, 0.0))
            q0 = ik_near(arm_robot, hole.start_tcp(peg, lateral=lat, tilt=tilt))
            if kind == "stream":  # the same cell, built in the streaming process
                arm = _open(robot, rec, stall_ms, q0=q0, workcell_factory=f"{_CELLS}:peg_hole_workcell",
                               factory_args=(peg, hole))
            else:
                arm = _open(robot, rec, stall_ms)
            with arm:
                _go_to(arm, arm_robot, q0)
                bottom = arm_robot.fk(q0)[:3, 3] - [0.0, 0.0, hole.advance()]
                src = _source(wrench, arm_robot, peg, (bottom, 1500.0))
                with _progress(f"insertion {k + 1}/{trials}", int(time_limit / arm.period)) as tick:
                    res = run_streamed(arm, arm_robot, skill.predict, hole.advance(), source=src,
                                        time_limit=time_limit, on_cycle=tick)
            f = res.outcome.figures
            rows.append({"trial": k, "success": bool(res.success), "reason": res.outcome.detail,
                         "time_s": float(f.get("time_s", float("nan"))), "max_force_n": float(f["max_force_n"]),
                         "advance_m": float(f["advance_m"])})
    finally:
        if rec is not None:
            rec.close()
    return rows


def skill_insert(skill: Path = typer.Option(None, "--skill", help="skill file from `robointel learn insertion`"),
                 strategy: str = typer.Option(None, help=RUN_STRATEGY_HELP),
                 robot: str = typer.Option("sim", help="'sim': the benchmark's cell (the LR Mate under torque-level "
                                           "impedance in MuJoCo); 'sim?process=1' or 'fanuc://HOST[:RMI_PORT]"
                                           "[?sm_port=N]': admittance over streamed joint positions (gmr only)"),
                 trials: int = typer.Option(3, min=1, help="insertions, each from a random start error (sim: up "
                                            "to +-2 mm and 5 deg)"),
                 clearance: float = typer.Option(None, help="diametral clearance of the fit, m (default 20e-6 on "
                                                 "'sim', the benchmark's; 0.5e-3 in the streamed cell)"),
                 time_limit: float = typer.Option(None, help="s per insertion (default: the skill's: felt 15, "
                                                  "gmr and the baselines 10)"),
                 seed: int = typer.Option(0, help="seed of the start errors (and of any demonstrations)"),
                 demos: int = typer.Option(None, min=1, help="without --skill: demonstrations to learn from "
                                           "(felt 10, gmr 4 seated)"),
                 json_out: Path = typer.Option(None, "--json", help="write the trials' results to this JSON file"),
                 wrench: str = typer.Option("sensor", help="streamed: " + "'sensor' (the robot's F/T reading) or "
                                            "'virtual' (a simulated contact, for the controller emulator)"),
                 record: Path = typer.Option(None, help="streamed: record the run as a ROS 2 bag (.mcap)"),
                 stall_ms: float = typer.Option(80.0, help="streamed: stop the robot when the skill gives no target "
                                                "for this long, ms")) -> None:
    """Insert the peg with a learned skill (--skill FILE) or a strategy by name; at 20 um on 'sim' by default."""
    if wrench not in ("sensor", "virtual"):  # checked for every robot, before any work
        raise typer.BadParameter(f"must be 'sensor' or 'virtual', got {wrench!r}", param_hint="'--wrench'")
    kind = _check_url(robot)
    if skill is not None and strategy is not None:
        fail("give --skill FILE or --strategy NAME, not both")
    if strategy is not None and strategy not in STRATEGIES:
        fail(f"--strategy must be one of {', '.join(STRATEGIES)}, got {strategy!r}")
    if clearance is not None and not (np.isfinite(clearance) and 0 < clearance < 2e-3):
        fail(f"--clearance must be in (0, 0.002) m, got {clearance!r}")
    if time_limit is not None and not (np.isfinite(time_limit) and time_limit > 0):
        fail(f"--time-limit must be > 0 s, got {time_limit!r}")
    try:
        fitted = load_skill(skill) if skill is not None else None
        if fitted is not None:
            model = insertion_model(fitted)
        else:
            model = strategy if strategy is not None else ("felt" if kind == "sim" else "gmr")
        limit = time_limit if time_limit is not None else TIME_LIMIT_S[model]
        if kind != "sim":
            if model != "gmr":
                raise InvalidInput(f"a position-streamed controller runs the gmr skill only (the {model} strategy "
                                   "needs the torque-controlled cell: --robot sim)", value=model)
            c = clearance if clearance is not None else STREAMED_CLEARANCE
            rows = _streamed(robot, kind, fitted, trials=trials, clearance=c, time_limit=limit, seed=seed,
                             demos=demos or 4, wrench=wrench, record=record, stall_ms=stall_ms)
            wins = sum(r["success"] for r in rows)
            t = Table(title=f"insertion on {robot.split('?')[0]} ({c * 1e3:.2f} mm clearance)")
            for col in ("trial", "result", "time [s]", "max force [N]", "advance [mm]"):
                t.add_column(col)
            for r in rows:
                t.add_row(str(r["trial"] + 1), "seated" if r["success"] else r["reason"], f"{r['time_s']:.2f}",
                          f"{r['max_force_n']:.1f}", f"{r['advance_m'] * 1e3:.1f}")
            console.print(t)
            _write_json(json_out, {"robot": robot.split("?")[0], "strategy": model, "clearance_m": c,
                                   "time_limit_s": limit, "seated": wins, "trials": rows})
            console.print(f"seated {wins}/{trials}" + (f"; recorded to {record}" if record is not None else ""))
            return
        if record is not None:
            raise InvalidInput("--record needs a robot interface: use --robot 'sim?process=1' (the streamed cell) "
                               "or fanuc://HOST", value=str(record))
        c = clearance if clearance is not None else BENCH_CLEARANCE
        if fitted is None and model in ("felt", "gmr"):
            fitted = _learn_now(model, demos, seed)
        runner: Any = fitted if fitted is not None else model
        results = _run_cell(runner, trials, seed=seed, clearance=c, time_limit=limit, label=f"insertion ({model})")
    except RobointelError as exc:
        fail(exc)
    wins = sum(r.success for r in results)
    console.print(_trial_table(f"insertion ({model}) on sim, clearance {c * 1e6:.0f} um, {limit:g} s per trial",
                               results))
    _write_json(json_out, {"robot": "sim", "strategy": model, "clearance_m": c, "time_limit_s": limit,
                           "seed": seed, "seated": wins, "trials": trial_rows(results)})
    console.print(f"seated {wins}/{trials} at {c * 1e6:.0f} um")


def _learn_now(model: str, demos: int | None, seed: int) -> Any:
    """Learn the felt or gmr skill now (no skill file given)."""
    if model == "felt":
        with Progress(console=console) as prog:
            task_id = prog.add_task("felt demonstrations", total=1.0)
            return ins.learn_felt_skill(demos or 10, seed, progress=lambda f, m: prog.update(
                task_id, completed=f, description=m))[1]
    task = ins.PegHole()
    rng = np.random.default_rng(seed)
    with Progress(TextColumn("seated demonstrations"), BarColumn(), console=console) as bar:
        t = bar.add_task("demos", total=demos or 4)
        ds = []
        scene = ins.HDDScene(task)
        for _ in range(demos or 4):
            ds += ins.seated_demonstrations(task, rng, 1, scene=scene)
            bar.advance(t)
    return ins.InsertionSkill(4, centre=PegTool().centre).fit(ds)


def register(app: typer.Typer) -> None:
    """Add ``learn insertion`` and ``skill insert`` (the groups are registered by the learning and skills modules).

    Args:
        app: The top-level typer application.
    """
    learn_app.command("insertion")(learn_insertion)
    skill_app.command("insert")(skill_insert)
