"""Semantic robot description (SRDF): the link pairs whose collisions are never checked."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable
from pathlib import Path

from robointel.errors import InvalidInput


def disabled_pairs(path: str | Path, link_names: Iterable[str]) -> set[frozenset[str]]:
    """Read the ``<disable_collisions link1=.. link2=..>`` pairs of an SRDF file.

    Args:
        path: the SRDF file.
        link_names: the robot's link names; every pair must name two of them.

    Returns:
        The disabled pairs, each a frozenset of two link names.

    Raises:
        InvalidInput: the file is missing or not XML, an entry lacks ``link1``/``link2``, or names
            a link the robot does not have (the message gives the file and the key).
    """
    p = Path(path)
    try:
        root = ET.parse(p).getroot()
    except (OSError, ET.ParseError) as exc:
        raise InvalidInput(f"cannot read SRDF {p}: {exc}", value=str(p)) from None
    links = set(link_names)
    out: set[frozenset[str]] = set()
    for k, e in enumerate(root.iter("disable_collisions")):
        a, b = e.get("link1"), e.get("link2")
        if not a or not b:
            raise InvalidInput(f"SRDF {p}: disable_collisions entry {k} lacks link1 or link2", value=str(p))
        for key, name in (("link1", a), ("link2", b)):
            if name not in links:
                raise InvalidInput(f"SRDF {p}: disable_collisions entry {k} {key}={name!r} is not a link of the "
                                   "robot", value=name)
        out.add(frozenset((a, b)))
    return out
