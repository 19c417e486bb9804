"""The torque-level Cartesian impedance path of the LR Mate insertion (RobotPegHole.run_impedance)."""
import numpy as np
import pytest

from robointel.learning import insertion as I


@pytest.fixture(scope="module")
def cell_and_skill():
    task = I.PegHole()
    rng = np.random.default_rng(5)
    scene = I.HDDScene(task)
    demos = [I.demonstrate(task, rng, scene=scene) for _ in range(2)]
    return I.RobotPegHole(task), I.InsertionSkill(3).fit(demos)


def test_exp_is_the_rotation_of_the_rotation_vector():
    w = np.array([0.01, -0.02, 0.005])
    np.testing.assert_allclose(I._log(I._exp(w)), w, atol=1e-12)
    np.testing.assert_allclose(I._log(I._exp(1e-4 * w)), 1e-4 * w, atol=1e-15)


def test_impedance_holds_pose_under_gravity(cell_and_skill):
    """With the equilibrium at the start pose the gravity-compensated impedance holds the tool."""
    cell, _ = cell_and_skill
    T0 = cell.start_pose(np.zeros(2), (0.0, 0.0))
    r = cell.run_impedance(None, T0, v_push=0.0, probe=False, time_limit=0.3)
    assert np.linalg.norm(r.tip[-1] - r.tip[0]) < 1e-3 and r.max_force < 1.0


def test_probe_finds_the_axis_and_the_skill_seats_a_tilted_peg(cell_and_skill):
    """A 2.5 deg tilted start: touching the hole's top face measures the axis (the true hole is
    vertical) to a small fraction of a degree, and the skill-driven impedance seats the peg without
    pressing into the walls; the stiff position-only servo does not."""
    cell, skill = cell_and_skill
    T0 = cell.start_pose(np.array([5e-4, -6e-4]), (1.0, np.radians(2.5)))
    r = cell.run_impedance(skill.predict, T0, seed=3)
    axis = cell.last_probe["axis"]
    assert np.degrees(np.arccos(-axis[2])) < 0.1
    assert r.success, r.reason
    assert r.max_penetration < 0.5 * cell.task.clearance
    assert not cell.run(None, T0, seed=3, time_limit=4.0).success
