"""RLTT device demonstrations exported as LeRobot v3 / robomimic and imported back unchanged."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.io.episode import Episode
from robointel.io.lerobot import read_lerobot, write_lerobot
from robointel.io.robomimic import read_robomimic, write_robomimic
from robointel.learning.demonstration import load_demonstrations, save_demonstrations
from robointel.learning.demonstration_episode import demonstration_to_episode, episode_to_demonstration


def assert_same(a, b):
    assert np.array_equal(a.t, b.t) and np.array_equal(a.pose, b.pose) and np.array_equal(a.wrench, b.wrench)
    assert (a.labels is None and b.labels is None) or np.array_equal(a.labels, b.labels)
    assert (a.action_names, a.device, a.name, a.meta) == (b.action_names, b.device, b.name, b.meta)


@pytest.fixture(scope="module")
def demos(tmp_path_factory, hdd_demos):
    """Two peg-in-hole demonstrations with the HDD in MuJoCo (seed 3), stored and re-read as the CLI does."""
    path = tmp_path_factory.mktemp("demos") / "demos.h5"
    save_demonstrations(path, list(hdd_demos))
    return load_demonstrations(path)


def test_device_demonstrations_pass_lerobot_doctor_and_round_trip(demos, tmp_path, doctor):
    episodes = [demonstration_to_episode(d) for d in demos]
    assert np.array_equal(episodes[0].action[:-1], episodes[0].observations["state"][1:])  # the next pose
    root = write_lerobot(tmp_path / "hdd", episodes, robot_type="hdd")
    report, fails = doctor(root)
    assert fails == [] and report["fps"] == 100 and report["total_episodes"] == 2
    for d, e in zip(demos, read_lerobot(root)):
        assert_same(d, episode_to_demonstration(e))


def test_device_demonstrations_round_trip_through_robomimic(demos, tmp_path):
    path = write_robomimic(tmp_path / "hdd.hdf5", [demonstration_to_episode(d) for d in demos])
    for d, e in zip(demos, read_robomimic(path)):
        assert_same(d, episode_to_demonstration(e))


def test_other_episodes_are_not_demonstrations():
    ep = Episode.create(np.arange(3.0), {"state": np.zeros((3, 2))}, np.zeros((3, 2)), kind="imitation")
    with pytest.raises(InvalidInput):
        episode_to_demonstration(ep)
