"""The registry of trial kinds: a name -> a pure function ``TaskSpec -> TrialOutcome``.

A kind's function must be a pure function of the spec (kind, params, seed): run twice, in any
process or on any machine, it gives the same outcome (timings aside). That is what makes a task
idempotent, so a task whose worker died can be run again and recorded once.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass

from robointel.batch.kinds import BUILTIN
from robointel.batch.spec import TaskSpec
from robointel.errors import InvalidInput, UnknownTaskKind
from robointel.outcome import TrialOutcome

__all__ = ["TrialKind", "get_kind", "kinds", "register_kind"]

TrialFunction = Callable[[TaskSpec], TrialOutcome]


@dataclass(frozen=True)
class TrialKind:
    """A registered trial kind.

    Attributes:
        name: The kind's name in sweep files.
        run: The pure trial function ``spec -> TrialOutcome``.
        category: ``spec -> str``: the report's grouping when the spec names none.
        summary: One line for ``robointel batch kinds``.
        cost: ``spec -> s``: the task's typical duration on one core, a scheduling hint only (the Ray
            engine starts the longest tasks first, so that no worker is left alone with a long trial
            at the end of a sweep). ``None``: 1 s.
    """

    name: str
    run: TrialFunction
    category: Callable[[TaskSpec], str]
    summary: str = ""
    cost: Callable[[TaskSpec], float] | None = None

    def expected_s(self, spec: TaskSpec) -> float:
        """The expected duration of ``spec`` (s; :attr:`cost`, 1 s without one)."""
        return 1.0 if self.cost is None else float(self.cost(spec))


_KINDS: dict[str, TrialKind] = {}


def register_kind(name: str, run: TrialFunction, *, category: Callable[[TaskSpec], str] | None = None,
                  summary: str = "", replace: bool = False, cost: Callable[[TaskSpec], float] | None = None,
                  ) -> TrialKind:
    """Register a trial kind.

    Args:
        name: The kind's name (non-empty).
        run: The pure trial function.
        category: The report grouping of a spec (default: the kind's name).
        summary: One-line description.
        replace: Allow replacing an existing kind.
        cost: The expected duration of a spec (s), a scheduling hint (see :class:`TrialKind`).

    Returns:
        The registered kind.

    Raises:
        InvalidInput: the name is empty or taken (and ``replace`` is False).
    """
    if not name:
        raise InvalidInput("a trial kind needs a name", value=name)
    if name in _KINDS and not replace:
        raise InvalidInput(f"trial kind {name!r} is already registered", value=name)
    kind = TrialKind(name, run, category or (lambda spec: spec.kind), summary, cost)
    if name in BUILTIN and not replace:
        raise InvalidInput(f"trial kind {name!r} is built in", value=name)
    _KINDS[name] = kind
    return kind


def get_kind(name: str) -> TrialKind:
    """Return the registered kind ``name``.

    A name ``"package.module:function"`` names a trial function any process can import (the way to
    run your own kind on Ray workers, which do not see kinds registered in the driver).

    Raises:
        UnknownTaskKind: no kind of that name (the message lists the known kinds).
    """
    if name not in _KINDS and name in BUILTIN:
        _KINDS[name] = importlib.import_module(BUILTIN[name]).KIND
    elif name not in _KINDS and ":" in name:  # "package.module:function": importable on every worker
        module, _, attr = name.partition(":")
        try:
            fn = getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError) as exc:
            raise UnknownTaskKind(f"trial kind {name!r}: cannot import {attr!r} from {module!r} ({exc})",
                                  value=name) from None
        _KINDS[name] = TrialKind(name, fn, lambda spec: attr, f"{module}.{attr}")
    try:
        return _KINDS[name]
    except KeyError:
        raise UnknownTaskKind(f"unknown trial kind {name!r}; known kinds: {', '.join(sorted({*BUILTIN, *_KINDS}))}",
                              value=name) from None


def kinds() -> dict[str, TrialKind]:
    """Return all registered kinds by name (imports every built-in kind's module)."""
    for name in BUILTIN:
        get_kind(name)
    return dict(_KINDS)
