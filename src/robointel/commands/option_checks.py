"""The ranges of every numeric command-line option, checked before a command starts.

Each ``float`` option must be finite (``nan``, ``inf`` are refused), and the options below must lie in
their range: a count of trials is at least 1, a time limit positive, a seed a non-negative 32-bit
integer. The rules are keyed by option name (the same name means the same thing in every command);
a ``(command, option)`` key overrides one command's rule, and an option that declares its own range
(``min``/``max``) keeps it (finite only is added). :func:`install` attaches the checks to
every command of the ``robointel`` group, so a garbage number gives one ``error:`` line and exit
code 2 before any work starts (:mod:`robointel.commands.failure`).
"""
from __future__ import annotations

import math
import typing
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import typer

__all__ = ["RANGES", "Range", "check_number", "install"]


@dataclass(frozen=True)
class Range:
    """An allowed interval ``[low, high]`` (``open_low``: ``low`` itself excluded); None: unbounded."""

    low: float | None = None
    high: float | None = None
    open_low: bool = False
    open_high: bool = False

    def describe(self) -> str:
        """The interval in words, e.g. ``> 0`` or ``in [1, 65535]``."""
        lo, hi = _num(self.low), _num(self.high)
        if self.low is not None and self.high is not None:
            return f"in {'(' if self.open_low else '['}{lo}, {hi}{')' if self.open_high else ']'}"
        if self.low is not None:
            return f"{'>' if self.open_low else '>='} {lo}"
        if self.high is not None:
            return f"{'<' if self.open_high else '<='} {hi}"
        return "finite"

    def contains(self, v: float) -> bool:
        """True when ``v`` lies in the interval."""
        if self.low is not None and (v < self.low or (self.open_low and v == self.low)):
            return False
        return not (self.high is not None and (v > self.high or (self.open_high and v == self.high)))


def _num(v: float | None) -> str:
    return "" if v is None else str(int(v)) if float(v).is_integer() else f"{v:g}"


COUNT = Range(1, 1_000_000)
POSITIVE = Range(0, None, open_low=True)
NON_NEGATIVE = Range(0, None)
RANGES: dict[str | tuple[str, str], Range] = {
    # counts
    "--n": COUNT, "--trials": COUNT, "--demos": COUNT, "--labelled": COUNT, "--per-family": COUNT,
    "--workers": Range(1, 1024), "--flush-rows": COUNT, "--max-retries": Range(0, 1000),
    # seeds and indices
    "--seed": Range(0, 2 ** 32 - 1), "--index": Range(0, 1_000_000), "--scenario": Range(1, 1000),
    # times, s (a duration 0 may mean "until stopped")
    "--time-limit": POSITIVE, "--time-budget": POSITIVE, "--timeout": POSITIVE, "--duration": NON_NEGATIVE,
    "--guidance-seconds": POSITIVE, "--latency": Range(0, 2), "--stall-ms": POSITIVE, "--hold": POSITIVE,
    "--rate": Range(1, 1000),
    # sizes, speeds and tolerances
    "--clearance": POSITIVE, "--speed": POSITIVE, "--tolerance": POSITIVE, "--d-min": NON_NEGATIVE,
    "--cpus-per-task": Range(0, 1024, open_low=True), "--worker-niceness": Range(0, 19),
    "--confidence": Range(0, 1, open_low=True, open_high=True),
    # ports
    "--port": Range(1, 65535), "--stream-port": Range(1, 65535),
}


def check_number(value: Any, option: str, rule: Range | None) -> Any:
    """Return ``value`` if it is a usable number for ``option``.

    Args:
        value: the parsed option value (int, float or None for an unset optional option).
        option: the option's name (``--n``), for the message.
        rule: its range, or None (finite only).

    Returns:
        The value unchanged.

    Raises:
        typer.BadParameter: NaN, inf, or outside the range.
    """
    if value is None or isinstance(value, bool) or not isinstance(value, int | float):
        return value
    if isinstance(value, float) and not math.isfinite(value):
        raise typer.BadParameter(f"must be a finite number, got {value}")
    if rule is not None and not rule.contains(float(value)):
        raise typer.BadParameter(f"must be {rule.describe()}, got {_num(value)}")
    return value


def _numeric(param: Any) -> bool:
    desc = getattr(param, "type_descriptor", None)
    ann = getattr(desc, "annotation", None)
    if ann is None:  # click's own parameter types
        name = getattr(getattr(param, "type", None), "name", "")
        return name in ("float", "integer", "float range", "integer range")
    return ann in (int, float) or any(a in (int, float) for a in typing.get_args(ann))


def _declares_range(param: Any) -> bool:
    """True when the option declares its own ``min``/``max`` (typer's option, or click's range type)."""
    holders = (param, getattr(param, "type", None))
    return any(getattr(h, k, None) is not None for h in holders for k in ("min", "max"))


def _commands(group: Any, path: tuple[str, ...] = ()) -> Iterator[tuple[str, Any]]:
    for name, cmd in getattr(group, "commands", {}).items():
        if getattr(cmd, "commands", None) is not None:
            yield from _commands(cmd, (*path, name))
        else:
            yield " ".join((*path, name)), cmd


def install(group: Any) -> None:
    """Attach the checks to every numeric option of every command under ``group`` (idempotent).

    Args:
        group: the click group typer built for the ``robointel`` app.
    """
    for path, cmd in _commands(group):
        for p in cmd.params:
            if not _numeric(p) or getattr(p, "_robointel_checked", False):
                continue
            option = max(p.opts, key=len) if p.opts else p.name
            rule = RANGES.get((path, option), RANGES.get(option))
            if (path, option) not in RANGES and _declares_range(p):
                rule = None  # the command declares its own range (``learn insertion --trials 0``: learn only)
            previous = p.callback

            def callback(ctx: Any, param: Any, value: Any, _rule: Range | None = rule, _opt: str = option,
                         _prev: Any = previous) -> Any:
                value = check_number(value, _opt, _rule)
                return _prev(ctx, param, value) if _prev is not None else value

            p.callback = callback
            p._robointel_checked = True
