"""One recorded episode as plain arrays: the neutral type the dataset files read and write.

Every kind of recording robointel makes (a device demonstration, a guided or teleoperated run, an
imitation run) converts to and from an :class:`Episode` in its own phase; the LeRobot and
robomimic writers in ``robointel.io`` only see this type.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel._validate import as_array
from robointel.errors import InvalidInput, ShapeError

#: The observation every episode has (the robot's or the device's state).
STATE = "state"


@dataclass(frozen=True)
class Episode:
    """One episode: per-frame observations and actions on a common clock.

    Attributes:
        t: (N,) sample times [s], strictly increasing.
        observations: name -> (N, k) array (float64, or int64 for labels); ``"state"`` is required.
        action: (N, a) float64 actions (what was commanded at each frame).
        names: component names per observation name and for ``"action"`` (may be empty tuples).
        task: a short description of the task (LeRobot's task string).
        kind: what recorded it ("device", "guidance", "teleoperation", "imitation", ...).
        name: the episode's name.
        meta: JSON-serialisable extras (units, device, labels' names, ...).
    """

    t: np.ndarray
    observations: dict[str, np.ndarray]
    action: np.ndarray
    names: dict[str, tuple[str, ...]] = field(default_factory=dict)
    task: str = ""
    kind: str = ""
    name: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def create(cls, t: npt.ArrayLike, observations: Mapping[str, npt.ArrayLike], action: npt.ArrayLike, *,
               names: Mapping[str, Sequence[str]] | None = None, task: str = "", kind: str = "", name: str = "",
               meta: Mapping[str, Any] | None = None) -> Episode:
        """Validated constructor: shapes, finiteness, strictly increasing time.

        Args:
            t: (N,) times [s].
            observations: name -> (N,) or (N, k) arrays; must contain ``"state"``. Integer arrays
                stay int64, the others become float64.
            action: (N,) or (N, a) actions.
            names: component names per observation and for ``"action"``; each must match the width.
            task: task description.
            kind: the kind of recording.
            name: the episode's name.
            meta: JSON-serialisable extras.

        Returns:
            The episode.

        Raises:
            ShapeError: inconsistent lengths or widths, fewer than 2 frames.
            NotFinite: NaN or inf values.
            InvalidInput: no ``"state"``, time not strictly increasing, a name with a '/' or '.'.
        """
        tt = as_array(t, "t", (None,))
        n = tt.shape[0]
        if n < 2:
            raise ShapeError(f"an episode needs at least 2 frames, got {n}", value=n)
        if np.any(np.diff(tt) <= 0):
            raise InvalidInput("episode times must be strictly increasing (seconds)", value=tt)
        if STATE not in observations:
            raise InvalidInput(f"an episode needs a {STATE!r} observation, got {sorted(observations)}",
                               value=sorted(observations))
        obs: dict[str, np.ndarray] = {}
        for key, value in observations.items():
            if not key or "/" in key or "." in key:
                raise InvalidInput(f"observation name {key!r} must be non-empty without '/' or '.'", value=key)
            raw = np.asarray(value)
            a = raw.astype(np.int64) if raw.dtype.kind in "iub" else as_array(raw, f"observations[{key!r}]")
            a = a.reshape(n, -1) if a.ndim == 1 else a
            if a.ndim != 2 or a.shape[0] != n or a.shape[1] < 1:
                raise ShapeError(f"observations[{key!r}] must have shape ({n}, k), got {raw.shape}", value=raw.shape)
            obs[key] = a
        act = as_array(action, "action")
        act = act.reshape(n, -1) if act.ndim == 1 else act
        if act.ndim != 2 or act.shape[0] != n or act.shape[1] < 1:
            raise ShapeError(f"action must have shape ({n}, a), got {np.shape(action)}", value=np.shape(action))
        width = {**{k: v.shape[1] for k, v in obs.items()}, "action": act.shape[1]}
        nm: dict[str, tuple[str, ...]] = {}
        for key, comps in (names or {}).items():
            if key not in width:
                raise InvalidInput(f"names given for {key!r}, which is neither an observation nor 'action'", value=key)
            comps = tuple(str(c) for c in comps)
            if comps and len(comps) != width[key]:
                raise ShapeError(f"{len(comps)} names for {key!r} of width {width[key]}", value=comps)
            nm[key] = comps
        return cls(tt, obs, act, nm, str(task), str(kind), str(name), dict(meta or {}))

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def equals(self, other: Episode) -> bool:
        """True when every array, name and attribute is identical (a lossless round trip)."""
        same_obs = (self.observations.keys() == other.observations.keys() and
                    all(self.observations[k].dtype == other.observations[k].dtype
                        and np.array_equal(self.observations[k], other.observations[k]) for k in self.observations))
        names = lambda e: {k: v for k, v in e.names.items() if v}  # noqa: E731
        return bool(same_obs and np.array_equal(self.t, other.t) and np.array_equal(self.action, other.action)
                    and names(self) == names(other) and (self.task, self.kind, self.name, self.meta)
                    == (other.task, other.kind, other.name, other.meta))
