from typer.testing import CliRunner

from robointel.cli import app


def test_learn_commands_registered():
    runner = CliRunner()
    r = runner.invoke(app, ["learn", "--help"])
    assert r.exit_code == 0 and "insertion" in r.output and "grinding" in r.output
    r = runner.invoke(app, ["learn", "insertion", "--demos", "3", "--labelled", "3"])
    assert r.exit_code == 2 and "labelled" in r.output


def test_learn_insertion_end_to_end(tmp_path):
    """demonstrate -> learn -> one robot trial beside the position-only baseline; plots and a table."""
    runner = CliRunner()
    r = runner.invoke(app, ["learn", "insertion", "--demos", "3", "--labelled", "1", "--trials", "1",
                            "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert "position-only" in r.output and "success" in r.output
    assert sorted(p.name for p in tmp_path.glob("*.png")) == [
        "fig5_10_synchronised.png", "fig5_11_decomposed.png", "fig5_12_skill.png", "insertion_trials.png"]
