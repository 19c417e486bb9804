import contextlib
import dataclasses

import pytest

from robointel.interface import open_robot
from robointel.interface.emulator import EmulatorProcess, protocol_violations


@pytest.fixture(scope="session")
def frmp_segment():
    """The first segment of the FRMP on the built-in table71 scene (CFS + temporal optimization)."""
    from robointel.planning import plan_scene
    from robointel.planning.scene import load_scene

    s = load_scene("table71")
    short = dataclasses.replace(s, waypoints=s.waypoints[:2], steps=s.steps[:1], waypoint_names=s.waypoint_names[:2])
    return plan_scene(short).trajectory


class FakeProxy:
    """The FakeCRXController API used by the tests, on an EmulatorProcess (a child process)."""

    PROPERTIES = {"q_meas_deg", "qd_meas_deg_s", "violations", "motion_possible", "tx_silent"}

    def __init__(self, emu):
        self._emu = emu
        self.rmi_port, self.sm_port = emu.rmi_port, emu.sm_port

    def timed(self, name, *args):
        """(value, child's perf_counter just before the call)."""
        return self._emu.timed(name, *args)

    def __getattr__(self, name):
        if name == "violations":
            return protocol_violations(self._emu.call(name))
        if name in self.PROPERTIES:
            return self._emu.call(name)
        return lambda *args: self._emu.call(name, *args)


@contextlib.contextmanager
def running_fake(q0=None):
    """FakeCRXController in strict-conformance mode on 127.0.0.1, wall-paced, in a child process, at ``q0`` (rad)."""
    emu = EmulatorProcess(q0)
    try:
        yield FakeProxy(emu)
    finally:
        emu.close()


def fanuc_url(fake) -> str:
    return f"fanuc://127.0.0.1:{fake.rmi_port}?sm_port={fake.sm_port}"


@pytest.fixture
def fake_controller():
    """A running fake controller; asserts zero strict-conformance violations at teardown."""
    emu = EmulatorProcess()
    try:
        yield FakeProxy(emu)
    finally:
        violations = protocol_violations(emu.close())
    assert violations == []


@pytest.fixture
def fanuc(fake_controller):
    robot = open_robot(fanuc_url(fake_controller))
    try:
        yield robot
    finally:
        robot.close()
