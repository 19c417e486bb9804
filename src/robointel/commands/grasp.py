"""Grasp transfer (Ch. 6): ``robointel grasp teach|classify|transfer|trial`` and the grasping demo stage.

Objects come from ``--source demo`` (generated cups, cans, boxes, balls, long tools and toy UR5 arms;
needs no shared data) or ``--source ycb`` (the YCB scans in ../shared/data plus toy arms).
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from robointel.commands.failure import fail
from robointel.errors import InvalidInput, RobointelError
from robointel.report.demo import Figure, StageContext, StageResult

if TYPE_CHECKING:
    from robointel.learning.grasp import GraspPlan, ObjectModel, Placement, Template

console = Console()
grasp_app = typer.Typer(no_args_is_help=True, help="Grasp transfer by non-rigid registration (Ch. 6).")

PAPER_CPD_MS = 549.0
PAPER_ACCURACY = 113 / 120
PAPER_SUCCESS = 18.8 / 20


def _objects(source: str, per_category: int = 4, seed: int = 0) -> dict[str, list[ObjectModel]]:
    from robointel.learning.grasp import demo_objects, toy_arm, ycb_objects

    if source == "demo":
        return demo_objects(per_category, seed)
    if source == "ycb":
        objs = ycb_objects()
        objs["toy_arm"] = [toy_arm(robot="ur5", rng=100 + i, name=f"toy_ur5_{i}") for i in range(per_category)]
        return objs
    raise typer.BadParameter("source must be 'demo' or 'ycb'")


def _templates(objs: dict[str, list[ObjectModel]], db: Path | None = None, *,
               sampled: bool = False) -> list[Template]:
    """The templates: one per category, its first instance, with its taught grasps.

    One template per category (its first instance). Generated objects: the template as the cameras
    see it (:func:`robointel.learning.grasp.seen_template`) with the grasps written per category; for
    scans (``sampled=True``) the best top-down grasps sampled on the template's full model stand in for
    the human demonstration (toy arms keep their written grasps).
    """
    from robointel.learning.grasp import Template, sample_points, sampled_grasps, seen_template, taught_grasps
    from robointel.learning.grasp_database import GraspDatabase

    if db is not None and Path(db).exists():
        return GraspDatabase(db).load_all()
    out = []
    for cat, lst in objs.items():
        o = lst[0]
        if not sampled:  # generated objects: the template as the cameras see it (see ``seen_template``)
            out.append(seen_template(o))
            continue
        grasps = sampled_grasps(o) if cat != "toy_arm" else []
        out.append(Template(o.name, cat, sample_points(o, 800, 0), grasps or taught_grasps(o)))
    return out


def _static_clouds(placements: list[Placement], rng: np.random.Generator) -> list[np.ndarray]:
    import mujoco

    from robointel.learning.grasp import default_cameras, depth_image, perceive, scene_xml

    cams = default_cameras()
    m0 = mujoco.MjModel.from_xml_string(scene_xml([]))
    d0 = mujoco.MjData(m0)
    mujoco.mj_forward(m0, d0)
    bgs = [depth_image(m0, d0, c, rng) for c in cams]
    m = mujoco.MjModel.from_xml_string(scene_xml(placements))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return perceive(m, d, cams, bgs, rng=rng)


def plot_transfer(plan: GraspPlan, cloud: np.ndarray, path: Path, title: str = "") -> Path:
    """Fig. 6.1: template (rigidly placed), warped template, target cloud and the grasps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fit = plan.classification.best
    T = fit.template.points
    init = fit.warp.inner.inner if hasattr(fit.warp.inner, "inner") else fit.warp.inner
    placed = init(T) + np.array([0.0, 0.0, 0.0])
    warped = fit.warp(T)
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    ax.scatter(*placed.T, s=2, c="tab:gray", alpha=0.3, label="template (placed)")
    ax.scatter(*warped.T, s=3, c="tab:blue", alpha=0.5, label="warped template")
    ax.scatter(*cloud.T, s=4, c="tab:orange", alpha=0.8, label="target (cameras)")
    for g in plan.transferred:
        c, y, z = g.centre, g.axis, g.approach
        ax.plot(*np.array([c - 0.024 * y, c + 0.024 * y]).T, c="tab:green", lw=1.5)
        ax.plot(*np.array([c, c - 0.05 * z]).T, c="tab:green", lw=0.8)
    g = plan.search.grasp
    c, y, z = g.centre, g.axis, g.approach
    for s in (-1, 1):
        tip = c + s * 0.5 * max(g.width, 0.01) * y
        ax.plot(*np.array([tip, tip - 0.04 * z]).T, c="tab:red", lw=3)
    ax.plot(*np.array([c - 0.04 * z - 0.024 * y, c - 0.04 * z + 0.024 * y]).T, c="tab:red", lw=3, label="chosen grasp")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    lo, hi = cloud.min(0) - 0.03, cloud.max(0) + 0.03
    r = (hi - lo).max() / 2
    mid = (hi + lo) / 2
    ax.set_xlim(mid[0] - r, mid[0] + r)
    ax.set_ylim(mid[1] - r, mid[1] + r)
    ax.set_zlim(max(0, mid[2] - r), mid[2] + r)
    ax.legend(loc="upper left", fontsize=7)
    ax.set_title(title or f"{fit.template.category}: residual {1000 * fit.residual:.1f} mm, "
                          f"isotropy {plan.search.quality:.2f}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_confusion(C: np.ndarray, labels: list[str], path: Path, title: str) -> Path:
    """Fig. 6.7: confusion matrix (rows true, columns predicted)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    ax.imshow(C, cmap="Blues")
    ax.set_xticks(range(len(labels)), labels, rotation=45, ha="right")
    ax.set_yticks(range(len(labels)), labels)
    for i in range(C.shape[0]):
        for j in range(C.shape[1]):
            ax.text(j, i, str(C[i, j]), ha="center", va="center", color="k" if C[i, j] < C.max() / 2 else "w")
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


@grasp_app.command()
def teach(out: Path = typer.Option(Path("grasps.h5"), help="grasp database file to write"),
          source: str = typer.Option("demo", help="'demo' (generated objects) or 'ycb' (shared data)")) -> None:
    """Write a grasp database: one template per category with its taught grasps."""
    from robointel.learning.grasp_database import GraspDatabase

    try:
        objs = _objects(source)
        db = GraspDatabase(out)
        t = Table(title=f"grasp database {out}")
        for c in ("template", "category", "points", "taught grasps"):
            t.add_column(c)
        for tm in _templates(objs, sampled=source == 'ycb'):
            db.add(tm, source=f"{source}:{tm.name}")
            t.add_row(tm.name, tm.category, str(len(tm.points)), ", ".join(g.name for g in tm.grasps))
        console.print(t)
    except RobointelError as exc:
        fail(exc)


def _check_db(db: Path | None) -> None:
    """Refuse a missing, foreign or corrupt ``--db`` before any work (one line, exit code 2)."""
    if db is None:
        return
    from robointel.learning.grasp_database import GraspDatabase

    if not Path(db).exists():
        fail(f"grasp database {db} does not exist; build it with `robointel grasp build --out {db}` or leave out --db")
    try:
        GraspDatabase(db).names()
    except RobointelError as exc:
        fail(exc)


def _one_target(source: str, category: str, seed: int, db: Path | None,
                ) -> tuple[dict[str, list[ObjectModel]], ObjectModel, Placement, np.ndarray, list[Template]]:
    from robointel.learning.grasp import random_placements

    objs = _objects(source)
    if category not in objs:
        raise typer.BadParameter(f"category must be one of {sorted(objs)}")
    rng = np.random.default_rng(seed)
    held = objs[category][1:]
    obj = held[int(rng.integers(len(held)))]
    p = random_placements([obj], rng)[0]
    clouds = _static_clouds([p], rng)
    if not clouds:
        fail("the cameras saw nothing")
    return objs, obj, p, clouds[0], _templates(objs, db, sampled=source == 'ycb')


@grasp_app.command("classify")
def classify_cmd(category: str = typer.Option("cup", help="category of the random target"),
                 seed: int = typer.Option(0), source: str = typer.Option("demo"),
                 db: Path = typer.Option(None, help="grasp database (default: templates built on the fly)")) -> None:
    """Place a held-out object at random, perceive it and classify it by registration residual (6.17)-(6.19)."""
    from robointel.learning.grasp import classify

    _check_db(db)
    try:
        _, obj, _, cloud, templates = _one_target(source, category, seed, db)
        t0 = time.perf_counter()
        cls = classify(cloud, templates)
        ms = (time.perf_counter() - t0) * 1e3
        t = Table(title=f"target {obj.name} ({len(cloud)} points after 5 mm voxels): predicted {cls.category}")
        t.add_column("template")
        t.add_column("category")
        t.add_column("residual [mm]", justify="right")
        for tm, r in zip(templates, cls.residuals):
            t.add_row(tm.name, tm.category, f"{1000 * r:.2f}")
        console.print(t)
        console.print(f"classification time {ms:.0f} ms for {len(templates)} templates")
    except RobointelError as exc:
        fail(exc)


@grasp_app.command()
def transfer(category: str = typer.Option("cup"), seed: int = typer.Option(0), source: str = typer.Option("demo"),
             db: Path = typer.Option(None),
             out: Path = typer.Option(Path("grasp_transfer.png"), help="3D picture")) -> None:
    """Plan a grasp on one perceived object and draw it.

    Classify, register, transfer the taught grasps (6.14)-(6.16), score them (6.20) and run the
    orientation search (6.21) with the LR Mate's IK; draws template, warped template, target and grasps.
    """
    from robointel.learning.grasp import GraspPlanner

    _check_db(db)
    try:
        _, obj, _, cloud, templates = _one_target(source, category, seed, db)
        plan = GraspPlanner(templates).plan(cloud)
        s = plan.search
        t = Table(title=f"{obj.name} -> {plan.classification.category}")
        for c in ("grasp", "centre [m]", "approach"):
            t.add_column(c)
        for g in plan.transferred:
            t.add_row(g.name, np.array2string(g.centre, precision=3), np.array2string(g.approach, precision=2))
        console.print(t)
        console.print(f"chosen: isotropy {s.quality:.3f}, turn {np.degrees(s.angle):.0f} deg, feasible {s.feasible}, "
                      f"q = {np.array2string(np.degrees(s.q), precision=1) if s.q is not None else '-'} deg")
        console.print("timings [ms]: " + ", ".join(f"{k} {1000 * v:.0f}" for k, v in plan.timings.items()))
        console.print(f"picture: {plot_transfer(plan, cloud, out)}")
    except RobointelError as exc:
        fail(exc)


@grasp_app.command()
def trial(category: str = typer.Option("all", help="a category or 'all'"),
          n: int = typer.Option(5, help="trials per category"),
          seed: int = typer.Option(0), source: str = typer.Option("demo"), db: Path = typer.Option(None),
          arm: bool = typer.Option(True, help="the whole LR Mate in MuJoCo (--no-arm: the gripper alone on the FK "
                                              "path)")) -> None:
    """MuJoCo lift-and-shake trials (Table 6.2): random placements, perceive, plan, grasp, lift 10 cm, shake."""
    from rich.progress import track

    from robointel.learning.grasp import GraspPlanner, grasp_trial, random_placements

    _check_db(db)
    try:
        objs = _objects(source)
        if category != "all" and category not in objs:
            raise InvalidInput(f"--category must be 'all' or one of {', '.join(objs)}, got {category!r}",
                               value=category)
        planner = GraspPlanner(_templates(objs, db, sampled=source == 'ycb'))
        rng = np.random.default_rng(seed)
        cats = list(objs) if category == "all" else [category]
        t = Table(title="lift-and-shake trials")
        for c in ("category", "success", "classified right", "gripper (48 mm / 85 mm)"):
            t.add_column(c, justify="right")
        tot = 0
        for cat in cats:
            held = objs[cat][1:]
            ok = right = wide = 0
            for k in track(range(n), description=cat):
                o = held[k % len(held)]
                r = grasp_trial(o, random_placements([o], rng)[0], planner, rng=rng, arm=arm)
                ok += int(r.success)
                right += int(r.category == cat)
                wide += int(r.plan is not None and r.plan.gripper != planner.gripper)
            tot += ok
            t.add_row(cat, f"{ok}/{n}", f"{right}/{n}", f"{n - wide} / {wide}")
        console.print(t)
        console.print(f"total {tot}/{n * len(cats)} (dissertation: 18.8/20)")
    except RobointelError as exc:
        fail(exc)


def register(app: typer.Typer) -> None:
    """Add ``robointel grasp`` to the CLI."""
    app.add_typer(grasp_app, name="grasp")


def demo_stage(ctx: StageContext) -> StageResult:
    """Grasping (Ch. 6) on generated objects: CPD time, classification, transfer and MuJoCo trials."""
    from robointel.learning.grasp import (
        GraspPlanner,
        confusion_matrix,
        cpd_nonrigid,
        grasp_trial,
        primitive_object,
        random_placements,
        sample_points,
    )

    ctx.advance(0.02, "objects")
    per = 2 if ctx.quick else 4
    objs = _objects("demo", per_category=per, seed=0)
    templates = _templates(objs)
    # CPD at ~930 points (the dissertation's size), beta 2, lambda 50
    a, b = primitive_object("cup", 41), primitive_object("cup", 42)
    X, Y = sample_points(b, 930, 1), sample_points(a, 930, 2)
    cpd_nonrigid(X, Y, beta=2.0, lmbda=50.0)
    ts = []
    for _ in range(5):
        t0 = time.perf_counter()
        res = cpd_nonrigid(X, Y, beta=2.0, lmbda=50.0)
        ts.append(time.perf_counter() - t0)
    cpd_ms = 1e3 * float(np.median(ts))
    ctx.advance(0.1, "grasp trials")
    planner = GraspPlanner(templates)
    rng = np.random.default_rng(6)
    n = 1 if ctx.quick else 3
    true, pred, ok, plan_ms, shown = [], [], 0, [], None
    cats = list(objs)
    for i, cat in enumerate(cats):
        held = objs[cat][1:]
        for k in range(n):
            o = held[k % len(held)]
            r = grasp_trial(o, random_placements([o], rng)[0], planner, rng=rng)
            true.append(cat)
            pred.append(r.category or "none")
            ok += int(r.success)
            if r.plan is not None:
                plan_ms.append(1e3 * r.plan.timings["total"])
                if shown is None and r.success and r.cloud is not None and cat in ("toy_arm", "cup"):
                    shown = (r.plan, r.cloud, o.name)
            ctx.advance(0.1 + 0.8 * (i * n + k + 1) / (len(cats) * n), f"{cat} trial {k + 1}/{n}")
    C, labels = confusion_matrix(true, pred, cats + (["none"] if "none" in pred else []))
    acc = float(np.mean(np.array(true) == np.array(pred)))
    images = [plot_confusion(C, labels, ctx.out / "grasp_confusion.png", f"classification {100 * acc:.0f}%")]
    if shown is not None:
        images.append(plot_transfer(shown[0], shown[1], ctx.out / "grasp_transfer.png",
                                    f"{shown[2]}: template, warped template, target, grasps (Fig. 6.1)"))
    total = len(true)
    figs = [Figure("CPD non-rigid, ~930 points (beta 2, lambda 50)", f"{cpd_ms:.1f} ms ({res.iterations} it.)",
                   f"{PAPER_CPD_MS:.0f} ms", "low-rank G + float32 E-step; shared 2-core machine"),
            Figure("classification by registration residual", f"{100 * acc:.1f}% ({int(np.trace(C))}/{total})",
                   f"{100 * PAPER_ACCURACY:.2f}% (113/120)", f"{len(cats)} categories, held-out generated instances, "
                   "two simulated depth cameras"),
            Figure("lift-and-shake grasp success", f"{ok}/{total} ({20 * ok / total:.1f}/20)", "18.8/20",
                   "MuJoCo, LR Mate IK + 48 mm or 85 mm parallel gripper, random placements"),
            Figure("classify + register + transfer + score + search per object",
                   f"{np.median(plan_ms):.0f} ms" if plan_ms else "-", None, "")]
    return StageResult("Grasp transfer by non-rigid registration (Ch. 6)", figs, images,
                       "Generated cups, cans, boxes, balls, long tools and toy UR5 arms at random joint angles "
                       "(example-robot-data); one template per category with a few taught grasps.")
