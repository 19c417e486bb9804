"""The README's quickstarts that stream in real time run as written (``examples/quickstart_*.py``)."""
from __future__ import annotations

import runpy
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.mark.parametrize("name", ["quickstart_robot", "quickstart_teach"])
def test_quickstart_runs(name, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    runpy.run_path(str(EXAMPLES / f"{name}.py"), run_name="__main__")
    out = capsys.readouterr().out
    if name == "quickstart_robot":  # the same trajectory ran on the sim and on the emulated FANUC controller
        assert "sim: completed True" in out and "fanuc: completed True" in out, out
    else:  # every taught waypoint was reached again, and the program planned
        assert "replayed 3 waypoints" in out and "planned" in out, out
