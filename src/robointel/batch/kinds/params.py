"""Typed access to a task spec's parameters."""

from __future__ import annotations

from typing import Any

from robointel.batch.spec import TaskSpec
from robointel.errors import InvalidInput


def param(spec: TaskSpec, name: str, default: Any, kind: type) -> Any:
    """Return ``spec.params[name]`` (or ``default``) checked to be of type ``kind`` (ints pass as floats).

    Raises:
        InvalidInput: the value has another type.
    """
    value = spec.params.get(name, default)
    if value is None:
        return None
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise InvalidInput(f"{spec.kind}: parameter {name!r} must be {kind.__name__}, got {value!r}", value=value)
    return value
