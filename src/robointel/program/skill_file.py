"""Skill files: a learned insertion or grinding skill saved for programs to reference.

One HDF5 file per skill (h5py), written by ``robointel learn ... --skill-out FILE`` or :func:`save_skill`::

    /               attrs: format = "robointel.skill/1", kind = "insertion" | "grinding", meta (JSON),
                    model = "felt" | "gmr" (insertion; absent: "gmr"), time_limit_s (insertion: the time
                    a trial of the skill needs, s), params (felt: the strategy's speeds and forces, JSON)
    /gmr/priors     (K,)       the mixture (5.14) of the GMR (5.17)
    /gmr/means      (K, D)
    /gmr/covariances (K, D, D)  attrs: n_inputs
    /scaling/<name> the fitted input/output scaling and saturation ranges of the skill

Two insertion models: ``felt`` (:class:`~robointel.learning.insertion.FeltSkill`, the feel-align-insert
strategy with the GMR-learned rotation: the skill the learning benchmark measures at 20 um) and ``gmr``
(:class:`~robointel.learning.insertion.InsertionSkill`, the wrench -> corrective twist GMR of Sec. 5.5).

The fitted skill is rebuilt without refitting (:func:`load_skill`), so a program runs exactly the skill
that was saved.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from robointel.errors import InvalidInput
from robointel.learning.gmr import GaussianMixtureRegression
from robointel.learning.grinding import GrindingSkill, Plate
from robointel.learning.insertion import TIME_LIMIT_S, FeltSkill, InsertionSkill

SKILL_FORMAT = "robointel.skill/1"
SKILL_KINDS = ("insertion", "grinding")
INSERTION_MODELS = ("felt", "gmr")
"""The insertion skill models a skill file holds (``model`` attribute)."""
_INSERTION_SCALING = ("x_lo_", "x_hi_", "y_lo_", "y_hi_", "x_mean_", "x_scale_", "y_mean_", "y_scale_",
                      "y_supported_")
_FELT_SCALING = ("x_lo_", "x_hi_", "y_lo_", "y_hi_", "x_mean_", "x_scale_", "y_mean_", "y_scale_")
_GRINDING_SCALING = ("y_mean_", "y_scale_", "y_lo_", "y_hi_")
_PLATE_FIELDS = ("center", "top", "size", "hard_spots", "spread", "light", "hard")

Skill = FeltSkill | InsertionSkill | GrindingSkill


def skill_kind(skill: Any) -> str:
    """The kind of a fitted skill object ("insertion" or "grinding").

    Raises:
        InvalidInput: Not a fitted insertion or grinding skill.
    """
    if isinstance(skill, (FeltSkill, InsertionSkill)) and hasattr(skill, "x_mean_"):
        return "insertion"
    if isinstance(skill, GrindingSkill) and hasattr(skill, "y_mean_"):
        return "grinding"
    raise InvalidInput(f"a skill file holds a fitted FeltSkill, InsertionSkill or GrindingSkill, got "
                       f"{type(skill).__name__}", value=type(skill).__name__)


def insertion_model(skill: Any) -> str:
    """The insertion model of a fitted insertion skill: ``"felt"`` or ``"gmr"``.

    Raises:
        InvalidInput: Not a fitted insertion skill.
    """
    if skill_kind(skill) != "insertion":
        raise InvalidInput(f"not an insertion skill: {type(skill).__name__}", value=type(skill).__name__)
    return "felt" if isinstance(skill, FeltSkill) else "gmr"


def skill_time_limit(skill: Any) -> float:
    """The time (s) a trial of a fitted insertion skill gets (:data:`TIME_LIMIT_S` of its model).

    Raises:
        InvalidInput: Not a fitted insertion skill.
    """
    return TIME_LIMIT_S[insertion_model(skill)]


def save_skill(path: str | Path, skill: Skill, *, meta: dict[str, Any] | None = None) -> Path:
    """Write a fitted skill to an HDF5 skill file (see the module docstring).

    Args:
        path: The file to write (replaced if it exists).
        skill: A fitted :class:`FeltSkill`, :class:`InsertionSkill` or :class:`GrindingSkill`.
        meta: Extra JSON-serialisable facts (demonstrations used, seed, ...).

    Returns:
        The path written.

    Raises:
        InvalidInput: ``skill`` is not a fitted skill.
    """
    kind = skill_kind(skill)
    p = Path(path)
    gmr = skill.gmr
    with h5py.File(p, "w") as f:
        f.attrs["format"] = SKILL_FORMAT
        f.attrs["kind"] = kind
        f.attrs["meta"] = json.dumps(meta or {})
        g = f.create_group("gmr")
        g["priors"], g["means"], g["covariances"] = gmr.priors_, gmr.means_, gmr.covariances_
        g.attrs["n_inputs"] = int(gmr.n_inputs_)
        s = f.create_group("scaling")
        felt = isinstance(skill, FeltSkill)
        for name in (_FELT_SCALING if felt else _INSERTION_SCALING if kind == "insertion" else _GRINDING_SCALING):
            s[name.rstrip("_")] = np.asarray(getattr(skill, name), float)
        if felt:
            f.attrs["model"] = "felt"
            f.attrs["params"] = json.dumps(skill.params_)  # type: ignore[union-attr]
            f.attrs["time_limit_s"] = TIME_LIMIT_S["felt"]
        elif kind == "insertion":
            f.attrs["model"] = "gmr"
            f.attrs["centre"] = float(skill.centre)  # type: ignore[union-attr]
            f.attrs["time_limit_s"] = TIME_LIMIT_S["gmr"]
        else:
            plate = skill.plate  # type: ignore[union-attr]
            f.attrs["plate"] = json.dumps({k: getattr(plate, k) for k in _PLATE_FIELDS})
    return p


def load_skill(path: str | Path) -> Skill:
    """Read a skill file written by :func:`save_skill`.

    Args:
        path: The HDF5 skill file.

    Returns:
        The fitted :class:`FeltSkill`, :class:`InsertionSkill` or :class:`GrindingSkill`.

    Raises:
        InvalidInput: The file is missing, not HDF5, or not a skill file of a known kind.
    """
    p = Path(path)
    if not p.is_file():
        raise InvalidInput(f"skill file {str(path)!r} not found (write one with `robointel learn insertion "
                           "--skill-out FILE`)", value=str(path))
    try:
        with h5py.File(p, "r") as f:
            if f.attrs.get("format") != SKILL_FORMAT:
                raise InvalidInput(f"{p}: not a robointel skill file (format {f.attrs.get('format')!r})", value=str(p))
            kind = str(f.attrs["kind"])
            if kind not in SKILL_KINDS:
                raise InvalidInput(f"{p}: unknown skill kind {kind!r}", value=kind)
            g = f["gmr"]
            gmr = GaussianMixtureRegression.from_mixture(g["priors"][()], g["means"][()], g["covariances"][()],
                                                         int(g.attrs["n_inputs"]))
            scaling = {k: f["scaling"][k][()] for k in f["scaling"]}
            centre = float(f.attrs.get("centre", 0.0))
            plate_d = json.loads(f.attrs["plate"]) if "plate" in f.attrs else None
            model = str(f.attrs.get("model", "gmr"))
            params = json.loads(f.attrs["params"]) if "params" in f.attrs else None
    except OSError as exc:
        raise InvalidInput(f"{p}: cannot read the skill file: {exc}", value=str(p)) from None
    except (KeyError, ValueError) as exc:
        raise InvalidInput(f"{p}: an incomplete skill file: {exc}", value=str(p)) from None
    skill: Skill
    names: tuple[str, ...]
    if kind == "insertion" and model not in INSERTION_MODELS:
        raise InvalidInput(f"{p}: unknown insertion model {model!r} (known: {', '.join(INSERTION_MODELS)})",
                           value=model)
    if kind == "insertion" and model == "felt":
        if not isinstance(params, dict):
            raise InvalidInput(f"{p}: a felt insertion skill without its strategy parameters", value=str(p))
        skill = FeltSkill(gmr.n_components)
        skill.params_ = {str(k): float(v) for k, v in params.items()}
        names = _FELT_SCALING
    elif kind == "insertion":
        skill = InsertionSkill(gmr.n_components, centre=centre)
        names = _INSERTION_SCALING
    else:
        assert plate_d is not None
        fields: dict[str, Any] = {k: (tuple(tuple(x) if isinstance(x, list) else x for x in v)
                                      if isinstance(v, list) else v) for k, v in plate_d.items()}
        plate = Plate(**fields)
        skill = GrindingSkill(plate, gmr.n_components)
        names = _GRINDING_SCALING
    skill.gmr = gmr
    for name in names:
        if name == "y_supported_" and "y_supported" not in scaling:  # an older file: every output used
            skill.y_supported_ = np.ones(len(scaling["y_mean"]), bool)  # type: ignore[union-attr]
            continue
        v = scaling[name.rstrip("_")]
        setattr(skill, name, v if np.ndim(v) else float(v))
    return skill
