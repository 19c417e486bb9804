import re

from typer.testing import CliRunner

from robointel.cli import app


def test_learn_commands_registered():
    runner = CliRunner()
    r = runner.invoke(app, ["learn", "--help"])
    assert r.exit_code == 0 and "insertion" in r.output and "grinding" in r.output
    r = runner.invoke(app, ["learn", "insertion", "--demos", "3", "--labelled", "3"])
    assert r.exit_code == 2 and "labelled" in r.output


def test_learn_grinding_runs_on_one_demonstration(tmp_path):
    r = CliRunner().invoke(app, ["learn", "grinding", "--demos", "1", "--out", str(tmp_path)],
                           env={"COLUMNS": "200"})
    assert r.exit_code == 0, r.output
    m = re.search(r"force RMS error along the diagonal ([\d.]+) % of the peak \(([\d.]+) % against", r.output)
    assert m, r.output
    rms_peak, rms_setpoint = float(m.group(1)), float(m.group(2))
    # the robot reproduces the learned pressing force under force control: a few percent, not a miss
    assert 0.0 < rms_setpoint < 15.0 and 0.0 < rms_peak < 25.0
    png = tmp_path / "fig5_13_grinding.png"
    assert png.stat().st_size > 10_000
