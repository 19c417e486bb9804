"""Success rates of a result store per kind and category, with Wilson score intervals, and a plot."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the file backend)
import numpy as np  # noqa: E402
from scipy.stats import binomtest  # noqa: E402

from robointel.batch.store import ResultStore  # noqa: E402
from robointel.errors import InvalidInput  # noqa: E402

__all__ = ["GroupSummary", "plot_summary", "summarize", "wilson_interval"]


def wilson_interval(successes: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial success rate (scipy's ``binomtest(...).proportion_ci``).

    Args:
        successes: k, 0 <= k <= n.
        trials: n >= 1.
        confidence: Confidence level in (0, 1).

    Returns:
        (low, high) bounds of the rate.

    Raises:
        InvalidInput: counts out of range or confidence outside (0, 1).
    """
    if trials < 1 or not 0 <= successes <= trials or not 0.0 < confidence < 1.0:
        raise InvalidInput(f"need 0 <= successes <= trials, trials >= 1 and 0 < confidence < 1; got "
                           f"{successes}/{trials} at {confidence}", value=(successes, trials, confidence))
    ci = binomtest(int(successes), int(trials)).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)


@dataclass(frozen=True)
class GroupSummary:
    """Results of one (kind, category) group.

    Attributes:
        kind: Trial kind.
        category: Category within the kind.
        trials: Rows in the group.
        successes: Successful rows.
        low: Lower Wilson bound of the success rate (95 %).
        high: Upper Wilson bound.
        reasons: Failure reasons and their counts.
        median_wall_s: Median wall time of a task (s).
    """

    kind: str
    category: str
    trials: int
    successes: int
    low: float
    high: float
    reasons: dict[str, int] = field(default_factory=dict)
    median_wall_s: float = float("nan")

    @property
    def rate(self) -> float:
        """Success rate successes / trials."""
        return self.successes / self.trials


def summarize(results: str | Path | ResultStore, confidence: float = 0.95) -> list[GroupSummary]:
    """Group a result store by (kind, category) with Wilson intervals.

    Args:
        results: A result folder or an open store.
        confidence: Confidence level of the intervals.

    Returns:
        One summary per group, sorted by kind then category.

    Raises:
        InvalidInput: the folder holds no results.
    """
    store = results if isinstance(results, ResultStore) else ResultStore(results)
    t = store.table()
    if t.num_rows == 0:
        raise InvalidInput(f"no results in {store.root}", value=str(store.root))
    kinds, cats = t.column("kind").to_pylist(), t.column("category").to_pylist()
    succ, reasons = t.column("success").to_pylist(), t.column("reason").to_pylist()
    wall = t.column("wall_s").to_pylist()
    groups: dict[tuple[str, str], list[int]] = {}
    for i, g in enumerate(zip(kinds, cats)):
        groups.setdefault(g, []).append(i)
    out = []
    for (kind, cat), idx in sorted(groups.items()):
        k = sum(bool(succ[i]) for i in idx)
        lo, hi = wilson_interval(k, len(idx), confidence)
        why = Counter(reasons[i] for i in idx if not succ[i])
        out.append(GroupSummary(kind, cat, len(idx), k, lo, hi, dict(why.most_common()),
                                float(np.median([wall[i] for i in idx]))))
    return out


def plot_summary(groups: list[GroupSummary], path: str | Path,
                 title: str = "success rate (95% Wilson interval)") -> Path:
    """Draw the success rate of each group with its interval as a horizontal bar chart (PNG).

    Args:
        groups: From :func:`summarize`.
        path: Output file (.png).
        title: Plot title.

    Returns:
        The written path.
    """
    path = Path(path)
    fig, ax = plt.subplots(figsize=(7, 0.45 * len(groups) + 1.4))
    y = np.arange(len(groups))
    rate = np.array([g.rate for g in groups])
    err = np.array([[g.rate - g.low for g in groups], [g.high - g.rate for g in groups]])
    ax.barh(y, rate, color="tab:blue", alpha=0.7)
    ax.errorbar(rate, y, xerr=err, fmt="none", ecolor="k", capsize=3)
    ax.set_yticks(y, [f"{g.kind}: {g.category} ({g.successes}/{g.trials})" for g in groups])
    ax.invert_yaxis()
    ax.set_xlim(0, 1)
    ax.set_xlabel("success rate")
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
