import math

import pytest
from typer.testing import CliRunner

from robointel.batch import TaskSpec, run_batch, summarize, wilson_interval
from robointel.cli import app
from robointel.errors import InvalidInput


@pytest.mark.parametrize("k,n", [(0, 10), (3, 10), (10, 10), (48, 50), (1, 1)])
def test_wilson_matches_the_formula(k, n):
    z = 1.959963984540054
    p = k / n
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    lo, hi = wilson_interval(k, n)
    assert lo == pytest.approx(max(0.0, c - h), abs=1e-9) and hi == pytest.approx(min(1.0, c + h), abs=1e-9)


def test_wilson_bad_input():
    for args in ((3, 2), (-1, 5), (0, 0)):
        with pytest.raises(InvalidInput):
            wilson_interval(*args)


def test_summary_and_cli_report(tmp_path):
    specs = [TaskSpec("synthetic", s, {"p_success": p, "category": c}) for p, c in ((0.2, "low"), (0.9, "high"))
             for s in range(20)]
    run_batch(specs, tmp_path / "r", progress=False)
    groups = {g.category: g for g in summarize(tmp_path / "r")}
    assert set(groups) == {"low", "high"} and all(g.trials == 20 for g in groups.values())
    # u ~ U(0,1) from the seed: the counts are the seeds whose draw is below p
    import numpy as np
    u = [np.random.default_rng(s).random() for s in range(20)]
    assert groups["low"].successes == sum(x < 0.2 for x in u)
    assert groups["high"].successes == sum(x < 0.9 for x in u)
    assert groups["low"].reasons == {"missed": 20 - groups["low"].successes}
    res = CliRunner().invoke(app, ["batch", "report", str(tmp_path / "r"), "--plot", str(tmp_path / "p.png")])
    assert res.exit_code == 0, res.output
    assert "high" in res.output and "low" in res.output
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(InvalidInput, match="no results"):
        summarize(tmp_path / "empty")


def test_cli_run_resumes(tmp_path):
    f = tmp_path / "s.yaml"
    f.write_text("tasks:\n  - kind: synthetic\n    seeds: 6\n")
    r = CliRunner().invoke(app, ["batch", "run", str(f), "-o", str(tmp_path / "out")])
    assert r.exit_code == 0, r.output
    assert "6 run" in r.output
    r = CliRunner().invoke(app, ["batch", "run", str(f), "-o", str(tmp_path / "out")])
    assert "0 run" in r.output and "6 already stored" in r.output
    r = CliRunner().invoke(app, ["batch", "run", str(tmp_path / "missing.yaml")])
    # the console wraps the message where the path ends (longer under pytest-xdist: .../popen-gw0/...)
    assert r.exit_code == 2 and "does not exist" in " ".join(r.output.split())
