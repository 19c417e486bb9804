"""Learning commands (Ch. 5): ``robointel learn insertion|grinding`` and the demo's learning stage.

Each command runs demonstrate (scripted person with the HDD in MuJoCo) -> learn (DTW synchronisation,
Algorithm 1 decomposition, GMM/GMR skill) -> reproduce (the LR Mate with the same tool) and writes
plots like the dissertation's Figs. 5.10-5.13.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import numpy.typing as npt
import typer
from rich.console import Console
from rich.progress import Progress

from robointel.learning import grinding as G
from robointel.learning import insertion as I
from robointel.learning.demonstration import Demonstration, save_demonstrations
from robointel.learning.insertion import PHASES, POLICY, HDDScene, InsertionSkill, InsertionTrial, tool_velocities
from robointel.learning.peer_checks import dtw_speed, gmr_agreement
from robointel.learning.rltt import LearnedInsertion, learn_insertion
from robointel.program.skill_file import save_skill
from robointel.report.demo import Figure, StageContext, StageResult

PHASE_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red")

#: A progress callback: fraction done in [0, 1] and a message.
ProgressFn = Callable[[float, str], None]


def _plt() -> Any:
    """Select the non-interactive Agg backend and return :mod:`matplotlib.pyplot`."""
    matplotlib.use("Agg")
    return plt


def plot_synchronised(demos: Sequence[Demonstration], learned: LearnedInsertion, path: Path) -> Path:
    """Plot Fig. 5.10: tool height and axial force of the demonstrations before and after DTW.

    Args:
        demos: The raw demonstrations.
        learned: The learning result holding the synchronised features.
        path: PNG file to write.

    Returns:
        ``path``.
    """
    plt = _plt()
    fig, ax = plt.subplots(2, 2, figsize=(11, 6), sharey="row")
    for d, a in zip(demos, learned.aligned):
        ax[0, 0].plot(d.t, d.position[:, 2] * 1e3, lw=0.7)
        ax[1, 0].plot(d.t, -d.wrench[:, 2], lw=0.7)
        tt = np.arange(len(a)) * 0.01
        ax[0, 1].plot(tt, a[:, 11] * 1e3, lw=0.7)
        ax[1, 1].plot(tt, -a[:, 14], lw=0.7)
    ax[0, 0].set_title("raw demonstrations")
    ax[0, 1].set_title("synchronised to the reference (DTW)")
    ax[0, 0].set_ylabel("tool z [mm] (raw) / rel. to final [mm]")
    ax[1, 0].set_ylabel("axial push [N]")
    for a in ax[1]:
        a.set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def plot_decomposed(demos: Sequence[Demonstration], labels: Sequence[npt.NDArray[np.int_]], path: Path,
                    n: int = 6) -> Path:
    """Plot Fig. 5.11: demonstrations coloured by the decomposed action (ground truth dashed).

    Args:
        demos: The demonstrations.
        labels: Per demonstration, the (N_i,) action labels.
        path: PNG file to write.
        n: How many of the last demonstrations to draw.

    Returns:
        ``path``.
    """
    plt = _plt()
    fig, axes = plt.subplots(min(n, len(demos)), 1, figsize=(10, 1.6 * min(n, len(demos))), sharex=True)
    axes = np.atleast_1d(axes)
    for ax, d, lab in zip(axes, demos[-len(axes):], labels[-len(axes):]):
        v = np.linalg.norm(np.gradient(d.position, d.t, axis=0), axis=1) * 1e3
        for a in range(len(PHASES)):
            m = lab == a
            ax.scatter(d.t[m], v[m], s=2, color=PHASE_COLORS[a], label=PHASES[a])
        if d.labels is not None:
            for s in d.phase_times():
                ax.axvline(s, color="k", ls="--", lw=0.7)
        ax.set_ylabel("speed [mm/s]")
    axes[0].legend(markerscale=4, ncol=4, fontsize=8, loc="upper right")
    axes[0].set_title("decomposed demonstrations (colour: Algorithm 1, dashed: ground truth)")
    axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def plot_skill(skill: InsertionSkill, demo: Demonstration, labels: npt.NDArray[np.int_], path: Path) -> Path:
    """Plot Fig. 5.12: the skill model's corrective velocity against the demonstration's.

    Args:
        skill: The learned insertion skill.
        demo: One demonstration.
        labels: Its (N,) action labels (the insertion phase, label 2, is drawn).
        path: PNG file to write.

    Returns:
        ``path``.
    """
    plt = _plt()
    m = labels == 2
    tw = tool_velocities(demo)[m]
    pred = skill.predict(demo.wrench[m])
    t = demo.t[m]
    fig, axes = plt.subplots(5, 1, figsize=(9, 8), sharex=True)
    scale = (1e3, 1e3, 1e3, 1.0, 1.0)
    units = ("mm/s", "mm/s", "mm/s", "rad/s", "rad/s")
    for i, ax in enumerate(axes):
        ax.plot(t, tw[:, i] * scale[i], color="0.5", lw=0.8, label="demonstration")
        ax.plot(t, pred[:, i] * scale[i], color="tab:red", lw=1.0, label="GMR")
        ax.set_ylabel(f"{POLICY[i]} [{units[i]}]")
    axes[0].legend(fontsize=8)
    axes[0].set_title("skill model (GMR: wrench -> tool velocity) vs the demonstration, insertion phase")
    axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def plot_trials(results: Sequence[InsertionTrial], baseline: Sequence[InsertionTrial], task: I.PegHole,
                path: Path) -> Path:
    """Plot the tip height of the robot's insertions: skill (solid) and position-only (dashed).

    Args:
        results: Trials with the learned skill.
        baseline: Trials from the same starts, position control only.
        task: The peg-in-hole task (hole bottom and depth).
        path: PNG file to write.

    Returns:
        ``path``.
    """
    plt = _plt()
    fig, ax = plt.subplots(figsize=(9, 4))
    for r in results:
        if len(r.t):
            ax.plot(r.t, (r.tip[:, 2] - task.bottom_z) * 1e3, color="tab:green" if r.success else "tab:red", lw=0.9)
    for r in baseline:
        if len(r.t):
            ax.plot(r.t, (r.tip[:, 2] - task.bottom_z) * 1e3, color="0.5", ls="--", lw=0.8)
    ax.axhline(1.0, color="k", lw=0.6)
    ax.axhline(task.depth * 1e3, color="k", lw=0.6, ls=":")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("tip above hole bottom [mm]")
    ax.set_title(f"LR Mate insertions, clearance {task.clearance * 1e6:.0f} um: skill (green ok / red fail), "
                 "position-only (grey dashed)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def plot_grinding(plate: G.Plate, skill: G.GrindingSkill, res: G.GrindingResult, path: Path) -> Path:
    """Plot Fig. 5.13: the learned force map and the force along the robot's diagonal path.

    Args:
        plate: The workpiece.
        skill: The learned position-to-force skill.
        res: The robot's reproduction.
        path: PNG file to write.

    Returns:
        ``path``.
    """
    plt = _plt()
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    hx, hy = 0.5 * np.array(plate.size)
    gx, gy = np.meshgrid(np.linspace(-hx, hx, 60), np.linspace(-hy, hy, 60))
    F = skill.predict(np.c_[gx.ravel(), gy.ravel()]).reshape(gx.shape)
    im = ax[0].contourf(gx * 1e3, gy * 1e3, F, 20, cmap="viridis")
    fig.colorbar(im, ax=ax[0], label="pressing force [N]")
    ax[0].plot(res.xy[:, 0] * 1e3, res.xy[:, 1] * 1e3, "w--", lw=1)
    ax[0].set_title("learned force map (GMR: position -> force), robot path dashed")
    ax[0].set_xlabel("x [mm]")
    ax[0].set_ylabel("y [mm]")
    s = np.linalg.norm(res.xy - res.xy[0], axis=1) * 1e3
    ax[1].plot(s, res.intended, "k", lw=1.2, label="demonstrator's intended force")
    ax[1].plot(s, res.setpoint, "tab:orange", lw=1, label="skill set-point (GMR)")
    ax[1].plot(s, res.force, "tab:blue", lw=1, label="robot measured force")
    ax[1].set_xlabel("path length [mm]")
    ax[1].set_ylabel("force [N]")
    ax[1].set_title(f"force along the diagonal: RMS error {100 * res.rms_rel:.1f} % of peak")
    ax[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def run_insertion(out: Path, *, demos: int, labelled: int, trials: int, seed: int = 0,
                  progress: ProgressFn | None = None, save: Path | None = None,
                  time_limit: float | None = None) -> dict[str, Any]:
    """Demonstrate, learn and reproduce the insertion (Sec. 5.5), writing Figs. 5.10-5.12.

    Args:
        out: Folder for the plots (created).
        demos: Number of scripted HDD demonstrations.
        labelled: How many of them carry hand labels (the rest are decomposed by Algorithm 1).
        trials: Number of robot insertion trials (each also run position-only).
        seed: Seed of the demonstrations; ``seed + 1`` draws the start errors.
        progress: Called with the fraction done and a message.
        save: Append the demonstrations to this HDF5 file.
        time_limit: Robot time per trial, s (default 10).

    Returns:
        A dict with ``task``, ``demos``, ``learned``, ``results``, ``baseline``, ``images``,
        ``boundary_ms`` (median decomposition boundary error, ms), ``success`` and ``success_pos``.

    Raises:
        InvalidInput: bad counts (see :func:`robointel.learning.rltt.learn_insertion`).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    step = progress or (lambda frac, msg: None)
    task = I.PegHole()
    rng = np.random.default_rng(seed)
    scene = I.HDDScene(task)
    ds = []
    for i in range(demos):
        step(0.6 * i / demos, f"demonstration {i + 1}/{demos}")
        ds.append(I.demonstrate(task, rng, scene=scene, name=f"demo_{i:02d}"))
    if save is not None:
        save_demonstrations(save, ds)
    step(0.6, "synchronise, decompose, learn")
    learned = learn_insertion(ds, n_labelled=labelled, centre=scene.tool.tip - scene.tool.radius)
    cell = I.RobotCell(task)
    starts = I.random_start_errors(np.random.default_rng(seed + 1), trials)
    res, base = [], []
    for k, (lat, tilt) in enumerate(starts):
        step(0.65 + 0.35 * k / max(1, trials), f"insertion trial {k + 1}/{trials}")
        T0 = cell.start_pose(lat, tilt)
        limit = 10.0 if time_limit is None else float(time_limit)
        res.append(cell.insert(learned.skill.predict, T0, seed=k, time_limit=limit))
        base.append(cell.insert_position_only(T0, seed=k, time_limit=limit))
    images = [plot_synchronised(ds, learned, out / "fig5_10_synchronised.png"),
              plot_decomposed(ds, learned.labels, out / "fig5_11_decomposed.png"),
              plot_skill(learned.skill, ds[-1], learned.labels[-1], out / "fig5_12_skill.png"),
              plot_trials(res, base, task, out / "insertion_trials.png")]
    step(1.0, "done")
    e = learned.boundary_errors[np.isfinite(learned.boundary_errors)] * 1e3
    return {"task": task, "demos": ds, "learned": learned, "results": res, "baseline": base, "images": images,
            "boundary_ms": float(np.median(e)) if e.size else float("nan"),
            "success": sum(r.success for r in res), "success_pos": sum(r.success for r in base)}


def run_grinding(out: Path, *, demos: int = 3, seed: int = 0, progress: ProgressFn | None = None) -> dict[str, Any]:
    """Demonstrate, learn and reproduce grinding (Sec. 5.5), writing Fig. 5.13.

    Args:
        out: Folder for the plot (created).
        demos: Number of scripted HDD demonstrations.
        seed: Seed of the demonstrations.
        progress: Called with the fraction done and a message.

    Returns:
        A dict with ``plate``, ``skill``, ``result`` (:class:`GrindingResult`) and ``images``.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    step = progress or (lambda frac, msg: None)
    plate = G.Plate()
    rng = np.random.default_rng(seed)
    scene = HDDScene(plate, plate.tool())
    ds = []
    for i in range(demos):
        step(0.7 * i / demos, f"demonstration {i + 1}/{demos}")
        ds.append(G.demonstrate_grinding(plate, rng, scene=scene))
    skill = G.GrindingSkill(plate).fit(ds)
    step(0.75, "robot reproduces the force along the diagonal")
    res = G.reproduce_grinding(plate, skill)
    img = plot_grinding(plate, skill, res, out / "fig5_13_grinding.png")
    step(1.0, "done")
    return {"plate": plate, "skill": skill, "result": res, "images": [img]}


learn_app = typer.Typer(help="Learning from demonstration (Ch. 5): HDD demonstrations in MuJoCo -> skill file -> "
                        "LR Mate.", no_args_is_help=True)
"""The ``learn`` group (``learn insertion`` is added by :mod:`robointel.commands.insertion`)."""


def register(app: typer.Typer) -> None:
    """Add the ``learn`` group with ``learn grinding`` to ``app``.

    Args:
        app: The top-level typer application.
    """
    console = Console()

    @learn_app.command("grinding")
    def grinding(out: Path = typer.Option(Path("robointel-learn"), help="folder for the plots"),
                 demos: int = typer.Option(3, min=1), seed: int = typer.Option(0),
                 skill_out: Path = typer.Option(None, "--skill-out",
                                                help="write the learned skill to this skill file (for programs)")
                 ) -> None:
        """Grinding: learn position -> pressing force from demonstrations, reproduce it under force control."""
        with Progress(console=console) as prog:
            task_id = prog.add_task("grinding", total=1.0)
            r = run_grinding(out, demos=demos, seed=seed,
                             progress=lambda f, m: prog.update(task_id, completed=f, description=m))
        res = r["result"]
        if skill_out is not None:
            save_skill(skill_out, r["skill"], meta={"task": "grinding", "demos": demos, "seed": seed})
            console.print(f"skill file: {skill_out}")
        console.print(f"force RMS error along the diagonal {100 * res.rms_rel:.1f} % of the peak "
                      f"({100 * res.rms_rel_setpoint:.1f} % against the skill's set-point); plot {r['images'][0]}")

    app.add_typer(learn_app, name="learn")


def demo_stage(ctx: StageContext) -> StageResult:
    """Run the demo's learning stage: a quick RLTT and the peer checks.

    A few demonstrations, learn, a few insertion trials; DTW speed against dtaidistance and GMR
    agreement with the gmr package.

    Args:
        ctx: The demo stage context (output folder, quick flag, progress).

    Returns:
        The stage's figures, images and text.
    """
    quick = ctx.quick
    ctx.advance(0.02, "DTW vs dtaidistance")
    d = dtw_speed(reps=5 if quick else 15, pairs=5 if quick else 20)
    n_demos, n_lab, n_trials = (4, 2, 1) if quick else (8, 4, 3)
    r = run_insertion(ctx.out, demos=n_demos, labelled=n_lab, trials=n_trials,
                      progress=lambda f, m: ctx.advance(0.05 + 0.9 * f, m))
    sk = r["learned"].skill
    Xt = (sk.X_ - sk.x_mean_) / sk.x_scale_
    agree = gmr_agreement(sk.gmr, Xt[:: max(1, len(Xt) // 200)])
    figs = [
        Figure("insertion success (LR Mate, skill model)", f"{r['success']}/{n_trials}", "48/50 (96 %)",
               f"clearance {r['task'].clearance * 1e6:.0f} um, {n_demos} demonstrations ({n_lab} labelled); "
               f"the benchmark runs 50 trials from 60 demonstrations"),
        Figure("insertion success, position-only", f"{r['success_pos']}/{n_trials}", None, "same starts, no skill"),
        Figure("DTW (1000 x 6-D, window 100)", f"{d['dtw_ms']:.2f} ms vs dtaidistance {d['dtaidistance_ms']:.2f} ms",
               None, f"max |diff| {d['dtw_max_abs_diff']:.1e}"),
        Figure("GMR vs gmr package (same mixture)", f"max |diff| {agree:.1e}", None, ""),
        Figure("decomposition boundary error (median)", f"{r['boundary_ms']:.0f} ms", None,
               f"{n_demos - n_lab} unlabelled demonstrations"),
    ]
    ctx.advance(1.0, "done")
    return StageResult("Learning from demonstration (Ch. 5): RLTT peg-in-hole", figures=figs, images=r["images"],
                       text="Scripted HDD demonstrations in MuJoCo, DTW synchronisation, Algorithm 1 decomposition, "
                            "GMM/GMR skill, reproduction by the LR Mate under a hybrid position/force controller.")
