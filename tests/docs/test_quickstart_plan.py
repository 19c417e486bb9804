"""The README's planning quickstart runs as written (``examples/quickstart_plan.py``)."""
from __future__ import annotations

import runpy
from pathlib import Path


def test_quickstart_plan_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    runpy.run_path(str(Path(__file__).resolve().parents[2] / "examples" / "quickstart_plan.py"), run_name="__main__")
    out = capsys.readouterr().out
    assert out.startswith("planned in ") and "s of motion" in out, out
