import contextlib
import dataclasses

import numpy as np
import pytest
from airo_fanuc.testing import FakeCRXConfig, FakeCRXController, WallClock

from robointel.interface import open_robot


@pytest.fixture(scope="session")
def frmp_segment():
    """The first segment of the FRMP on the built-in table71 scene (CFS + temporal optimization)."""
    from robointel.io.scene import load_scene
    from robointel.planning import plan_scene

    s = load_scene("table71")
    short = dataclasses.replace(s, waypoints=s.waypoints[:2], steps=s.steps[:1], waypoint_names=s.waypoint_names[:2])
    return plan_scene(short).trajectory


@contextlib.contextmanager
def running_fake(q0=None):
    """FakeCRXController in strict-conformance mode on 127.0.0.1, wall-paced, its joints at ``q0`` (rad)."""
    fake = FakeCRXController(FakeCRXConfig(strict=True), host="127.0.0.1", clock=WallClock(),
                             initial_q_deg=None if q0 is None else list(np.degrees(q0)) + [0.0] * 3).start()
    fake.start_realtime()
    try:
        yield fake
    finally:
        fake.stop_realtime()
        fake.close()


def fanuc_url(fake) -> str:
    return f"fanuc://127.0.0.1:{fake.rmi_port}?sm_port={fake.sm_port}"


@pytest.fixture
def fake_controller():
    """A running fake controller; asserts zero strict-conformance violations at teardown."""
    with running_fake() as fake:
        yield fake
    assert fake.violations == []


@pytest.fixture
def fanuc(fake_controller):
    robot = open_robot(fanuc_url(fake_controller))
    try:
        yield robot
    finally:
        robot.close()
