"""Imitation, guided and teleoperated recordings exported as LeRobot v3 / robomimic and read back."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput, LimitViolation
from robointel.io.lerobot import read_lerobot, write_lerobot
from robointel.io.robomimic import read_robomimic, write_robomimic
from robointel.teach.imitation import kinematic_imitation, simulate_imitation
from robointel.teach.recording_episodes import (
    guidance_episode,
    imitation_episode,
    scara_episode,
    teleop_episode,
)
from robointel.teach.scara import simulate_scara
from robointel.teach.scenarios import run_scenario
from robointel.teach.skeleton import synthetic_wave

READY = np.array([0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0])


@pytest.fixture(scope="module")
def episodes(lrmate):
    sk = synthetic_wave(1.5, dropout_at=None)
    run = simulate_imitation(kinematic_imitation(sk, lrmate), lrmate)
    guided = run_scenario(1, duration=0.3, physics=False, identify=False)
    waypoints = [READY, READY + [0.2, 0.1, -0.1, 0.0, 0.2, 0.3], READY + [0.1, 0.0, 0.0, 0.2, 0.0, 0.0]]
    return {"scara": scara_episode(simulate_scara(sk, latency=0.1)), "imitation": imitation_episode(run, lrmate),
            "guidance": guidance_episode(guided, lrmate), "teleop": teleop_episode(waypoints, robot=lrmate),
            "waypoints": np.array(waypoints)}


@pytest.mark.parametrize("kind", ["scara", "imitation", "guidance", "teleop"])
def test_each_kind_passes_lerobot_doctor_and_round_trips(episodes, kind, tmp_path, doctor):
    ep = episodes[kind]
    root = write_lerobot(tmp_path / kind, [ep], robot_type="scara2" if kind == "scara" else "lrmate200id7l")
    report, fails = doctor(root)
    assert fails == [] and report["fps"] == 1000
    (back,) = read_lerobot(root)
    assert back.equals(ep)


def test_all_kinds_share_one_robomimic_file(episodes, tmp_path):
    eps = [episodes[k] for k in ("scara", "imitation", "guidance", "teleop")]
    back = read_robomimic(write_robomimic(tmp_path / "all.hdf5", eps))
    assert [e.kind for e in back] == ["imitation", "imitation", "guidance", "teleoperation"]
    assert all(a.equals(b) for a, b in zip(eps, back))


def test_teleop_episode_is_the_program_executed(episodes):
    ep, W = episodes["teleop"], episodes["waypoints"]
    assert np.allclose(ep.observations["state"][-1], W[-1], atol=1e-3)     # the robot reached the last waypoint
    targets = {tuple(a) for a in ep.action}
    assert targets == {tuple(w) for w in W}                                # the action is the streamed target
    assert np.all(np.diff(ep.t) > 0) and np.isclose(np.median(np.diff(ep.t)), 1e-3)


def test_scara_episode_keeps_the_human_and_the_robot(episodes):
    ep = episodes["scara"]
    assert set(ep.observations) == {"state", "human", "torque", "received"}
    assert ep.names["action"] == ("q1", "q2") and ep.meta["latency_s"] == 0.1


def test_bad_teleop_programs(lrmate):
    with pytest.raises(InvalidInput):
        teleop_episode([READY], robot=lrmate)
    with pytest.raises(LimitViolation):
        teleop_episode([READY, READY + [10.0, 0, 0, 0, 0, 0]], robot=lrmate)
