"""The HTML report of a task-program run: the steps with their outcomes and times, the joint plot."""

from __future__ import annotations

import base64
import html
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from robointel.io.mcap_log import McapRecorder  # noqa: E402
from robointel.program import Program, ProgramRun  # noqa: E402
from robointel.program.check import ProgramCheck  # noqa: E402
from robointel.program.runner import StepResult  # noqa: E402


def plot_run(program: Program, run: ProgramRun, path: Path) -> Path:
    """Plot the measured joint angles of every moving step, one after the other, with step boundaries.

    Args:
        program: The program that ran.
        run: Its run.
        path: The PNG file to write.

    Returns:
        The path written.
    """
    fig, ax = plt.subplots(figsize=(10, 4))
    t0 = 0.0
    names = program.robot.joint_names
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for r in run.steps:
        if len(r.executed) == 0:
            continue
        t = t0 + np.arange(len(r.executed)) * 1e-3
        for j in range(r.executed.shape[1]):
            ax.plot(t, np.degrees(r.executed[:, j]), color=colors[j % len(colors)],
                    label=names[j] if t0 == 0.0 else None)
        ax.axvline(t0, color="0.8", lw=0.6, zorder=0)
        ax.text(t0, ax.get_ylim()[1] if ax.lines else 0, r.name, fontsize=6, rotation=90, va="top")
        t0 = float(t[-1])
    ax.set_xlabel("motion time [s]")
    ax.set_ylabel("q [deg]")
    ax.set_title(f"program {program.name!r}: measured joints")
    if ax.lines:
        ax.legend(ncol=6, fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def write_program_report(program: Program, run: ProgramRun, out: Path) -> Path:
    """Write ``out/index.html``: the check time, each step's outcome, time and reason, the joint plot.

    Args:
        program: The program that ran.
        run: Its run.
        out: The report folder (created).

    Returns:
        The HTML file.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    png = plot_run(program, run, out / "joints.png")
    status = "succeeded" if run.success else f"FAILED at step {run.failed_step}"
    rows = []
    for r in run.steps:
        plan = run.check.plans[r.index]
        moved = "" if plan.trajectory is None else f"{plan.trajectory.duration:.2f} s"
        rows.append(f"<tr><td>{r.index}</td><td>{html.escape(r.name)}</td><td>{r.kind}</td>"
                    f"<td>{'ok' if r.outcome.success else html.escape(r.outcome.reason.value)}</td>"
                    f"<td>{moved}</td><td>{plan.plan_ms:.1f}</td><td>{r.seconds * 1e3:.1f}</td>"
                    f"<td>{html.escape(r.outcome.detail)}{' (replanned)' if r.replanned else ''}</td></tr>")
    img = base64.b64encode(png.read_bytes()).decode()
    page = ("<!doctype html><html><head><meta charset='utf-8'><title>robointel program report</title><style>"
            "body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;color:#222}"
            "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:4px 8px}th{background:#f0f0f0}"
            "img{max-width:100%}</style></head><body>"
            f"<h1>program {html.escape(program.name)}: {status}</h1>"
            f"<p>pre-run check {run.check.check_ms:.0f} ms; source {html.escape(str(program.source or '-'))}</p>"
            "<table><tr><th>#</th><th>step</th><th>kind</th><th>outcome</th><th>motion</th><th>plan [ms]</th>"
            "<th>run [ms]</th><th>detail</th></tr>" + "".join(rows) + "</table>"
            f"<img src='data:image/png;base64,{img}' alt='joints'></body></html>")
    index = out / "index.html"
    index.write_text(page)
    return index


@dataclass
class _Sample:
    """A joint-state sample for the recorder (the Recorder protocol's state)."""

    t: float
    q: np.ndarray
    qd: np.ndarray
    wrench: None = None


class StepRecorder:
    """Record a simulated run step by step as it runs (``run_program(..., on_step=StepRecorder(...))``).

    Each step's checked trajectory (``move`` and ``path`` steps) goes to the trajectory topic at its
    start time and its measured joints (1 ms grid) to ``/joint_states`` every ``period`` s, the steps
    one after the other on one clock. The recorder writes them to its file as it goes.

    Args:
        recorder: The open recorder (closed by the caller).
        check: The pre-run check whose plans the steps follow.
        period: Spacing of the recorded joint states, s.

    Attributes:
        count: Joint states recorded so far.
    """

    def __init__(self, recorder: McapRecorder, check: ProgramCheck, *, period: float = 0.008) -> None:
        self.recorder, self.check = recorder, check
        self.every = max(1, int(round(period / 1e-3)))
        self.t0 = 0.0
        self.count = 0

    def __call__(self, r: StepResult) -> None:
        """Record one finished step."""
        plan = self.check.plans[r.index]
        if plan.trajectory is not None and not r.replanned:
            self.recorder.trajectory(self.t0, plan.trajectory)
        Q = r.executed
        if len(Q) == 0:
            return
        qd = np.gradient(Q, 1e-3, axis=0) if len(Q) > 1 else np.zeros_like(Q)
        for k in range(0, len(Q), self.every):
            self.recorder.joint_state(_Sample(self.t0 + k * 1e-3, Q[k], qd[k]))
            self.count += 1
        self.t0 += len(Q) * 1e-3


def record_run(recorder: McapRecorder, program: Program, run: ProgramRun, *, period: float = 0.008) -> int:
    """Record a finished simulated run (as :class:`StepRecorder` does while it runs).

    Args:
        recorder: The open recorder (closed by the caller).
        program: The program that ran.
        run: Its run.
        period: Spacing of the recorded joint states, s.

    Returns:
        The number of joint states recorded.
    """
    rec = StepRecorder(recorder, run.check, period=period)
    for r in run.steps:
        rec(r)
    return rec.count
