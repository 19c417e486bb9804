"""The insertion skill uses an output only where the demonstrations tie it to the wrench; decompositions
that hand the approach to the insertion are not learned from."""

from __future__ import annotations

import numpy as np

from robointel.learning.demonstration import Demonstration
from robointel.learning.insertion import PHASES, POLICY, InsertionSkill
from robointel.learning.rltt import plausible_decompositions


def _demo(rng: np.random.Generator, n: int = 400) -> Demonstration:
    """A synthetic insertion: the tool descends at a speed that falls with the axial force and turns at a
    rate unrelated to the wrench (tremor); the lateral force moves it sideways."""
    dt = 0.01
    t = np.arange(n) * dt
    box = np.ones(25) / 25  # wrenches that change over ~0.25 s, as contact forces do
    fz = -np.abs(np.convolve(rng.normal(0.0, 10.0, n), box, mode="same"))
    fx = np.convolve(rng.normal(0.0, 1.5, n), box, mode="same")
    vz = 0.008 + 0.0015 * fz  # m/s, slower under load
    vx = 2e-3 * fx
    wy = 0.05 * np.sin(2 * np.pi * rng.uniform(2, 4) * t + rng.uniform(0, 6))  # rad/s, not tied to the wrench
    pose = np.tile(np.eye(4), (n, 1, 1))
    ang = np.cumsum(wy) * dt
    c, s = np.cos(ang), np.sin(ang)
    pose[:, 0, 0], pose[:, 0, 2], pose[:, 2, 0], pose[:, 2, 2] = c, s, -s, c
    # tool-frame velocity integrated into world positions
    v_world = np.einsum("nij,nj->ni", pose[:, :3, :3], np.stack([vx, np.zeros(n), vz], 1))
    pose[:, :3, 3] = np.cumsum(v_world, 0) * dt
    wrench = np.zeros((n, 6))
    wrench[:, 0], wrench[:, 2] = fx, fz
    wrench[:, 3:5] = rng.normal(0.0, 0.01, (n, 2))
    labels = np.full(n, PHASES.index("insertion"))
    return Demonstration.create(t, pose, wrench, labels, action_names=PHASES, device="hdd")


def test_outputs_the_wrench_does_not_predict_are_not_used():
    rng = np.random.default_rng(5)
    demos = [_demo(rng) for _ in range(6)]
    skill = InsertionSkill(3).fit(demos)
    used = dict(zip(POLICY, skill.y_supported_, strict=True))
    assert used["vz"] and used["vx"]  # the speed follows the axial force, the lateral motion the lateral force
    assert not used["wx"] and not used["wy"]  # the turning is tremor: held-out R^2 below the bar
    assert skill.r2_[POLICY.index("vz")] > 0.5
    # whatever the torque, no turn: nothing in the demonstrations ties one to it
    w = np.zeros((3, 6))
    w[:, 3] = [-5.0, 0.0, 5.0]
    out = skill.predict(w)
    np.testing.assert_array_equal(out[:, 3:5], 0.0)
    assert out[0, 2] > 0 and np.all(np.isfinite(out))
    # the axial speed falls as the axial force grows, as demonstrated
    w = np.zeros((2, 6))
    w[:, 2] = [-0.2, -4.0]
    vz = skill.predict(w)[:, 2]
    assert vz[0] > vz[1]


def test_a_decomposition_that_collapses_the_approach_is_not_learned_from():
    # hand labels: approach 150, rotation 80, insertion 400, completion 60 samples
    hand = [np.repeat(np.arange(4), [150, 80, 400, 60]), np.repeat(np.arange(4), [170, 90, 380, 50])]
    good = np.repeat(np.arange(4), [140, 75, 420, 55])
    collapsed = np.repeat(np.arange(4), [2, 2, 626, 60])  # approach and rotation handed to the insertion
    assert plausible_decompositions([*hand, good, collapsed], 2) == [True, True, True, False]
