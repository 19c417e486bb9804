from dataclasses import replace

import numpy as np
import pytest

from robointel.learning.grinding import GrindingSkill, Plate, demonstrate_grinding, reproduce_grinding
from robointel.learning.insertion import HDDScene
from robointel.outcome import Failure


@pytest.fixture(scope="module")
def setup():
    plate = Plate()
    rng = np.random.default_rng(0)
    demos = [demonstrate_grinding(plate, rng, scene=HDDScene(plate, plate.tool()), lines=4, speed=0.1)]
    return plate, demos


def test_profile_and_demonstration(setup):
    plate, demos = setup
    f = plate.force_profile(np.array(plate.hard_spots + ((0.08, -0.08),)))
    np.testing.assert_allclose(f[:2], plate.hard, rtol=1e-9)
    assert abs(f[2] - plate.light) < 0.5
    sk = GrindingSkill(plate, 6)
    X, Y = sk.samples(demos[0])
    assert len(X) > 300
    assert np.corrcoef(Y, plate.force_profile(X))[0, 1] > 0.8  # the person presses as intended


def test_force_controlled_reproduction_tracks_setpoint(setup):
    plate, demos = setup
    sk = GrindingSkill(plate, 8).fit(demos)
    res = reproduce_grinding(plate, sk, speed=0.05, t_touch=0.6)
    assert res.force.shape == res.setpoint.shape and len(res.force) > 50
    assert res.rms_rel_setpoint < 0.15  # the robot's force follows the learned set-point
    far = sk.predict(np.array([[0.3, 0.3], [-0.3, 0.3], [0.0, -0.5]]))  # off the demonstrated area
    assert np.all((far >= sk.Y_.min()) & (far <= sk.Y_.max()))
    assert np.all(np.isfinite(res.force))
    # the shared trial outcome: success exactly when the error is within the bound, the figures are the result's
    out = res.outcome
    assert out.success == (res.rms_rel <= 0.25) and out.figures["rms_rel"] == res.rms_rel
    assert out.figures["max_force_n"] == pytest.approx(float(res.force.max()))
    strict = replace(res, max_rms_rel=0.5 * res.rms_rel).outcome
    assert not strict.success and strict.reason is Failure.TRACKING


def test_default_strokes_cover_the_plate():
    """By default the strokes are at most one tool diameter apart, so the sensor samples the whole
    plate (no unground stripe wider than the tool between strokes)."""
    from robointel.errors import InvalidInput

    plate = Plate()
    d = demonstrate_grinding(plate, np.random.default_rng(4), speed=0.4)
    X, _ = GrindingSkill(plate).samples(d)
    y = np.sort(X[np.abs(X[:, 0]) < 0.05, 1])  # away from the turnarounds at the plate's edges
    assert np.diff(y).max() <= 2 * plate.tool().radius + 1e-3
    assert y[0] < plate.hard_spots[0][1] and y[-1] > plate.hard_spots[1][1]
    with pytest.raises(InvalidInput):
        demonstrate_grinding(plate, np.random.default_rng(0), lines=0)


class _ConstantForce:
    """A set-point map pressing 15 N everywhere (the interface of GrindingSkill.predict)."""

    def predict(self, xy):
        return np.full(len(np.atleast_2d(xy)), 15.0)


def test_sliding_contact_does_not_chatter():
    """The arm slides the stylus along the diagonal at a constant 15 N set-point: the pad's soft first
    touch keeps the contact closed, so the 10 ms force means stay within 1.5 N of the set-point (a
    stiff first touch made the friction contact chatter: 1 ms contact losses, means off by up to 4 N)."""
    res = reproduce_grinding(Plate(), _ConstantForce(), speed=0.06, t_touch=1.0)
    f = res.force[20:]
    assert np.abs(f - 15.0).max() < 1.5
    assert f.std() < 0.5
