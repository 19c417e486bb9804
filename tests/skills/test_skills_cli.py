"""``robointel skill insert`` and ``robointel grasp execute`` with ``--robot`` and ``--record``."""
from mcap.reader import make_reader
from typer.testing import CliRunner

from robointel.cli import app
from robointel.io.mcap_log import COMMAND, JOINT_STATES
from robointel.skills.cells import HoleTask, PegTool, ik_near
from robointel.testing.emulator import fanuc_url, running_fake


def _topics(path):
    counts: dict[str, int] = {}
    with open(path, "rb") as f:
        for _, channel, _ in make_reader(f).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return counts


def test_skill_insert_on_the_emulator_with_a_virtual_contact_records_the_run(tmp_path):
    peg = PegTool()
    robot = peg.robot()
    q0 = ik_near(robot, HoleTask().start_tcp(peg))  # the emulated arm waits over the pocket
    with running_fake(q0) as fake:
        out = CliRunner().invoke(app, ["skill", "insert", "--robot", fanuc_url(fake), "--wrench", "virtual",
                                       "--demos", "1", "--trials", "1", "--time-limit", "8", "--stall-ms", "400",
                                       "--record", str(tmp_path / "run.mcap")])
        violations = fake.violations
    assert out.exit_code == 0, out.output
    assert "seated 1/1" in out.output
    assert violations == []
    counts = _topics(tmp_path / "run.mcap")
    assert counts[COMMAND] > 100 and counts[JOINT_STATES] >= counts[COMMAND]


def test_skill_commands_refuse_a_bad_robot_url():
    for cmd in (["grasp", "execute"], ["skill", "insert"], ["skill", "grind"]):
        out = CliRunner().invoke(app, [*cmd, "--robot", "ur5://x"])
        assert out.exit_code == 2 and "unknown robot" in out.output, cmd
