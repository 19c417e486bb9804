"""A robot description as its maker ships it: URDF (+ SRDF) to a Pinocchio model of one planning group.

* Joints: revolute, continuous, prismatic, fixed and mimic. A continuous joint becomes a revolute
  joint over [-2 pi, 2 pi] (planned as an angle; a goal is wrapped by whole turns to the nearest
  representative, see :meth:`robointel.robot.Robot.wrap_goal`). A mimic joint follows its master
  (value = multiplier * master + offset) and is held with it; in a planning group, a mimic joint
  whose master is planned is refused (named); with no group (every joint planned) it is planned as a
  joint of its own, as before.
* Planning group: an SRDF group name, a base and tip link, or a list of joint names; every other
  movable joint is held at the value the user gives (default: 0, or the mid-range when 0 is
  outside its limits) and locked out of the model (Pinocchio's ``buildReducedModel``).
* Every Pinocchio exception the description triggers becomes a :class:`DescriptionError` naming the
  file and, where the URDF can be read, the element.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from robointel.errors import DescriptionError, InvalidInput
from robointel.robot.srdf import SRDF, group_joints

#: range of a continuous joint once it is planned as an angle, rad
CONTINUOUS_RANGE = 2.0 * math.pi
_MOVABLE = ("revolute", "continuous", "prismatic")
_KNOWN = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")


@dataclass
class Description:
    """A URDF read for planning.

    Attributes:
        urdf: the URDF text given to Pinocchio (continuous joints rewritten as revolute).
        source: the file, or "<text>".
        full: the model of every joint.
        model: the model of the planning group (held joints locked).
        group: the planned joint names, in model order.
        held: the value of every held movable joint (rad or m).
        continuous: names of the joints that were continuous in the URDF.
        mimic: ``{joint: (master, multiplier, offset)}``.
    """

    urdf: str
    source: str
    full: pin.Model
    model: pin.Model
    group: list[str]
    held: dict[str, float] = field(default_factory=dict)
    continuous: set[str] = field(default_factory=set)
    mimic: dict[str, tuple[str, float, float]] = field(default_factory=dict)


def _num(src: str, where: str, attr: str, raw: str | None, default: float | None = None) -> float:
    if raw is None:
        if default is None:
            raise DescriptionError(f"URDF {src}: {where} lacks the attribute {attr!r}", value=where)
        return default
    try:
        v = float(raw)
    except ValueError:
        raise DescriptionError(f"URDF {src}: {where} attribute {attr}={raw!r} is not a number", value=raw) from None
    if not math.isfinite(v):
        raise DescriptionError(f"URDF {src}: {where} attribute {attr}={raw!r} is not finite", value=raw)
    return v


def prepare_urdf(text: str, source: str) -> tuple[str, set[str], dict[str, tuple[str, float, float]]]:
    """Check a URDF's joints and rewrite continuous joints as revolute ones.

    Returns:
        (URDF text for Pinocchio, continuous joint names, mimic joints ``{joint: (master, multiplier, offset)}``).

    Raises:
        DescriptionError: not XML, no ``<robot>``, a joint without name/type/parent/child, an
            unknown joint type, or a non-numeric limit or mimic attribute (the message names the
            file and the element).
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise DescriptionError(f"cannot read URDF {source}: {exc}; check that it is a valid URDF XML file",
                               value=source) from None
    if root.tag != "robot":
        raise DescriptionError(f"URDF {source}: the root element is <{root.tag}>, not <robot>", value=source)
    links = {lk.get("name") for lk in root.findall("link")}
    continuous: set[str] = set()
    mimic: dict[str, tuple[str, float, float]] = {}
    for k, j in enumerate(root.findall("joint")):
        name, kind = j.get("name"), j.get("type")
        where = f"<joint> {k} ({name!r})"
        if not name or not kind:
            raise DescriptionError(f"URDF {source}: {where} lacks a name or a type", value=name)
        if kind not in _KNOWN:
            raise DescriptionError(f"URDF {source}: joint {name!r} has type {kind!r}; robointel reads "
                                   f"{', '.join(_KNOWN[:4])} joints", value=kind)
        for tag in ("parent", "child"):
            e = j.find(tag)
            if e is None or e.get("link") not in links:
                raise DescriptionError(f"URDF {source}: joint {name!r} <{tag}> names no link of the URDF "
                                       f"({None if e is None else e.get('link')!r})", value=name)
        lim = j.find("limit")
        if kind in ("revolute", "prismatic"):
            if lim is None:
                raise DescriptionError(f"URDF {source}: {kind} joint {name!r} has no <limit>", value=name)
            lo = _num(source, f"joint {name!r} <limit>", "lower", lim.get("lower"), 0.0)
            hi = _num(source, f"joint {name!r} <limit>", "upper", lim.get("upper"), 0.0)
            if hi < lo:
                raise DescriptionError(f"URDF {source}: joint {name!r} <limit> lower {lo} > upper {hi}", value=name)
        if lim is not None:
            for a in ("effort", "velocity"):
                _num(source, f"joint {name!r} <limit>", a, lim.get(a), 0.0)
        m = j.find("mimic")
        if m is not None and kind in _MOVABLE:
            master = m.get("joint")
            if not master:
                raise DescriptionError(f"URDF {source}: joint {name!r} <mimic> lacks the attribute 'joint'", value=name)
            mimic[name] = (master, _num(source, f"joint {name!r} <mimic>", "multiplier", m.get("multiplier"), 1.0),
                           _num(source, f"joint {name!r} <mimic>", "offset", m.get("offset"), 0.0))
        if kind == "continuous":
            continuous.add(name)
            j.set("type", "revolute")
            if lim is None:
                lim = ET.SubElement(j, "limit")
            lim.set("lower", repr(-CONTINUOUS_RANGE))
            lim.set("upper", repr(CONTINUOUS_RANGE))
            lim.set("effort", lim.get("effort", "0"))
            lim.set("velocity", lim.get("velocity", "0"))
    names = {j.get("name") for j in root.findall("joint")}
    for jn, (master, _, _) in mimic.items():
        if master not in names:
            raise DescriptionError(f"URDF {source}: joint {jn!r} mimics {master!r}, which is not a joint", value=jn)
    return ET.tostring(root, encoding="unicode"), continuous, mimic


def build_model(text: str, source: str) -> pin.Model:
    """Pinocchio's model of a (prepared) URDF text.

    Raises:
        DescriptionError: Pinocchio refused it (its message, with the file), or a joint with more
            than one coordinate (floating, planar).
    """
    try:
        model = pin.buildModelFromXML(text)
    except Exception as exc:  # Pinocchio raises ValueError/RuntimeError/std::exception wrappers
        raise DescriptionError(f"URDF {source}: Pinocchio could not build a model: {exc}", value=source) from None
    for j in range(1, model.njoints):
        jm = model.joints[j]
        if jm.nq != 1 or jm.nv != 1:
            raise DescriptionError(f"URDF {source}: joint {model.names[j]!r} ({jm.shortname()}) has {jm.nq} "
                                   "coordinates; robointel plans fixed-base robots with 1-DoF joints (revolute, "
                                   "continuous, prismatic)", value=model.names[j])
    return model


def body_frame(model: pin.Model, link: str) -> int:
    """Index of the BODY frame named ``link`` (a name shared by frames of other types is not ambiguous here).

    Raises:
        InvalidInput: no link of that name.
    """
    for i, f in enumerate(model.frames):
        if f.name == link and f.type == pin.FrameType.BODY:
            return i
    raise InvalidInput(f"no link {link!r}; links: {[f.name for f in model.frames if f.type == pin.FrameType.BODY]}",
                       value=link)


def chain_joints(model: pin.Model, base: str | None, tip: str) -> list[str]:
    """The joints between link ``base`` (None: the root) and link ``tip``, root first.

    Raises:
        InvalidInput: an unknown link, or ``tip`` not below ``base``.
    """
    jt = int(model.frames[body_frame(model, tip)].parentJoint)
    jb = 0 if base is None else int(model.frames[body_frame(model, base)].parentJoint)
    path = [int(j) for j in model.supports[jt]]
    if jb not in path:
        raise InvalidInput(f"link {tip!r} is not below link {base!r}: no chain between them", value=(base, tip))
    return [model.names[j] for j in path[path.index(jb) + 1:]]


def default_value(lo: float, hi: float) -> float:
    """Held value of a joint the user gives none for: 0, or the mid-range when 0 is outside [lo, hi]."""
    return 0.0 if lo <= 0.0 <= hi else 0.5 * (lo + hi)


def select_group(full: pin.Model, source: str, *, srdf: SRDF | None, group: str | None, base_link: str | None,
                 tip_link: str | None, joints: Sequence[str] | None) -> list[str]:
    """The planned joints: an SRDF group, a base-tip chain, a list, or every movable joint.

    Raises:
        InvalidInput: more than one way given, a group without an SRDF, unknown names.
    """
    movable = [full.names[j] for j in range(1, full.njoints)]
    ways = sum(x is not None for x in (group, joints)) + (tip_link is not None)
    if ways > 1:
        raise InvalidInput("give one of group, tip_link (with base_link) or joints", value=(group, tip_link, joints))
    if base_link is not None and tip_link is None:
        raise InvalidInput(f"base_link {base_link!r} needs a tip_link", value=base_link)
    if group is not None:
        if srdf is None:
            raise InvalidInput(f"group {group!r} needs an SRDF file (srdf=...)", value=group)
        return group_joints(srdf, group, movable=movable, chain=lambda b, t: chain_joints(full, b, t))
    if tip_link is not None:
        js = chain_joints(full, base_link, tip_link)
        if not js:
            raise InvalidInput(f"no movable joint between {base_link!r} and {tip_link!r}", value=tip_link)
        return js
    if joints is not None:
        unknown = [j for j in joints if j not in movable]
        if unknown:
            raise InvalidInput(f"URDF {source}: no movable joint {unknown[0]!r}; movable joints: {movable}",
                               value=unknown[0])
        if not joints:
            raise InvalidInput("joints must name at least one joint", value=joints)
        return [j for j in movable if j in set(joints)]
    return movable


def reduce(full: pin.Model, source: str, plan: list[str], held: Mapping[str, float] | None,
           mimic: dict[str, tuple[str, float, float]], *, strict: bool = True) -> tuple[pin.Model, dict[str, float]]:
    """Lock every movable joint outside ``plan`` at its held value.

    With ``strict`` False (no group given: every joint planned), a mimic joint planned with its
    master is planned as a joint of its own, as Pinocchio models it.

    Returns:
        (the reduced model, the held values).

    Raises:
        InvalidInput: a held value for an unknown or planned joint, or outside the joint's limits.
        DescriptionError: a mimic joint whose master is planned.
    """
    movable = [full.names[j] for j in range(1, full.njoints)]
    given = dict(held or {})
    for jn in given:
        if jn not in movable:
            raise InvalidInput(f"held joint {jn!r} is not a movable joint of {source}", value=jn)
        if jn in plan:
            raise InvalidInput(f"joint {jn!r} is planned and cannot be held", value=jn)
    q = np.zeros(full.nq)
    values: dict[str, float] = {}
    for jn in movable:
        if jn in plan:
            continue
        j = full.getJointId(jn)
        iq = full.joints[j].idx_q
        lo, hi = float(full.lowerPositionLimit[iq]), float(full.upperPositionLimit[iq])
        v = float(given[jn]) if jn in given else default_value(lo, hi)
        if not (lo - 1e-9 <= v <= hi + 1e-9) or not math.isfinite(v):
            raise InvalidInput(f"held value {v} of joint {jn!r} is outside its limits [{lo}, {hi}]", value=v)
        values[jn] = v
    for jn, (master, mult, off) in mimic.items():
        if not strict and jn in plan and master in plan:
            continue  # every joint planned (no group given): a mimic joint is planned as a joint of its own
        if jn in plan or master in plan:
            raise DescriptionError(f"URDF {source}: mimic joint {jn!r} follows {master!r}; robointel holds a mimic "
                                   "joint with its master (leave both out of the planning group)", value=jn)
        if jn not in given:
            values[jn] = mult * values[master] + off
    for jn, val in values.items():
        q[full.joints[full.getJointId(jn)].idx_q] = val
    lock = [full.getJointId(jn) for jn in values]
    if not lock:
        return full, values
    try:
        model = pin.buildReducedModel(full, lock, q)
    except Exception as exc:
        raise DescriptionError(f"URDF {source}: Pinocchio could not hold joints {sorted(values)}: {exc}",
                               value=source) from None
    return model, values


def load_description(text: str, source: str, *, srdf: SRDF | None = None, group: str | None = None,
                     base_link: str | None = None, tip_link: str | None = None, joints: Sequence[str] | None = None,
                     held: Mapping[str, float] | None = None) -> Description:
    """Read a URDF text into a :class:`Description` of one planning group (see the module docstring).

    Raises:
        DescriptionError: the URDF is malformed or Pinocchio refuses it (file and element named).
        InvalidInput: a bad group, chain, joint list or held value.
    """
    prepared, continuous, mimic = prepare_urdf(text, source)
    full = build_model(prepared, source)
    if full.nq == 0:
        raise DescriptionError(f"URDF {source} has no movable joints", value=source)
    plan = select_group(full, source, srdf=srdf, group=group, base_link=base_link, tip_link=tip_link, joints=joints)
    strict = group is not None or tip_link is not None or joints is not None
    model, values = reduce(full, source, plan, held, mimic, strict=strict)
    return Description(prepared, source, full, model, plan, values, continuous, mimic)
