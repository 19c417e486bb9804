"""Lead-through (admittance over streamed positions) on the robot interface."""
import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.interface import open_robot
from robointel.interface.sim import SimRobot
from robointel.robot import Robot
from robointel.sim import Workcell
from robointel.teach.lead_through import lead_through
from robointel.testing.emulator import running_fake


def test_a_push_on_the_simulated_tool_moves_the_tcp_along_it():
    robot = Robot.load("lrmate200id7l")
    q0 = np.array([0.0, 0.2, -0.3, 0.0, -0.8, 0.0])
    wc = Workcell(robot, q0=q0)
    arm = SimRobot(wc)
    p0 = robot.fk(q0)[:3, 3]

    def hand(k):
        if k < 60:  # 0.48 s of a 20 N push along +y at the TCP
            wc.apply_wrench([0.0, 20.0, 0.0], point=robot.fk(wc.q)[:3, 3])
        else:
            wc.clear_wrench()

    res = lead_through(arm, robot, 1.0, step_world=hand)
    arm.idle(0.3)
    d = robot.fk(wc.q)[:3, 3] - p0
    assert d[1] > 0.02, d  # moved along the push
    assert abs(d[0]) < 0.3 * d[1] and abs(d[2]) < 0.3 * d[1]
    assert not res.held.any()
    np.testing.assert_allclose(res.q_cmd[-1], res.q_cmd[-2], atol=1e-4)  # released: it stops
    arm.close()


def test_fanuc_without_force_telemetry_is_refused():
    with running_fake() as fake:
        with open_robot(f"fanuc://127.0.0.1:{fake.rmi_port}?sm_port={fake.sm_port}") as arm:
            with pytest.raises(InvalidInput, match="no F/T wrench"):
                lead_through(arm, Robot.load("lrmate200id7l"), 1.0)
        assert fake.violations == []
