from typer.testing import CliRunner

from robointel.cli import app


def test_learn_commands_registered():
    runner = CliRunner()
    r = runner.invoke(app, ["learn", "--help"])
    assert r.exit_code == 0 and "insertion" in r.output and "grinding" in r.output
    r = runner.invoke(app, ["learn", "insertion", "--demos", "3", "--labelled", "3"])
    assert r.exit_code == 2 and "labelled" in r.output


def test_learning_has_demo_stage():
    from robointel.commands import learning

    assert callable(learning.demo_stage) and callable(learning.register)
