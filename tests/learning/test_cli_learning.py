import re

from typer.testing import CliRunner

from robointel.cli import app


def test_learn_commands_registered():
    runner = CliRunner()
    r = runner.invoke(app, ["learn", "--help"])
    assert r.exit_code == 0 and "insertion" in r.output and "grinding" in r.output
    r = runner.invoke(app, ["learn", "insertion", "--strategy", "gmr", "--demos", "3", "--labelled", "3"])
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


def test_learn_insertion_end_to_end(tmp_path):
    """gmr: demonstrate -> learn -> one robot trial beside the position-only baseline; plots, a table, a skill file."""
    runner = CliRunner()
    r = runner.invoke(app, ["learn", "insertion", "--strategy", "gmr", "--demos", "3", "--labelled", "1",
                            "--trials", "1", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert "position-only" in r.output and "seated" in r.output
    assert sorted(p.name for p in tmp_path.glob("*.png")) == [
        "fig5_10_synchronised.png", "fig5_11_decomposed.png", "fig5_12_skill.png", "insertion_trials.png"]
    assert (tmp_path / "insertion.skill.h5").is_file()
