"""Learned skills and grasp execution on the robot interface, ``sim`` backend (the MuJoCo workcell)."""
import numpy as np
import pytest

from robointel.control.admittance import AdmittanceGains
from robointel.control.payload import PayloadCompensation
from robointel.errors import ControllerFault, InvalidInput
from robointel.geometry.obstacles import Box
from robointel.interface.gripper import JawGeometry, SimGripper
from robointel.interface.sim import SimRobot
from robointel.interface.state import RobotMode
from robointel.interface.wrench_source import StateWrench
from robointel.outcome import Failure
from robointel.robot import Robot
from robointel.sim import Workcell
from robointel.sim.mjcf import Payload, SimObject
from robointel.skills.cells import (
    R_DOWN,
    HoleTask,
    PegTool,
    PlateTask,
    ik_near,
    peg_hole_workcell,
    plate_workcell,
    stylus,
)
from robointel.skills.grasp_execution import GraspMotion, execute_grasp, joint_move
from robointel.skills.grinding import run_grinding
from robointel.skills.insertion import SkillLimits, run_insertion


def _peg_arm(peg, hole, lateral=(0.0, 0.0), tilt=(0.0, 0.0)):
    wc, robot = peg_hole_workcell(peg, hole)
    wc.reset(ik_near(robot, hole.start_tcp(peg, lateral=lateral, tilt=tilt)))
    wc.hold(0.2)
    source = StateWrench(robot, PayloadCompensation(peg.mass, np.asarray(peg.payload().com)))
    return SimRobot(wc), robot, source


def test_learned_insertion_seats_the_peg_over_streamed_positions(insertion_skill):
    peg, hole = PegTool(), HoleTask(clearance=0.5e-3)
    rng = np.random.default_rng(2026)  # starts never used while writing the runner
    wins = 0
    for _ in range(3):
        lat, tilt = rng.uniform(-1.5e-3, 1.5e-3, 2), (rng.uniform(0, 2 * np.pi), rng.uniform(0, np.radians(3)))
        arm, robot, source = _peg_arm(peg, hole, lat, tilt)
        res = run_insertion(arm, robot, insertion_skill.predict, hole.advance(), source=source, time_limit=8.0)
        wins += res.success
        # every command went through the interface: consecutive targets within one period's reach
        steps = np.abs(np.diff(res.q_cmd, axis=0)) / arm.period
        assert np.all(steps <= robot.velocity_limit + 1e-9)
        if res.success:
            T = robot.fk(arm.workcell.q)
            tip = T[:3, 3] + T[:3, 2] * peg.radius
            assert tip[2] - (hole.top[2] - hole.depth) < 1.5e-3  # seated: the tip at the pocket's bottom
            assert res.outcome.figures["max_force_n"] < SkillLimits().max_force
    assert wins >= 2, f"{wins}/3 insertions seated"


def test_a_blocked_peg_hits_the_force_limit_and_the_arm_stops_saying_why():
    peg, hole = PegTool(), HoleTask(clearance=-2e-3)  # the pocket is narrower than the peg

    def push(w):
        return np.array([0.0, 0.0, 0.01, 0.0, 0.0])

    arm, robot, source = _peg_arm(peg, hole)
    res = run_insertion(arm, robot, push, hole.advance(), source=source, time_limit=5.0,
                        gains=AdmittanceGains(0.0, 0.0), limits=SkillLimits(max_force=25.0))  # no yield
    assert res.outcome.reason is Failure.FORCE_LIMIT
    st = arm.state()
    assert st.mode is RobotMode.STOPPED and "force limit" in st.why_stopped
    with pytest.raises(ControllerFault, match="force limit"):
        arm.stream(st.q)
    arm.recover()
    arm.stream(arm.state().q_cmd)  # recovered: commanding again


def test_a_policy_that_returns_garbage_is_refused_and_the_arm_holds():
    arm, robot, source = _peg_arm(PegTool(), HoleTask())
    with pytest.raises(InvalidInput, match="5 finite numbers"):
        run_insertion(arm, robot, lambda w: np.array([0.0, np.nan, 0.0, 0.0, 0.0]), 0.03, source=source)
    assert arm.state().mode is RobotMode.HOLDING


def test_grinding_tracks_the_force_map_over_streamed_positions():
    plate = PlateTask()
    tool = stylus()
    wc, robot = plate_workcell(plate, tool)
    c = np.array(plate.center)
    a = np.r_[c - 0.05, plate.top + tool.radius + 0.0005]
    b = np.r_[c + 0.05, plate.top + tool.radius]
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R_DOWN, a
    wc.reset(ik_near(robot, T))
    wc.hold(0.2)
    arm = SimRobot(wc)

    def setpoint(p):  # a force map with a hard spot at the plate centre, 6 .. 20 N
        return 6.0 + 14.0 * np.exp(-0.5 * np.sum((p[:2] - c) ** 2) / 0.02 ** 2)

    res = run_grinding(arm, robot, setpoint, a, b, source=StateWrench(robot, PayloadCompensation(
        tool.mass, np.asarray(tool.payload().com))), speed=0.03)
    assert res.outcome.success
    assert res.rms_rel() < 0.15, res.rms_rel()
    on = res.on_path
    hard = np.linalg.norm(res.position[on, :2] - c, axis=1) < 0.01
    assert res.force[on][hard].mean() > 15.0  # it pressed harder on the hard spot
    assert np.percentile(res.force[on][~hard], 2) > 3.0  # and stayed in contact elsewhere
    assert np.linalg.norm(res.position[-1, :2] - b[:2]) < 2e-3  # reached the end of the path


def _gripper_cell():
    jaws = JawGeometry()
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = [[0, 0, 1.0], [0, 1, 0], [-1, 0, 0]], [0.14, 0, 0]
    robot = Robot.load("lrmate200id7l", tool=T)
    cube = SimObject("cube", Box(np.array([0.5, 0.1, 0.02]), np.array([0.03, 0.03, 0.04])), 0.1)
    wc = Workcell(Robot.load("lrmate200id7l"), objects=[cube], payload=Payload(0.4, (0.08, 0, 0)))
    wc.reset(np.array([0.0, 0.2, -0.3, 0.0, -1.2, 0.0]))
    wc.hold(0.2)
    arm = SimRobot(wc)
    return arm, robot, SimGripper(arm, robot, jaws)


def test_a_pick_on_the_simulated_cell_lifts_the_cube():
    arm, robot, gripper = _gripper_cell()
    G = np.eye(4)
    G[:3, :3], G[:3, 3] = R_DOWN, [0.5, 0.1, 0.025]
    run = execute_grasp(arm, gripper, robot, GraspMotion(G, 0.045, lift=0.1))
    assert run.success and run.grip["close"].held == "cube"
    assert run.grip["close"].width == pytest.approx(0.03, abs=1e-3)
    arm.idle(0.5)
    z = arm.workcell.body_pose("cube")[2, 3]
    assert z == pytest.approx(0.02 + 0.1, abs=5e-3)  # carried up by the lift
    for name in ("approach", "descend", "lift"):
        assert run.phases[name].completed
    gripper.open()
    arm.idle(1.0)
    assert arm.workcell.body_pose("cube")[2, 3] < 0.03  # released: it fell back on the table


def test_a_grasp_beside_the_cube_closes_on_nothing_and_retreats():
    arm, robot, gripper = _gripper_cell()
    G = np.eye(4)
    G[:3, :3], G[:3, 3] = R_DOWN, [0.5, 0.16, 0.025]
    run = execute_grasp(arm, gripper, robot, GraspMotion(G, 0.045))
    assert not run.success and run.outcome.reason is Failure.NO_GRASP
    np.testing.assert_allclose(arm.state().q, run.q["pre"], atol=2e-3)  # backed off to the pre-grasp
    assert arm.workcell.body_pose("cube")[2, 3] == pytest.approx(0.02, abs=2e-3)


def test_joint_move_respects_the_scaled_limits():
    robot = Robot.load("lrmate200id7l")
    a, b = np.zeros(6), np.array([0.5, 0.3, -0.2, 1.0, -0.5, 2.0])
    tr = joint_move(robot, a, b, 0.008, speed=0.3)
    np.testing.assert_allclose(tr.q[0], a)
    np.testing.assert_allclose(tr.q[-1], b)
    assert np.all(np.abs(tr.qd) <= 0.3 * robot.velocity_limit + 1e-6)
    with pytest.raises(InvalidInput):
        joint_move(robot, a, b, 0.008, speed=1.5)
