"""Per-sphere blends between the spheres as given and the covering ones (obstacles and self-collision)."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.planning import Environment
from robointel.robot import Robot


@pytest.fixture(scope="module")
def ur5_env(shared_data):
    root = shared_data("mbm", "ur5")
    return Environment(Robot.load(root / "ur5.urdf"), [], srdf=root / "ur5.srdf")


def test_a_link_blended_alone_keeps_its_groups_bounding(ur5_env):
    env = ur5_env
    mask = env.link_spheres(["forearm_link"])
    assert mask.any() and not mask.all()
    env.use("fitted", blend=mask * 1.0)
    try:
        sj, sp, sr, _, gc, gr, gs = env.world[5:12]
        f, c = env._fitted, env._cover
        assert np.allclose(sr[mask], c[2][mask]) and np.allclose(sr[~mask], f[2][~mask])
        for g in range(len(gr)):  # each group's sphere still bounds its spheres
            k = slice(gs[g], gs[g + 1])
            assert np.all(np.linalg.norm(sp[k] - gc[g], axis=1) + sr[k] <= gr[g] + 1e-12)
        assert np.array_equal(env.blend, mask * 1.0)
    finally:
        env.use("cover")


def test_self_blend_only_lowers_the_self_clearance_of_its_links(ur5_env):
    env = ur5_env
    rng = np.random.default_rng(1)
    Q = env.robot.random_configuration(rng, 30)
    before = np.array([env.self_offset_clearance(q) for q in Q])
    env.set_self_blend(env.link_spheres(["wrist_2_link", "forearm_link"]) * 1.0)
    try:
        after = np.array([env.self_offset_clearance(q) for q in Q])
        assert np.all(after <= before + 1e-12) and np.any(after < before - 1e-3)
    finally:
        env.set_self_blend(0.0)
    assert np.allclose([env.self_offset_clearance(q) for q in Q], before)
    with pytest.raises(InvalidInput, match="blend"):
        env.set_self_blend(1.5)
    with pytest.raises(InvalidInput, match="blend"):
        env.use("fitted", blend=np.ones(3))
