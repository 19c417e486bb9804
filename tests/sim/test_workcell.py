"""The workcell in MuJoCo: tracking under the Fig. 2.3 controller, F/T sensor, wrenches, contacts, faults."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput, LimitViolation, NotFinite, ShapeError
from robointel.geometry import Box, Sphere
from robointel.sim import Payload, Workcell

G = 9.81
Q0 = np.array([0.0, 0.3, -0.2, 0.0, -0.5, 0.0])


def smooth_trajectory(q0, q1, T=2.0, n=201):
    t = np.linspace(0.0, T, n)
    s = 0.5 - 0.5 * np.cos(np.pi * t / T)
    sd = 0.5 * np.pi / T * np.sin(np.pi * t / T)
    sdd = 0.5 * (np.pi / T) ** 2 * np.cos(np.pi * t / T)
    dq = q1 - q0
    return t, q0 + np.outer(s, dq), np.outer(sd, dq), np.outer(sdd, dq)


@pytest.fixture(scope="module")
def wc():
    return Workcell()


def test_tracks_a_smooth_trajectory(wc, lrmate):
    t, q, qd, qdd = smooth_trajectory(Q0, np.array([1.0, 0.8, 0.3, 1.0, 0.8, 2.0]))
    log = wc.run_trajectory(t, q, qd, qdd)
    assert log.q.shape == (2001, 6) and log.tau.shape == (2001, 6) and log.ft.shape == (2001, 6)
    # measured: max |e| <= 7e-5 rad (J6), RMS <= 2.3e-5 rad, TCP error <= 6 um
    assert np.all(log.max_error < 5e-4), log.max_error
    assert np.all(log.rms_error < 1e-4), log.rms_error
    assert log.tcp_error(lrmate).max() < 1e-4
    assert not log.collided and np.isinf(log.min_distance)
    assert np.all(np.abs(log.tau) <= lrmate.effort_limit + 1e-12)
    np.testing.assert_allclose(log.q[-1], q[-1], atol=5e-4)


def test_tracks_without_feedforward_worse_but_stable(lrmate):
    wc = Workcell(lrmate)
    wc.controller.feedforward = False
    t, q, qd, qdd = smooth_trajectory(Q0, np.array([1.0, 0.8, 0.3, 1.0, 0.8, 2.0]))
    log = wc.run_trajectory(t, q, qd, qdd)
    assert np.all(np.isfinite(log.q))
    assert np.all(log.max_error < 0.2)
    assert log.rms_error.max() > 1e-3  # the feed-forward is what makes tracking tight


def test_position_and_velocity_commands(wc):
    wc.reset(Q0)
    target = Q0 + np.array([0.05, -0.05, 0.05, 0.1, 0.1, -0.1])
    for _ in range(1500):
        wc.track(target)
    # J6 (2e-5 kg m^2 against 0.2 N m of Coulomb friction) may hunt in a sub-mrad stick-slip cycle
    np.testing.assert_allclose(wc.q, target, atol=1.5e-3)
    wc.reset(Q0)
    v = np.array([0.2, 0.0, -0.1, 0.0, 0.3, 0.5])
    for _ in range(500):
        wc.command_velocity(v)
    np.testing.assert_allclose(wc.hold_reference, Q0 + 0.5 * v, atol=1e-9)
    np.testing.assert_allclose(wc.q, Q0 + 0.5 * v, atol=2e-3)
    np.testing.assert_allclose(wc.qd, v, atol=0.05)


def test_ft_sensor_reads_payload_weight_and_moment(lrmate):
    m, com = 2.0, np.array([0.05, 0.01, 0.02])
    wc = Workcell(lrmate, payload=Payload(m, com))
    q = np.array([0.3, 0.2, -0.1, 0.5, -0.7, 1.0])
    wc.reset(q)
    R = lrmate.frame_pose(q, "flange")[:3, :3]
    f = R.T @ np.array([0.0, 0.0, -m * G])
    np.testing.assert_allclose(wc.ft_reading(), np.r_[f, np.cross(com, f)], atol=1e-9)  # right after reset
    wc.hold(1.0)
    R = lrmate.frame_pose(wc.q, "flange")[:3, :3]
    f = R.T @ np.array([0.0, 0.0, -m * G])
    w = wc.ft_reading()
    np.testing.assert_allclose(w[:3], f, atol=1e-3 * np.linalg.norm(f))
    np.testing.assert_allclose(w[3:], np.cross(com, f), atol=1e-3 * np.linalg.norm(np.cross(com, f)))
    # world-frame reading: the weight points down
    np.testing.assert_allclose(wc.ft_reading(frame="world")[:3], [0, 0, -m * G], atol=1e-3 * m * G)
    np.testing.assert_allclose(wc.sensor_pose()[:3, :3], R, atol=1e-9)
    # bias and noise hooks
    b = np.arange(6.0)
    np.testing.assert_allclose(wc.ft_reading(bias=b), w + b)
    noisy = np.array([wc.ft_reading(noise=0.5) for _ in range(2000)])
    assert 0.45 < noisy[:, 0].std() < 0.55


def test_applied_wrench_shows_in_sensor(lrmate):
    wc = Workcell(lrmate)
    q = np.array([0.0, 0.2, 0.1, 0.0, -0.6, 0.0])
    wc.reset(q)
    wc.hold(0.3)
    w0 = wc.ft_reading()
    T = wc.sensor_pose()
    f = np.array([10.0, -5.0, 20.0])
    p = T[:3, 3] + T[:3, :3] @ np.array([0.1, 0.02, 0.0])
    wc.apply_wrench(f, torque=(0.0, 0.0, 0.5), point=p)
    wc.hold(1.0)
    T = wc.sensor_pose()
    R = T[:3, :3]
    dw = wc.ft_reading() - w0
    r = R.T @ (p - T[:3, 3])  # the point moved with the tool; use its offset in the sensor frame
    r = np.array([0.1, 0.02, 0.0])
    fs = R.T @ f
    ts = np.cross(r, fs) + R.T @ np.array([0.0, 0.0, 0.5])
    np.testing.assert_allclose(dw[:3], fs, atol=1e-3 * np.linalg.norm(fs))
    np.testing.assert_allclose(dw[3:], ts, atol=1e-3 * np.linalg.norm(ts))
    wc.clear_wrench()
    wc.hold(1.0)
    np.testing.assert_allclose(wc.ft_reading(), w0, atol=1e-3)


def test_obstacles_are_geoms_and_motion_into_them_makes_contacts(lrmate):
    t, q, qd, qdd = smooth_trajectory(np.array([-0.8, 0.3, 0.0, 0.0, -0.3, 0.0]),
                                      np.array([0.8, 0.3, 0.0, 0.0, -0.3, 0.0]), T=1.5, n=151)
    mid = lrmate.fk(q[75])[:3, 3]
    obstacles = [Sphere(mid, 0.05, name="ball"),
                 Box(np.array([0.3, -0.5, 0.2]), np.array([0.1, 0.1, 0.4]), name="post")]
    wc = Workcell(lrmate, obstacles=obstacles)
    assert wc.obstacle_names == ["ball", "post"]
    assert wc.model.geom("obstacle/ball").id >= 0 and wc.model.geom("obstacle/post").id >= 0
    np.testing.assert_allclose(wc.body_pose("ball")[:3, 3], mid)
    log = wc.run_trajectory(t, q, qd, qdd)
    assert log.collided and log.contacts.max() > 0 and log.min_distance < 0
    # away from the obstacle: the arm does not touch it
    free = Workcell(lrmate, obstacles=[Sphere(mid + [0, 0, 0.5], 0.05, name="ball")])
    log2 = free.run_trajectory(t, q, qd, qdd)
    assert not log2.collided and 0.3 < log2.min_distance < 0.6


def test_contacts_name_robot_and_obstacle(lrmate):
    q = np.array([0.0, 0.3, 0.0, 0.0, -0.3, 0.0])
    p = lrmate.fk(q)[:3, 3]
    wc = Workcell(lrmate, obstacles=[Sphere(p + [0.0, 0.0, 0.3], 0.05, name="ball")])
    wc.reset(q)
    wc.hold(0.01)
    assert wc.contacts() == []
    d, rg, og = wc.obstacle_distance()
    assert og == "obstacle/ball" and 0.1 < d < 0.3
    wc.set_obstacle_pose("ball", p)  # move it onto the flange
    wc.hold(0.01)
    cs = wc.contacts()
    assert cs and all(c.kind == "obstacle" and c.other_geom == "obstacle/ball" for c in cs)
    assert min(c.distance for c in cs) < 0
    assert cs[0].robot_body in lrmate.link_names


def test_bad_input_raises_and_holds(wc):
    wc.reset(Q0)
    wc.hold(0.2)
    q_before, t_before = wc.q, wc.time
    with pytest.raises(NotFinite):
        wc.step([0, 0, np.nan, 0, 0, 0])
    with pytest.raises(ShapeError):
        wc.step(np.zeros(5))
    assert wc.time == t_before
    np.testing.assert_array_equal(wc.q, q_before)
    with pytest.raises(NotFinite):
        wc.track([np.nan] * 6)
    with pytest.raises(ShapeError):
        wc.track(np.zeros(7))
    with pytest.raises(NotFinite):
        wc.command_velocity([np.inf, 0, 0, 0, 0, 0])
    wc.hold(1.0)  # the robot holds the last valid reference
    np.testing.assert_allclose(wc.q, Q0, atol=1e-4)
    assert np.all(np.abs(wc.qd) < 1e-3)
    with pytest.raises(LimitViolation):
        wc.reset(np.array([4.0, 0, 0, 0, 0, 0]))
    t, q, qd, qdd = smooth_trajectory(Q0, Q0 + [0, 0, 0, 0, 3.0, 0])
    with pytest.raises(LimitViolation):
        wc.run_trajectory(t, q)
    with pytest.raises(InvalidInput):
        wc.run_trajectory(t[::-1], q)
    with pytest.raises(InvalidInput):
        wc.body_pose("no_such_body")
    with pytest.raises(InvalidInput):
        wc.ft_reading(frame="moon")
    with pytest.raises(InvalidInput):
        wc.set_obstacle_pose("nothing", [0, 0, 0])


@pytest.mark.parametrize("name", ["lrmate200id7l", "ur5", "panda"])
def test_controller_stable_across_the_workspace(name):
    """Inertia-scheduled gains: stable when folded (small J1 inertia) and stretched, for any arm."""
    from robointel.robot import Robot

    robot = Robot.load(name)
    wc = Workcell(robot, table=False)
    rng = np.random.default_rng(3)
    qs = sorted(robot.random_configuration(rng, 40), key=lambda q: robot.mass_matrix(q)[0, 0])
    lo, hi = robot.lower + 0.02, robot.upper - 0.02
    for q in (qs[0], qs[-1]):  # smallest and largest J1 inertia
        q = np.clip(q, lo, hi)
        wc.reset(q)
        wc.hold(0.3)
        assert np.abs(wc.q - q).max() < 1e-4 and np.abs(wc.qd).max() < 1e-2
    a, b = np.clip(qs[0], lo, hi), np.clip(qs[-1], lo, hi)
    t, q, qd, qdd = smooth_trajectory(a, a + 0.5 * (b - a), T=1.5, n=151)
    log = wc.run_trajectory(t, q, qd, qdd)
    assert np.all(np.isfinite(log.q)) and log.max_error.max() < 5e-3, log.max_error


def test_log_roundtrip_and_trajectory_object(wc, tmp_path):
    from robointel.trajectory import Trajectory

    t, q, qd, qdd = smooth_trajectory(Q0, Q0 + 0.2, T=0.5, n=51)
    traj = Trajectory(t, q, qd, qdd, joint_names=list(wc.robot.joint_names))
    log = wc.run_trajectory(traj)
    assert log.q.shape == (501, 6)
    log.save(tmp_path / "log.npz")
    back = type(log).load(tmp_path / "log.npz")
    np.testing.assert_array_equal(back.q, log.q)
    np.testing.assert_array_equal(back.ft, log.ft)
    assert back.joint_names == log.joint_names and back.summary() == log.summary()


def test_snapshot_restore_replays_exactly(wc):
    wc.reset(Q0)
    wc.apply_wrench([5.0, 0.0, -3.0])
    for _ in range(100):
        wc.command_velocity(np.full(6, 0.2))
    snap = wc.snapshot()
    runs = []
    for _ in range(2):
        wc.restore(snap)
        for _ in range(200):
            wc.command_velocity(np.full(6, -0.1))
        runs.append((wc.q, wc.qd, wc.time, wc.ft_reading()))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    np.testing.assert_array_equal(runs[0][3], runs[1][3])
    assert runs[0][2] == runs[1][2]
    wc.clear_wrench()
    other = Workcell(wc.robot, obstacles=[Sphere(np.array([1.0, 1.0, 1.0]), 0.1)])
    with pytest.raises(InvalidInput):
        other.restore(snap)


def test_log_reports_saturation_and_velocity_ratio(lrmate):
    wc = Workcell(lrmate)
    stretched = np.array([-1.2, 1.0, 0.3, 0.0, 0.0, 0.0])  # J1 inertia 2.3 kg m^2
    t, q, qd, qdd = smooth_trajectory(stretched, stretched + np.array([2.5, 0, 0, 0, 0, 0]), T=0.35, n=36)
    log = wc.run_trajectory(t, q, qd, qdd)
    assert log.velocity_ratio(lrmate)[0] == pytest.approx(np.pi * 2.5 / 2 / 0.35 / lrmate.velocity_limit[0])
    assert log.velocity_ratio(lrmate)[0] > 1  # too fast for J1
    assert log.saturation_fraction[0] > 0  # 100 rad/s^2 x 2.3 kg m^2 is more than J1's 150 N m
    assert np.all(np.abs(log.tau[:, 0]) <= 150.0)
