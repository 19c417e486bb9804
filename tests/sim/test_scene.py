"""Workcell scene: objects, point clouds, scene edits, payloads, time steps, rendering."""
from __future__ import annotations

import mujoco
import numpy as np
import pytest
import trimesh

from robointel.errors import InvalidInput, RobointelError
from robointel.geometry import Box, Capsule, Cylinder, PointCloud, Sphere
from robointel.sim import Payload, SimObject, Workcell

Q0 = np.array([0.0, 0.3, -0.2, 0.0, -0.5, 0.0])


def test_objects_fall_and_rest_on_the_table(lrmate):
    mug = trimesh.creation.cylinder(radius=0.04, height=0.1)
    pose = np.eye(4)
    pose[:3, 3] = [0.5, 0.2, 0.2]
    objs = [SimObject("cube", Box(np.array([0.45, -0.2, 0.1]), np.array([0.05, 0.05, 0.05])), 0.2),
            SimObject("ball", Sphere(np.array([0.6, 0.0, 0.3]), 0.03), 0.1, friction=2.0),
            SimObject("mug", mug, 0.3, pose=pose)]
    wc = Workcell(lrmate, objects=objs)
    m = wc.model
    # masses as given; the mesh inertia is trimesh's, scaled to the mass
    assert m.body_mass[m.body("object/cube").id] == pytest.approx(0.2)
    assert m.body_mass[m.body("object/mug").id] == pytest.approx(0.3)
    I = mug.moment_inertia * 0.3 / mug.mass
    np.testing.assert_allclose(np.sort(m.body_inertia[m.body("object/mug").id]), np.sort(np.linalg.eigvalsh(I)),
                               rtol=1e-6)
    wc.reset(Q0)
    wc.hold(1.0)
    assert wc.body_pose("cube")[2, 3] == pytest.approx(0.025, abs=1e-3)
    assert wc.body_pose("mug")[2, 3] == pytest.approx(0.05, abs=1e-3)
    assert wc.body_pose("ball")[2, 3] == pytest.approx(0.03, abs=1e-3)
    # reset puts them back
    wc.reset(Q0)
    np.testing.assert_allclose(wc.body_pose("mug")[:3, 3], [0.5, 0.2, 0.2], atol=1e-12)
    assert wc.contacts() == []  # objects touching the table are not robot contacts


def test_all_obstacle_shapes_become_geoms(lrmate):
    pts = np.random.default_rng(0).uniform([0.4, -0.6, 0.0], [0.6, -0.5, 0.1], (50, 3))
    obs = [Sphere(np.array([0.5, 0.3, 0.4]), 0.08, name="s"),
           Capsule(np.array([0.3, 0.4, 0.1]), np.array([0.3, 0.4, 0.5]), 0.04, name="c"),
           Cylinder(np.array([0.7, 0.0, 0.0]), np.array([0.7, 0.1, 0.2]), 0.05, name="y"),
           Box(np.array([0.6, -0.3, 0.15]), np.array([0.1, 0.2, 0.3]), name="b"),
           PointCloud(pts, 0.01, name="p")]
    wc = Workcell(lrmate, obstacles=obs)
    m, d = wc.model, wc.data
    G = mujoco.mjtGeom
    assert m.geom_type[m.geom("obstacle/s").id] == G.mjGEOM_SPHERE
    assert m.geom_type[m.geom("obstacle/c").id] == G.mjGEOM_CAPSULE
    assert m.geom_type[m.geom("obstacle/y").id] == G.mjGEOM_CYLINDER
    assert m.geom_type[m.geom("obstacle/b").id] == G.mjGEOM_BOX
    assert sum(1 for g in range(m.ngeom) if m.geom(g).name.startswith("obstacle/p/")) == 50
    # the MuJoCo geoms are the shapes: signed distance from test points agrees with geometry's
    rng = np.random.default_rng(1)
    probe = m.geom("obstacle/s").id
    for shape, name in zip(obs[:4], ["s", "c", "y", "b"]):
        gid = m.geom(f"obstacle/{name}").id
        for p in rng.uniform([0.0, -0.7, -0.1], [1.0, 0.7, 0.7], (5, 3)):
            d_ours = shape.distance(p[None])[0][0]
            # a 1 mm sphere probe placed at p (move the 's' obstacle there) measured by MuJoCo
            if name == "s":
                continue
            wc.set_obstacle_pose("s", p)
            m.geom_size[probe][0] = 1e-3
            mujoco.mj_forward(m, d)
            dm = mujoco.mj_geomDistance(m, d, probe, gid, 2.0, None)
            assert dm + 1e-3 == pytest.approx(d_ours, abs=2e-6), (name, p)
    with pytest.raises(InvalidInput):
        Workcell(lrmate, obstacles=[Sphere(np.zeros(3) + 1, 0.1, name="a"), Sphere(np.zeros(3) + 2, 0.1, name="a")])
    with pytest.raises(InvalidInput):
        Workcell(lrmate, obstacles=["not a shape"])


def test_add_obstacle_keeps_the_state(lrmate):
    wc = Workcell(lrmate)
    wc.reset(Q0)
    wc.command_velocity(np.full(6, 0.1))
    for _ in range(200):
        wc.command_velocity(np.full(6, 0.1))
    q, qd, t = wc.q, wc.qd, wc.time
    name = wc.add_obstacle(Sphere(np.array([0.6, 0.0, 0.6]), 0.05, name="late"))
    assert name == "late" and wc.obstacle_names == ["late"]
    np.testing.assert_array_equal(wc.q, q)
    np.testing.assert_array_equal(wc.qd, qd)
    assert wc.time == t
    wc.set_obstacle_pose("late", [0.7, 0.1, 0.5])
    np.testing.assert_allclose(wc.body_pose("late")[:3, 3], [0.7, 0.1, 0.5])


def test_uncompensated_payload_is_held_by_the_integral(lrmate):
    wc = Workcell(lrmate, payload=Payload(3.0, (0.1, 0.0, 0.0)), compensate_payload=False)
    q = np.array([0.0, 0.2, 0.1, 0.0, -0.6, 0.0])
    wc.reset(q)
    wc.hold(1.5)
    np.testing.assert_allclose(wc.q, q, atol=5e-5)  # measured 1e-5 (stiction band of the integral)
    assert np.abs(wc.qd).max() < 1e-3


@pytest.mark.parametrize("timestep", [0.0005, 0.002])
def test_other_timesteps(lrmate, timestep):
    wc = Workcell(lrmate, timestep=timestep)
    assert wc.control_dt == max(timestep, 0.001)
    wc.reset(Q0)
    wc.hold(0.5)
    np.testing.assert_allclose(wc.q, Q0, atol=1e-6)
    assert wc.time == pytest.approx(0.5)
    with pytest.raises(InvalidInput):
        Workcell(lrmate, timestep=0.0003)


def test_render_png_or_clear_error(lrmate, tmp_path):
    from robointel.sim.render import available_backend

    wc = Workcell(lrmate, obstacles=[Sphere(np.array([0.5, 0.3, 0.4]), 0.08)])
    if available_backend() is None:
        with pytest.raises(RobointelError, match="offscreen rendering is unavailable"):
            wc.render(tmp_path / "x.png")
        return
    img = wc.render(tmp_path / "cell.png", width=160, height=120)
    assert img.shape == (120, 160, 3) and img.std() > 10
    assert (tmp_path / "cell.png").stat().st_size > 1000
    qs = [np.zeros(6), np.array([0.5, 0.3, 0.0, 0.0, -0.5, 0.0]), np.array([-0.5, 0.6, 0.2, 0.0, -0.9, 0.0])]
    strip = wc.render_frames(qs, tmp_path / "strip.png", width=80, height=60)
    assert strip.shape == (60, 240, 3)
    assert np.abs(strip[:, :80].astype(int) - strip[:, 80:160]).mean() > 1  # the arm moved between frames
    with pytest.raises(InvalidInput):
        wc.render_frames([np.zeros(4)])


def test_tool_contact_force_is_felt_by_the_sensor(lrmate):
    peg = Payload(0.5, (0.06, 0, 0), shape=Cylinder(np.zeros(3), np.array([0.12, 0, 0]), 0.01), collide=True)
    wc = Workcell(lrmate, payload=peg)
    down = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0.0]])  # flange x axis pointing down
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = down, [0.5, 0.0, 0.13]  # peg tip 1 cm above the table
    q = lrmate.ik(T, q_ref=np.array([0, 0.5, 0, 0, -1.0, 0]))[0]
    T[2, 3] = 0.10  # command the tip 2 cm into the table
    q_press = lrmate.ik(T, q_ref=q)[0]
    wc.reset(q)
    for _ in range(800):
        wc.track(q_press)
    cs = wc.contacts()
    assert cs and all(c.kind == "table" and c.robot_geom == "payload" and c.robot_body == "tool" for c in cs)
    f_contact = sum(c.force for c in cs)
    assert f_contact[2] > 50  # the table pushes the peg up
    # quasi-static: the sensor feels the contact force plus the peg's weight (world axes)
    w = wc.ft_reading(frame="world")
    np.testing.assert_allclose(w[:3], f_contact + [0, 0, -0.5 * 9.81], rtol=0.02, atol=0.5)


def test_instability_stops_safely(lrmate):
    wc = Workcell(lrmate)
    q = np.array([0.0, 0.6, -0.3, 0.0, -0.3, 0.0])
    wc.reset(q)
    wc.hold(0.1)
    t = wc.time
    wc.apply_wrench([1e30, 0, 0])  # absurd: MuJoCo diverges
    with pytest.raises(RobointelError, match="unstable"):
        wc.hold(0.01)
    np.testing.assert_allclose(wc.q, q, atol=1e-6)  # put back where it was, not at MuJoCo's qpos0
    assert np.all(wc.qd == 0) and wc.time == pytest.approx(t, abs=0.002)
    wc.hold(0.2)  # and it holds
    np.testing.assert_allclose(wc.q, q, atol=1e-5)


def test_armature_enters_mujoco_and_the_controller(lrmate):
    arm = np.array([0.5, 0.5, 0.2, 0.02, 0.02, 0.01])
    wc = Workcell(lrmate, armature=arm, table=False)
    q = np.array([0.1, 0.4, -0.2, 0.3, -0.5, 0.2])
    wc.reset(q)
    M = np.zeros((6, 6))
    mujoco.mj_fullM(wc.model, wc.data, M)
    np.testing.assert_allclose(M, lrmate.mass_matrix(q) + np.diag(arm), atol=1e-12)
    t = np.linspace(0, 1, 101)
    s = 0.5 - 0.5 * np.cos(np.pi * t)
    log = wc.run_trajectory(t, q + np.outer(s, [0.3, 0.2, 0.2, 0.5, 0.5, 0.5]))
    assert log.max_error.max() < 5e-4


def test_grasp_carries_an_object_and_release_drops_it(lrmate):
    cube = SimObject("cube", Box(np.array([0.5, 0.0, 0.025]), np.array([0.05, 0.05, 0.05])), 0.4)
    wc = Workcell(lrmate, objects=[cube])
    down = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0.0]])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = down, [0.5, 0.0, 0.06]  # flange just above the cube
    q = lrmate.ik(T, q_ref=np.array([0, 0.5, 0, 0, -1.0, 0]))[0]
    wc.reset(q)
    wc.hold(0.3)
    w0 = wc.ft_reading(frame="world")
    wc.grasp("cube")
    assert wc.grasped() == ["cube"]
    rel0 = np.linalg.inv(wc.body_pose("tool")) @ wc.body_pose("cube")
    offset = wc.body_pose("cube")[:3, 3] - wc.body_pose("tool")[:3, 3]
    T[:3, 3] = [0.4, 0.2, 0.3]
    q1 = lrmate.ik(T, q_ref=q)[0]
    tt = np.linspace(0, 1.5, 151)
    s = 0.5 - 0.5 * np.cos(np.pi * tt / 1.5)
    wc.run_trajectory(tt, q + np.outer(s, q1 - q), reset=False)
    wc.hold(0.5)
    rel = np.linalg.inv(wc.body_pose("tool")) @ wc.body_pose("cube")
    np.testing.assert_allclose(rel[:3, 3], rel0[:3, 3], atol=1e-3)
    np.testing.assert_allclose(wc.body_pose("cube")[:3, 3], np.array([0.4, 0.2, 0.3]) + offset, atol=2e-3)
    dw = wc.ft_reading(frame="world") - w0
    np.testing.assert_allclose(dw[:3], [0, 0, -0.4 * 9.81], atol=0.02)
    wc.release("cube")
    wc.hold(1.0)
    assert wc.grasped() == [] and wc.body_pose("cube")[2, 3] == pytest.approx(0.025, abs=2e-3)
    with pytest.raises(InvalidInput):
        wc.grasp("nothing")


def test_bad_scene_input_raises_named_errors(lrmate):
    with pytest.raises(InvalidInput, match="payload mass"):
        Workcell(lrmate, payload=Payload(-1.0))
    with pytest.raises(InvalidInput, match="positive definite"):
        Workcell(lrmate, payload=Payload(1.0, inertia=-np.eye(3)))
    with pytest.raises(InvalidInput, match="mass"):
        Workcell(lrmate, objects=[SimObject("a", Sphere(np.array([0.5, 0, 0.1]), 0.02), 0.0)])
    with pytest.raises(InvalidInput, match="SimObject"):
        Workcell(lrmate, objects=[Sphere(np.array([0.5, 0, 0.1]), 0.02)])
    with pytest.raises(InvalidInput, match="mesh"):
        Workcell(lrmate, objects=[SimObject("a", "/no/such/mesh.stl", 0.1)])
    with pytest.raises(InvalidInput, match="duplicate"):
        Workcell(lrmate, objects=[SimObject("a", Sphere(np.array([0.5, 0, 0.1]), 0.02), 0.1)] * 2)
    with pytest.raises(InvalidInput, match="timestep"):
        Workcell(lrmate, timestep=float("nan"))
    with pytest.raises(InvalidInput):
        Workcell(lrmate, armature=np.full(6, -1.0))
    wc = Workcell(lrmate, ft_sensor=False)
    with pytest.raises(InvalidInput, match="no F/T sensor"):
        wc.ft_reading()
    with pytest.raises(InvalidInput):
        wc.apply_wrench([0, 0, np.nan])
    with pytest.raises(InvalidInput):
        wc.apply_wrench([0, 0, 1.0], body="nowhere")
