"""Device demonstrations (Sec. 5.2) as dataset episodes and back (LeRobot / robomimic export).

A demonstration's tool pose T_k becomes the state [p_k, vec(R_k)] (12: position in m, then the
rotation matrix row by row), its wrench an observation, its labels an integer observation; the
action at frame k is the state at frame k + 1 (the pose the device was moved to next; the last
frame repeats). The conversion is lossless.
"""
from __future__ import annotations

import numpy as np

from robointel.errors import InvalidInput
from robointel.io.episode import Episode
from robointel.learning.demonstration import UNITS, Demonstration

KIND = "device"
STATE_NAMES = ("x", "y", "z", "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33")
WRENCH_NAMES = ("fx", "fy", "fz", "tx", "ty", "tz")


def _state(pose: np.ndarray) -> np.ndarray:
    return np.concatenate([pose[:, :3, 3], pose[:, :3, :3].reshape(len(pose), 9)], axis=1)


def demonstration_to_episode(demo: Demonstration, *, task: str = "") -> Episode:
    """One device demonstration as an :class:`~robointel.io.episode.Episode`.

    Args:
        demo: the demonstration (t (N,) s, pose (N, 4, 4), wrench (N, 6), optional labels (N,)).
        task: the task description (default "<device> demonstration").

    Returns:
        Episode with observations ``state`` (N, 12) [m, -], ``wrench`` (N, 6) [N, N m] and
        ``label`` (N, 1) (if labelled), action (N, 12) = the next frame's state, kind "device".
    """
    state = _state(demo.pose)
    obs: dict[str, np.ndarray] = {"state": state, "wrench": demo.wrench}
    names = {"state": STATE_NAMES, "wrench": WRENCH_NAMES, "action": STATE_NAMES}
    if demo.labels is not None:
        obs["label"] = demo.labels.reshape(-1, 1)
    action = np.concatenate([state[1:], state[-1:]])
    meta = {"device": demo.device, "action_names": list(demo.action_names), "units": UNITS,
            "demonstration_meta": demo.meta}
    return Episode.create(demo.t, obs, action, names=names, task=task or f"{demo.device} demonstration",
                          kind=KIND, name=demo.name, meta=meta)


def episode_to_demonstration(episode: Episode) -> Demonstration:
    """The demonstration an episode of :func:`demonstration_to_episode` came from.

    Args:
        episode: a "device" episode with a (N, 12) ``state`` and a (N, 6) ``wrench``.

    Returns:
        The demonstration (equal to the original).

    Raises:
        InvalidInput: the episode is not a device demonstration, or its orientation is not a rotation.
    """
    state, wrench = episode.observations.get("state"), episode.observations.get("wrench")
    if episode.kind != KIND or state is None or wrench is None or state.shape[1] != 12 or wrench.shape[1] != 6:
        raise InvalidInput(f"episode {episode.name!r} (kind {episode.kind!r}) is not a device demonstration "
                           "with a (N, 12) state and a (N, 6) wrench", value=episode.name)
    pose = np.zeros((len(episode), 4, 4))
    pose[:, :3, 3] = state[:, :3]
    pose[:, :3, :3] = state[:, 3:].reshape(-1, 3, 3)
    R = pose[:, :3, :3]
    err = np.abs(np.einsum("kji,kjl->kil", R, R) - np.eye(3)).max(axis=(1, 2))
    bad = np.flatnonzero((err > 1e-6) | (np.linalg.det(R) < 0))
    if bad.size:
        raise InvalidInput(f"episode {episode.name!r}: state[{int(bad[0])}, 3:12] is not a rotation matrix (the "
                           "tool orientation of a device demonstration)", value=int(bad[0]))
    pose[:, 3, 3] = 1.0
    labels = episode.observations["label"][:, 0] if "label" in episode.observations else None
    meta = episode.meta
    return Demonstration.create(episode.t, pose, wrench, labels, action_names=tuple(meta.get("action_names", ())),
                                device=str(meta.get("device", "hdd")), name=episode.name,
                                meta=dict(meta.get("demonstration_meta", {})))
