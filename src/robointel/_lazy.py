"""Public names of a package imported from their modules on first access (PEP 562), so importing it stays light."""
from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any


def lazy_exports(package: str, exports: dict[str, str],
                 public: list[str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module-level ``__getattr__`` and ``__dir__`` of ``package``.

    Use as ``__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)``, with the same names
    imported under ``TYPE_CHECKING`` for type checkers.

    Args:
        package: the package's ``__name__``.
        exports: public name -> the module that defines it.
        public: the package's ``__all__``.

    Returns:
        ``__getattr__`` (imports ``exports[name]`` and returns its attribute; AttributeError for other
        names) and ``__dir__`` (the public names).
    """

    def __getattr__(name: str) -> Any:
        if name in exports:
            return getattr(importlib.import_module(exports[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return list(public)

    return __getattr__, __dir__
