"""``--robot sim?process=1``: the CLI's commands run the paced sim in its streaming process."""
import os

import numpy as np
import pytest
from typer.testing import CliRunner

from robointel.cli import app
from robointel.errors import InvalidInput
from robointel.interface import sim_stream
from robointel.interface.open import is_sim, parse_robot_url


class _Spy(sim_stream.SimStreamRobot):
    """The streaming process's robot, noting what the command did with it."""

    made: list["_Spy"] = []

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.pid = self.driver._proc.pid
        self.runs = []
        _Spy.made.append(self)

    def execute(self, trajectory, **kwargs):
        res = super().execute(trajectory, **kwargs)
        self.idle(0.5)  # the servo settles on the last target (the in-process sim's bound, test_sim)
        self.runs.append((trajectory, res, self.state().q))
        return res


def _gone(pid):
    """True when no process ``pid`` exists (not even a zombie: the parent has reaped it)."""
    return not os.path.exists(f"/proc/{pid}")


def test_plan_execute_moves_the_arm_through_the_streaming_process(tmp_path, monkeypatch):
    _Spy.made = []
    monkeypatch.setattr(sim_stream, "SimStreamRobot", _Spy)
    out = CliRunner().invoke(app, ["plan", "table71", "--out", str(tmp_path / "t.npz"), "--no-plots", "--execute",
                                   "--robot", "sim?process=1"])
    assert out.exit_code == 0, out.output
    assert "missed cycles" in out.output
    assert len(_Spy.made) == 1, "the command did not open the sim's streaming process"
    robot = _Spy.made[0]
    (trajectory, res, q_end), = robot.runs
    travel = float(np.max(np.abs(trajectory.q[-1] - trajectory.q[0])))
    assert travel > 0.1  # the plan moves the arm
    assert res.completed and len(res.q_cmd) >= len(trajectory.q) - 1
    # where the child's workcell ended (its state through the shared block), not where we asked
    assert np.max(np.abs(q_end - trajectory.q[-1])) < 2e-3
    assert not robot.driver.alive() and _gone(robot.pid)  # closed, and no process left behind


def test_the_url_forms():
    assert parse_robot_url("sim").stream_process is False
    assert parse_robot_url("sim?process=1").stream_process is True
    assert parse_robot_url("sim?process=0").stream_process is False
    u = parse_robot_url("fanuc://10.0.0.2:16002?sm_port=60016")
    assert (u.kind, u.host, u.rmi_port, u.sm_port) == ("fanuc", "10.0.0.2", 16002, 60016)
    assert is_sim("sim?process=1") and not is_sim("fanuc://h") and not is_sim("ur5://x")
    for bad in ("sim?proc=1", "sim?process=2", "sim?process", "ur5://x", "fanuc://h?sm_port=x"):
        with pytest.raises(InvalidInput) as e:
            parse_robot_url(bad)
        assert e.value.value == bad


@pytest.mark.parametrize("cmd", [["skill", "insert"], ["skill", "grind"], ["grasp", "execute"]])
def test_a_bad_sim_option_is_refused_before_any_learning(cmd):
    out = CliRunner().invoke(app, [*cmd, "--robot", "sim?lookahead=1"])
    assert out.exit_code == 2 and "unknown option 'lookahead'" in out.output, out.output


def test_grasp_execute_says_the_streaming_process_has_no_gripper():
    out = CliRunner().invoke(app, ["grasp", "execute", "--robot", "sim?process=1"])
    assert out.exit_code == 2 and "no gripper" in out.output, out.output
