"""Fixtures shared by the planning tests: MBM bookshelf_thin 70's environment, the dense clearance of an edge."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from robointel.io.mbm import load_mbm_problems
from robointel.planning import Environment
from robointel.planning import _collision_kernels as K
from robointel.robot import Robot


@pytest.fixture(scope="module")
def thin70(shared_data):
    """bookshelf_thin 70 and its environment: its goal clears the fitted spheres (2.7 mm) but not the covering ones."""
    root = shared_data("mbm", "ur5")
    p = next(q for q in load_mbm_problems(root / "problems.json").select(families=["bookshelf_thin"])
             if q.index == 70)
    robot = Robot.load(root / "ur5.urdf")
    env = Environment(robot, p.obstacles, srdf=root / "ur5.srdf", spheres=root / "ur5_spherized.urdf")
    return p, env


def _dense_min(env, W, q0, q1, gap=0.004) -> float:
    """Smallest clearance in ``W`` on samples of q0 -> q1 at most ``gap`` (m) of sphere travel apart."""
    s = env.scratch
    k = int(np.ceil(K.travel(q0, q1, env.lever) / gap)) + 1
    return min(float(K.config_clearance(q0 + t * (q1 - q0), W, s.T, s.C, s.G, s.out, 1.0))
               for t in np.linspace(0.0, 1.0, k))


@pytest.fixture(scope="session")
def dense_min() -> Callable[..., float]:
    """Call ``dense_min(env, W, q0, q1, gap=0.004)``: the smallest clearance on densely sampled q0 -> q1, m."""
    return _dense_min
