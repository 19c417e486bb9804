import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.learning import insertion as I
from robointel.learning.rltt import gmr_agreement, learn_insertion


@pytest.fixture(scope="module")
def learned():
    task = I.PegHole()
    rng = np.random.default_rng(11)
    scene = I.HDDScene(task)
    demos = [I.demonstrate(task, rng, scene=scene) for _ in range(4)]
    return task, demos, learn_insertion(demos, n_labelled=2)


def test_pipeline_sync_decompose_train(learned):
    task, demos, lr = learned
    assert len(lr.aligned) == 4 and all(a.shape == lr.aligned[0].shape for a in lr.aligned)
    assert lr.boundary_errors.shape == (2, 3)
    for d, lab in zip(demos, lr.labels):
        assert lab.shape == d.labels.shape and np.all(np.diff(lab) >= 0)
    Xt = (lr.skill.X_ - lr.skill.x_mean_) / lr.skill.x_scale_
    assert gmr_agreement(lr.skill.gmr, Xt[::20]) < 1e-9
    assert set(lr.timings) == {"sync", "decompose", "train", "total"}
    with pytest.raises(InvalidInput):
        learn_insertion(demos, n_labelled=4)


def test_robot_inserts_with_skill_position_only_fails(learned):
    """A CI-sized trial: small start error (0.4 mm, 0.3 deg). The skill-driven hybrid controller
    seats the peg without pressing into the walls; position-only control jams or hits the force limit."""
    task, demos, lr = learned
    cell = I.RobotPegHole(task)
    T0 = cell.start_pose(np.array([4e-4, -2e-4]), (0.5, np.radians(0.3)))
    ok = cell.run(lr.skill.predict, T0, seed=1)
    assert ok.success, ok.reason
    assert ok.depth_error <= 1e-3 and ok.max_penetration < 0.5 * task.clearance
    base = cell.run(None, T0, seed=1, time_limit=4.0)
    assert not base.success


def test_rim_slow_zone_limits_the_axial_speed(learned):
    """With ``rim_speed`` the hybrid controller crosses the rim zone no faster than that speed;
    the default gains leave the zone off (same result as without it)."""
    task, demos, lr = learned
    cell = I.RobotPegHole(task)
    T0 = cell.start_pose(np.array([2e-4, 1e-4]), (0.3, np.radians(0.2)))
    assert I.AdmittanceGains().rim_speed is None
    zone = (0.002, 0.012)
    slow = cell.run(lr.skill.predict, T0, seed=2, time_limit=3.0,
                    gains=I.AdmittanceGains(rim_speed=5e-4, rim_zone=zone, torque_filter_hz=5.0))
    depth = task.top[2] - slow.tip[:, 2]
    inside = (depth > zone[0] + 1e-4) & (depth < zone[1])
    assert inside.sum() > 20
    d, t = depth[inside], slow.t[inside]
    assert (d[-1] - d[0]) / (t[-1] - t[0]) < 1.2 * 5e-4  # mean speed through the zone, m/s
    assert depth.max() < zone[0] + 5e-4 * 3.0 + 1e-3
