"""Fig. 3.8-style plot of SCARA imitation runs."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from robointel.teach.scara.simulation import ScaraResult  # noqa: E402


def plot_scara(results: Sequence[ScaraResult], path: str | Path) -> None:
    """Write a Fig. 3.8-style plot, one column per run.

    Each column shows the true human angle, the delayed signal the controller receives, the
    predicted signal (compensated runs) and the SCARA's angle in MuJoCo, for both joints.

    Args:
        results: the runs to show.
        path: image file to write (PNG).
    """
    fig, axes = plt.subplots(2, len(results), figsize=(6 * len(results), 5.5), squeeze=False, sharex=True)
    for c, r in enumerate(results):
        for j in range(2):
            ax = axes[j, c]
            ax.plot(r.t, r.q_human[:, j], "k-", lw=1.2, label="human (true)")
            if not r.offline and r.q_delayed is not None:
                ax.plot(r.t, r.q_delayed[:, j], "C1-", lw=0.7, alpha=0.8,
                        label=f"received (delayed {r.latency:.2f} s)")
            if r.compensated and r.q_pred is not None:
                ax.plot(r.t, r.q_pred[:, j], "C2--", lw=0.8, label="predicted")
            ax.plot(r.t, r.q[:, j], "C0-", lw=1.0, label="SCARA (MuJoCo)")
            ax.set_ylabel(f"q{j + 1} [rad]")
            mode = ("offline replay (recording known, no latency)" if r.offline else
                    "with delay compensation" if r.compensated else "without delay compensation")
            ax.set_title(f"{mode}: q{j + 1} RMS vs human {r.rms[j]:.3f} rad", fontsize=9)
            if j == 1:
                ax.set_xlabel("t [s]")
        axes[0, c].legend(fontsize=7, loc="best")
    fig.suptitle(f"Dynamic imitation on the 2-link SCARA (computed torque + LQ), live latency "
                 f"{max(r.latency for r in results):.2f} s: {results[0].source}",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
