"""The ``robointel grasp`` command group."""
from typer.testing import CliRunner

from robointel.cli import app
from robointel.learning.grasp_database import GraspDatabase


def test_grasp_teach_writes_a_database(tmp_path):
    out = tmp_path / "g.h5"
    res = CliRunner().invoke(app, ["grasp", "teach", "--out", str(out)])
    assert res.exit_code == 0, res.output
    db = GraspDatabase(out)
    cats = {t.category for t in db.load_all()}
    assert {"cup", "can", "box", "ball", "long_tool", "toy_arm"} <= cats
