"""The per-robot cache of the environment's robot side: shared where the inputs agree, rebuilt where
they differ, and the same answers as an environment packed from scratch."""
from __future__ import annotations

import os
import re

import numpy as np
import pytest

from robointel.geometry.obstacles import Box, Sphere
from robointel.planning import Environment
from robointel.planning import _sphere_pack as packmod
from robointel.robot import Robot
from robointel.robot.collision import SphereModel


def _world_equal(a: Environment, b: Environment) -> bool:
    return all(np.array_equal(x, y) for x, y in zip(a.world, b.world)) and len(a.world) == len(b.world)


def test_environments_of_one_robot_share_the_robot_side_and_agree_with_a_fresh_pack():
    robot = Robot.load("lrmate200id7l")
    wall = Box(center=[0.45, 0.0, 0.4], size=[0.05, 0.6, 0.3], name="wall")
    ball = Sphere(center=[0.3, 0.3, 0.5], radius=0.1, name="ball")
    a = Environment(robot, [wall], floor=0.0)
    b = Environment(robot, [ball], floor=0.0)
    assert a._cover is b._cover and a._self is b._self and a.spheres is b.spheres  # packed once
    packmod._ROBOT_CACHE.clear()
    fresh = Environment(robot, [ball], floor=0.0)
    assert fresh._cover is not b._cover
    assert _world_equal(fresh, b)
    rng = np.random.default_rng(3)
    for q in robot.random_configuration(rng, 20):
        assert b.clearance(q) == fresh.clearance(q)
    # other spheres: packed apart, and their clearances are those of the other spheres
    sm = robot.spheres
    big = SphereModel(list(sm.links), np.asarray(sm.centers), 1.5 * np.asarray(sm.radii))
    c = Environment(robot, [ball], floor=0.0, spheres=big)
    assert c._fitted is not b._fitted and not np.array_equal(c._fitted[2], b._fitted[2])
    for q in robot.random_configuration(rng, 20):
        assert c.clearance(q) <= b.clearance(q) + 1e-12
    # using one environment's blended spheres leaves the shared pack alone
    b.use("fitted", blend=0.5)
    assert np.array_equal(fresh._fitted[2], Environment(robot, [ball], floor=0.0)._fitted[2])


def test_an_edited_sphere_urdf_is_read_again(shared_data, tmp_path):
    root = shared_data("mbm", "ur5")
    robot = Robot.load(root / "ur5.urdf")
    path = tmp_path / "spheres.urdf"
    text = (root / "ur5_spherized.urdf").read_text()
    path.write_text(text)
    e1 = Environment(robot, [], spheres=path, cover_meshes=False)
    r0 = float(re.search(r'<sphere radius="([0-9.eE+-]+)"', text).group(1))
    path.write_text(re.sub(r'<sphere radius="([0-9.eE+-]+)"', f'<sphere radius="{r0 + 0.05:.6f}"', text, count=1))
    st = path.stat()
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))  # a new version even on a coarse clock
    e2 = Environment(robot, [], spheres=path, cover_meshes=False)
    assert np.sum(e2.spheres.radii) == pytest.approx(np.sum(e1.spheres.radii) + 0.05)
