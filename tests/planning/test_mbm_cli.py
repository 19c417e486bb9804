"""robointel plan mbm: MBM problems planned start to goal from the command line, then judged by the
independent exact checker (benchmarks/_mbm_checker.py, coal on the URDF meshes)."""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from robointel.cli import _load_commands, app
from robointel.io.trajectory import load_trajectory

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from _mbm_checker import MBMChecker  # noqa: E402

PER_FAMILY = int(os.environ.get("ROBOINTEL_MBM_PER_FAMILY", "1"))  # CI: at most 3


@pytest.fixture(scope="module")
def root(shared_data):
    return shared_data("mbm", "ur5")


@pytest.fixture(scope="module")
def planned(root, tmp_path_factory):
    _load_commands()
    out = tmp_path_factory.mktemp("mbm") / "traj.npz"
    res = CliRunner().invoke(app, ["plan", "mbm", str(root / "problems.json"), "--urdf", str(root / "ur5.urdf"),
                                   "--per-family", str(PER_FAMILY), "--time-budget", "20", "--out", str(out)])
    raw = json.loads((root / "problems.json").read_text())["problems"]
    return res, out, raw


def test_cli_plans_every_family(planned):
    res, out, raw = planned
    assert res.exit_code == 0, res.output
    assert f"{7 * PER_FAMILY}/{7 * PER_FAMILY} planned and passed" in res.output
    for family in raw:
        for p in [p for p in raw[family] if p["valid"]][:PER_FAMILY]:
            tr = load_trajectory(out.with_name(f"traj_{family}_{p['index']}.npz"))
            np.testing.assert_allclose(tr.q[0], p["start"], atol=1e-6)
            assert np.abs(np.asarray(p["goals"]) - tr.q[-1]).max(1).min() < 1e-6
            assert np.all(np.abs(tr.qd) <= 0.5 * (1 + 1e-6))  # the URDF's velocity limit


def test_cli_trajectories_pass_the_independent_checker(planned, root):
    res, out, raw = planned
    checker = MBMChecker(root / "ur5.urdf", root / "ur5.srdf")
    bad = []
    for family in raw:
        for p in [p for p in raw[family] if p["valid"]][:PER_FAMILY]:
            tr = load_trajectory(out.with_name(f"traj_{family}_{p['index']}.npz"))
            v = checker.check_trajectory(tr.t, tr.q, p, qd=tr.qd, amax=3.0 * checker.vmax)
            if not v.ok:
                bad.append((family, p["index"], v.pair, v.min_clearance, v.limit_violation))
    assert not bad, bad


def test_cli_bad_input(root, tmp_path):
    _load_commands()
    r = CliRunner()
    res = r.invoke(app, ["plan", "mbm", str(root / "problems.json")])
    assert res.exit_code == 2 and "--urdf" in res.output
    res = r.invoke(app, ["plan", "mbm", str(root / "problems.json"), "--urdf", str(root / "ur5.urdf"),
                         "--family", "kitchen"])
    assert res.exit_code == 2 and "unknown family 'kitchen'" in res.output
    bad = tmp_path / "p.json"
    bad.write_text(json.dumps({"robot": "ur5", "joints": ["a"], "problems": {"box": [{"index": 1}]}}))
    res = r.invoke(app, ["plan", "mbm", str(bad), "--urdf", str(root / "ur5.urdf")])
    assert res.exit_code == 2 and "problems.box[0]" in res.output
