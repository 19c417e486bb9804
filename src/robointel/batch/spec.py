"""Task specs: one trial described by its kind, seed and parameters, and sweep files of them.

A :class:`TaskSpec` is small and serialisable (plain JSON types only), so it crosses process and
machine boundaries unchanged. Its :attr:`TaskSpec.spec_hash` is stable across runs, machines and
Python versions: the first 16 hex digits of the SHA-256 of the canonical JSON of ``kind`` and
``params`` (the seed is not part of it). A result row is keyed by ``(spec_hash, seed)``.

A sweep file (YAML) lists groups of tasks::

    name: insertion-gains
    tasks:
      - kind: insertion
        seeds: {start: 0, count: 20}      # or a list: [0, 1, 2]
        params: {controller: impedance}
        grid: {rot_stiffness: [100, 300]} # optional: one spec per combination, merged into params
        category: impedance               # optional: the report's grouping (default: kind-specific)
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from robointel.errors import InvalidInput, SweepFileError

__all__ = ["TaskSpec", "expand_group", "load_sweep", "sweep_from_dict"]


def _canonical(value: Any, where: str) -> Any:
    """Return ``value`` as plain JSON types (dict with str keys, list, str, int, float, bool, None).

    Raises:
        InvalidInput: a value is not JSON-representable or a float is not finite.
    """
    if value is None or isinstance(value, bool | str):
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise InvalidInput(f"{where}: parameters must be finite, got {value!r}", value=value)
        return float(value)
    if isinstance(value, Mapping):
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise InvalidInput(f"{where}: parameter names must be strings, got {k!r}", value=k)
            out[k] = _canonical(v, f"{where}.{k}")
        return out
    if isinstance(value, list | tuple):
        return [_canonical(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if hasattr(value, "item") and callable(value.item):  # numpy scalar
        return _canonical(value.item(), where)
    raise InvalidInput(f"{where}: {type(value).__name__} is not serialisable (use numbers, strings, lists, dicts)",
                       value=value)


@dataclass(frozen=True)
class TaskSpec:
    """One trial to run.

    Attributes:
        kind: The registered trial kind (see :func:`robointel.batch.registry.kinds`).
        seed: The trial's seed (int >= 0); the trial is a pure function of ``(kind, params, seed)``.
        params: JSON-serialisable parameters of the kind.
        category: The report's grouping; empty: the kind decides (e.g. the object category).
    """

    kind: str
    seed: int
    params: dict[str, Any] = field(default_factory=dict)
    category: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.kind, str) or not self.kind:
            raise InvalidInput(f"a task needs a non-empty kind, got {self.kind!r}", value=self.kind)
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InvalidInput(f"a task seed is an int >= 0, got {self.seed!r}", value=self.seed)
        object.__setattr__(self, "params", _canonical(dict(self.params), f"{self.kind}.params"))
        object.__setattr__(self, "category", str(self.category or ""))

    @property
    def spec_hash(self) -> str:
        """16 hex digits of SHA-256 over the canonical JSON of ``kind`` and ``params`` (not the seed)."""
        text = json.dumps({"kind": self.kind, "params": self.params}, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    @property
    def key(self) -> tuple[str, int]:
        """The result store's row key ``(spec_hash, seed)``."""
        return (self.spec_hash, self.seed)

    def to_dict(self) -> dict[str, Any]:
        """Return the spec as plain JSON types."""
        return {"kind": self.kind, "seed": self.seed, "params": self.params, "category": self.category}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> TaskSpec:
        """Rebuild a spec from :meth:`to_dict` output.

        Raises:
            InvalidInput: a field is missing or invalid.
        """
        try:
            return cls(str(d["kind"]), int(d["seed"]), dict(d.get("params") or {}), str(d.get("category") or ""))
        except KeyError as exc:
            raise InvalidInput(f"a task spec needs {exc.args[0]!r}", value=dict(d)) from None


def _seeds(value: Any, where: str) -> list[int]:
    if isinstance(value, Mapping):
        start, count = int(value.get("start", 0)), value.get("count")
        if count is None or int(count) < 0:
            raise SweepFileError(f"{where}: seeds {{start, count}} needs count >= 0", value=value)
        return list(range(start, start + int(count)))
    if isinstance(value, int) and not isinstance(value, bool):
        return list(range(value))
    if isinstance(value, list) and all(isinstance(s, int) and not isinstance(s, bool) for s in value):
        return [int(s) for s in value]
    raise SweepFileError(f"{where}: seeds must be a count, a list of ints or {{start, count}}, got {value!r}",
                         value=value)


def expand_group(group: Mapping[str, Any], where: str = "task group") -> list[TaskSpec]:
    """Expand one sweep group (kind, seeds, params, optional grid and category) into task specs.

    Args:
        group: ``{"kind": str, "seeds": ..., "params": {...}, "grid": {name: [values]}, "category": str}``.
        where: Where the group is (for messages).

    Returns:
        One spec per grid combination and seed, in file order.

    Raises:
        SweepFileError: a field is missing or has the wrong type.
    """
    if not isinstance(group, Mapping) or "kind" not in group:
        raise SweepFileError(f"{where}: each task group needs a 'kind'", value=group)
    unknown = set(group) - {"kind", "seeds", "params", "grid", "category"}
    if unknown:
        raise SweepFileError(f"{where}: unknown fields {sorted(unknown)}", value=sorted(unknown))
    params = dict(group.get("params") or {})
    grid = dict(group.get("grid") or {})
    for name, values in grid.items():
        if not isinstance(values, list) or not values:
            raise SweepFileError(f"{where}: grid.{name} must be a non-empty list", value=values)
    seeds = _seeds(group.get("seeds", 1), where)
    out = []
    names = list(grid)
    for combo in itertools.product(*(grid[n] for n in names)):
        p = {**params, **dict(zip(names, combo))}
        for s in seeds:
            out.append(TaskSpec(str(group["kind"]), s, p, str(group.get("category") or "")))
    return out


def sweep_from_dict(d: Mapping[str, Any]) -> list[TaskSpec]:
    """Expand a parsed sweep file (``{"tasks": [group, ...]}``) into task specs.

    Raises:
        SweepFileError: the structure is wrong, or two groups produce the same (spec hash, seed).
    """
    groups = d.get("tasks") if isinstance(d, Mapping) else None
    if not isinstance(groups, list) or not groups:
        raise SweepFileError("a sweep file needs a non-empty list 'tasks'", value=d)
    specs: list[TaskSpec] = []
    for i, g in enumerate(groups):
        specs += expand_group(g, f"tasks[{i}]")
    seen: set[tuple[str, int]] = set()
    for s in specs:
        if s.key in seen:
            raise SweepFileError(f"task {s.kind} seed {s.seed} params {s.params} appears twice", value=s.to_dict())
        seen.add(s.key)
    return specs


def load_sweep(path: str | Path) -> list[TaskSpec]:
    """Read a sweep YAML file and expand it into task specs.

    Raises:
        SweepFileError: the file is missing, is not YAML or has the wrong structure.
    """
    p = Path(path)
    if not p.is_file():
        raise SweepFileError(f"sweep file {p} does not exist", value=str(p))
    try:
        d = yaml.safe_load(p.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise SweepFileError(f"sweep file {p} is not valid YAML: {' '.join(str(exc).split())}",
                             value=str(p)) from None
    except OSError as exc:
        raise SweepFileError(f"cannot read sweep file {p}: {exc}", value=str(p)) from None
    try:
        return sweep_from_dict(d)
    except SweepFileError as exc:
        raise SweepFileError(f"{p}: {exc}", value=exc.value) from None


def unique(specs: Iterable[TaskSpec]) -> list[TaskSpec]:
    """Return ``specs`` without repeated keys (first occurrence kept, order preserved)."""
    seen: set[tuple[str, int]] = set()
    out = []
    for s in specs:
        if s.key not in seen:
            seen.add(s.key)
            out.append(s)
    return out
