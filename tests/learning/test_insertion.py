import copy

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.learning.insertion import (
    PHASES,
    POLICY,
    HDDScene,
    InsertionSkill,
    PegHole,
    press_test,
    tool_velocities,
)


@pytest.fixture(scope="module")
def task():
    return PegHole()


def test_tight_fit_settings(task):
    assert task.clearance <= 20e-6
    assert task.contact.solimp[2] < 0.5 * task.clearance and task.contact.margin == 0.0
    scene = HDDScene(task)
    m = scene.model
    assert m.opt.timestep <= 1e-3 and m.opt.cone == 1  # elliptic
    walls = [g for g in range(m.ngeom) if (m.geom(g).name or "").startswith("hole/")]
    assert np.all(m.geom_margin[walls] == 0) and np.all(m.geom_solref[walls, 0] <= 0.002)
    with pytest.raises(InvalidInput):
        PegHole(clearance=5e-6)  # impedance width not below the radial gap


def test_physics_is_honest_interference_does_not_go_in(task):
    ok = press_test(task, force=50.0)
    assert ok.inserted and ok.max_penetration < 0.5 * task.clearance
    bad = press_test(task, interference=20e-6, force=300.0)
    assert not bad.inserted and bad.height > 0.01  # stuck at the rim, 300 N pushing
    assert bad.axial_force > 250.0


def test_demonstration_phases_and_skill_with_rotation(task, hdd_demos):
    scene = HDDScene(task)
    d = copy.deepcopy(hdd_demos[0])  # demonstrate(task, default_rng(3), scene=scene), made once per session
    assert d.action_names == PHASES
    assert np.all(np.diff(d.labels) >= 0) and set(np.unique(d.labels)) == {0, 1, 2, 3}
    np.testing.assert_allclose(np.diff(d.t), 0.01, atol=1e-9)
    np.testing.assert_allclose(d.phase_times(), d.meta["phase_times"], atol=0.011)
    assert np.degrees(d.meta["residual_tilt"]) <= 5.0 and np.all(np.abs(d.meta["lateral_error"]) <= 2e-3)
    tw = tool_velocities(d)
    ins = d.labels == PHASES.index("insertion")
    tip_z = d.pose[ins, 2, 3] + d.pose[ins, 2, 2] * scene.tool.tip
    assert tip_z[0] - tip_z.min() > 0.005  # the tip went into the hole
    # the velocity of a point on the axis: v_c = v + w x c
    c = 0.09
    twc = tool_velocities(d, centre=c)
    np.testing.assert_allclose(twc[:, 0], tw[:, 0] + tw[:, 4] * c, atol=1e-12)
    skill = InsertionSkill(4, centre=c).fit([d])
    out = skill.predict(np.zeros(6))
    assert out.shape == (len(POLICY),) and np.all(np.isfinite(out)) and out[2] > 0
    # the skill outputs rotation as well as translation: its outputs vary with the wrench in wx, wy
    W = d.wrench[ins][:: 20]
    assert np.ptp(skill.predict(W)[:, 3:5], axis=0).min() > 0


def test_steel_contact_has_a_hertz_patch_torsional_friction(task):
    # MuJoCo's default torsional friction (5 mm) would resist spinning a 400 N wedge contact with 2 N m
    scene = HDDScene(task)
    m = scene.model
    peg = m.geom("peg/peg").id
    assert 1e-5 <= m.geom_friction[peg, 1] <= 1e-4 and m.geom_condim[peg] == 4
