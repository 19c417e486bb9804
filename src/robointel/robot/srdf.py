"""Semantic robot description (SRDF): planning groups, group states and disabled collision pairs.

Read as MoveIt reads it: an entry naming a link or joint the URDF lacks is skipped with a
:class:`~robointel.errors.DescriptionWarning` that names it (the file stays usable); a file that is
not XML, or an element that lacks a required attribute, raises :class:`~robointel.errors.InvalidInput`
naming the file and the element.
"""
from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from robointel.errors import DescriptionWarning, InvalidInput


@dataclass(frozen=True)
class GroupSpec:
    """One ``<group>`` of an SRDF, as written (names not yet resolved against a URDF).

    Attributes:
        name: the group name.
        joints: ``<joint name>`` entries.
        links: ``<link name>`` entries (MoveIt: the joint that moves each link joins the group).
        chains: ``<chain base_link tip_link>`` entries as (base, tip).
        subgroups: ``<group name>`` entries (other groups included whole).
    """

    name: str
    joints: tuple[str, ...] = ()
    links: tuple[str, ...] = ()
    chains: tuple[tuple[str, str], ...] = ()
    subgroups: tuple[str, ...] = ()


@dataclass(frozen=True)
class SRDF:
    """What robointel reads of an SRDF file.

    Attributes:
        path: the file.
        groups: planning groups by name.
        group_states: named joint values per group, ``{group: {state: {joint: value}}}`` (rad or m).
        disabled: link pairs whose collisions are never checked, each a frozenset of two link names
            (only pairs whose two links exist in the robot, when read with ``link_names``).
        skipped: a message for every entry skipped because it names an absent link or joint.
    """

    path: Path
    groups: dict[str, GroupSpec] = field(default_factory=dict)
    group_states: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)
    disabled: frozenset[frozenset[str]] = frozenset()
    skipped: tuple[str, ...] = ()


def _element(p: Path, tag: str, k: int, e: ET.Element, attr: str) -> str:
    v = e.get(attr)
    if not v:
        raise InvalidInput(f"SRDF {p}: <{tag}> element {k} lacks the attribute {attr!r}", value=str(p))
    return v


def read_srdf(path: str | Path, link_names: Iterable[str] | None = None, *, warn: bool = True) -> SRDF:
    """Read an SRDF file.

    Args:
        path: the SRDF file.
        link_names: the robot's link names; ``disable_collisions`` entries naming another link are
            skipped (None: keep every entry).
        warn: emit one :class:`~robointel.errors.DescriptionWarning` per skipped entry.

    Returns:
        The :class:`SRDF`.

    Raises:
        InvalidInput: the file is missing or not XML, or an element lacks a required attribute
            (the message gives the file, the element and the attribute), or a group state value is
            not a number.
    """
    p = Path(path)
    try:
        root = ET.parse(p).getroot()
    except (OSError, ET.ParseError) as exc:
        raise InvalidInput(f"cannot read SRDF {p}: {exc}", value=str(p)) from None
    links = set(link_names) if link_names is not None else None
    skipped: list[str] = []
    disabled: set[frozenset[str]] = set()
    for k, e in enumerate(root.iter("disable_collisions")):
        a, b = _element(p, "disable_collisions", k, e, "link1"), _element(p, "disable_collisions", k, e, "link2")
        absent = [f"{key}={name!r}" for key, name in (("link1", a), ("link2", b)) if links is not None and
                  name not in links]
        if absent:
            skipped.append(f"SRDF {p}: disable_collisions entry {k} ({', '.join(absent)}) names a link the robot "
                           "does not have; entry skipped")
            continue
        disabled.add(frozenset((a, b)))
    groups: dict[str, GroupSpec] = {}
    for k, g in enumerate(root.findall("group")):
        name = _element(p, "group", k, g, "name")
        joints = tuple(_element(p, f"group {name!r} joint", i, e, "name") for i, e in enumerate(g.findall("joint")))
        glinks = tuple(_element(p, f"group {name!r} link", i, e, "name") for i, e in enumerate(g.findall("link")))
        where = f"group {name!r} chain"
        chains = tuple((_element(p, where, i, e, "base_link"), _element(p, where, i, e, "tip_link"))
                       for i, e in enumerate(g.findall("chain")))
        subs = tuple(_element(p, f"group {name!r} group", i, e, "name") for i, e in enumerate(g.findall("group")))
        groups[name] = GroupSpec(name, joints, glinks, chains, subs)
    states: dict[str, dict[str, dict[str, float]]] = {}
    for k, s in enumerate(root.findall("group_state")):
        sname, gname = _element(p, "group_state", k, s, "name"), s.get("group", "")  # "": the whole robot
        vals: dict[str, float] = {}
        for i, e in enumerate(s.findall("joint")):
            jn = _element(p, f"group_state {sname!r} joint", i, e, "name")
            raw = _element(p, f"group_state {sname!r} joint", i, e, "value")
            try:
                vals[jn] = float(raw.split()[0])
            except (ValueError, IndexError):
                raise InvalidInput(f"SRDF {p}: group_state {sname!r} joint {jn!r} value {raw!r} is not a number",
                                   value=raw) from None
        states.setdefault(gname, {})[sname] = vals
    if warn and skipped:
        names = sorted({n for e in root.iter("disable_collisions") for n in (e.get("link1") or "", e.get("link2") or "")
                        if links is not None and n not in links})
        warnings.warn(f"SRDF {p}: {len(skipped)} disable_collisions entries name links the robot does not have "
                      f"({', '.join(names)}); those entries are skipped", DescriptionWarning, stacklevel=3)
    return SRDF(p, groups, states, frozenset(disabled), tuple(skipped))


def disabled_pairs(path: str | Path, link_names: Iterable[str]) -> set[frozenset[str]]:
    """The ``<disable_collisions link1=.. link2=..>`` pairs of an SRDF file whose links both exist.

    Args:
        path: the SRDF file.
        link_names: the robot's link names; an entry naming another link is skipped with a
            :class:`~robointel.errors.DescriptionWarning` naming it, as MoveIt does.

    Returns:
        The disabled pairs, each a frozenset of two link names.

    Raises:
        InvalidInput: the file is missing or not XML, or an entry lacks ``link1``/``link2`` (the
            message gives the file and the entry).
    """
    return set(read_srdf(path, link_names).disabled)


def group_joints(srdf: SRDF, group: str, *, movable: list[str], chain: object) -> list[str]:
    """The movable joints of SRDF group ``group``, in the order of ``movable`` (the model's order).

    Args:
        srdf: the parsed SRDF.
        group: the group name.
        movable: the robot's movable joint names, in model order.
        chain: a callable ``chain(base_link, tip_link) -> list[str]`` giving the movable joints
            between two links (it raises for unknown links).

    Returns:
        The group's movable joints present in the robot (entries naming absent joints are skipped
        with a warning).

    Raises:
        InvalidInput: no such group (the message lists the groups), a cycle of subgroups, or a
            group with no movable joint of the robot.
    """
    if group not in srdf.groups:
        raise InvalidInput(f"SRDF {srdf.path}: no group {group!r}; groups: {sorted(srdf.groups)}", value=group)
    chosen: set[str] = set()
    stack, seen = [group], set()
    while stack:
        name = stack.pop()
        if name in seen:
            continue
        seen.add(name)
        if name not in srdf.groups:
            raise InvalidInput(f"SRDF {srdf.path}: group {group!r} includes unknown group {name!r}", value=name)
        g = srdf.groups[name]
        for j in g.joints:
            if j in movable:
                chosen.add(j)
        for base, tip in g.chains:
            chosen.update(chain(base, tip))  # type: ignore[operator]
        stack += list(g.subgroups)
        absent = [j for j in g.joints if j not in movable]
        for j in absent:
            warnings.warn(f"SRDF {srdf.path}: group {name!r} joint {j!r} is not a movable joint of the robot; "
                          "skipped", DescriptionWarning, stacklevel=3)
        chosen.update(_link_joints(g.links, movable, chain))
    out = [j for j in movable if j in chosen]
    if not out:
        raise InvalidInput(f"SRDF {srdf.path}: group {group!r} has no movable joint of the robot", value=group)
    return out


def _link_joints(links: tuple[str, ...], movable: list[str], chain: object) -> set[str]:
    """The joint that moves each link (the last movable joint of the chain from the root to it)."""
    out: set[str] = set()
    for link in links:
        js = chain(None, link)  # type: ignore[operator]
        if js:
            out.add(js[-1])
    return out
