import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from robointel.batch import Fault, ResultStore, TaskSpec, run_batch
from robointel.errors import InvalidInput, UnknownTaskKind

SRC = str(Path(__file__).resolve().parents[2] / "src")


def outcomes(folder):
    """(key -> outcome) of a result folder: what must agree between runs (timings and workers aside)."""
    return {(r["spec_hash"], r["seed"]): (r["success"], r["reason"], r["detail"], r["figures"], r["category"])
            for r in ResultStore(folder).rows()}


def test_run_then_resume_skips_done(tmp_path):
    specs = [TaskSpec("synthetic", s, {"p_success": 0.5}) for s in range(12)]
    r1 = run_batch(specs[:7], tmp_path, progress=False)
    assert (r1.counts.done, r1.counts.skipped) == (7, 0)
    r2 = run_batch(specs, tmp_path, progress=False)
    assert (r2.counts.done, r2.counts.skipped, r2.counts.total) == (5, 7, 12)
    r3 = run_batch(specs + specs, tmp_path, progress=False)  # repeated specs run once
    assert (r3.counts.done, r3.counts.total) == (0, 12)
    rows = ResultStore(tmp_path).rows()
    assert len(rows) == 12 and sum(r["success"] for r in rows) == r1.counts.done - r1.counts.failed + \
        r2.counts.done - r2.counts.failed


def test_stop_from_callback_keeps_finished_rows(tmp_path):
    specs = [TaskSpec("synthetic", s) for s in range(10)]
    seen = []

    def stop(row):
        seen.append(row)
        if len(seen) == 4:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_batch(specs, tmp_path, progress=False, on_row=stop, flush_rows=100, flush_s=100.0)
    assert len(ResultStore(tmp_path)) == 4  # flushed on the way out
    assert run_batch(specs, tmp_path, progress=False).counts.done == 6


DRIVER = """
import sys
from robointel.batch import TaskSpec, run_batch
specs = [TaskSpec("synthetic", s, {"work_s": 0.05, "p_success": 0.6}) for s in range(40)]
run_batch(specs, sys.argv[1], progress=False, flush_rows=2, flush_s=0.2)
"""


def test_driver_killed_and_resumed_equals_uninterrupted(tmp_path):
    env = {**os.environ, "PYTHONPATH": SRC}
    cut = tmp_path / "cut"
    p = subprocess.Popen([sys.executable, "-c", DRIVER, str(cut)], env=env)
    t0 = time.monotonic()
    while len(list(cut.glob("part-*.parquet"))) < 3 and time.monotonic() - t0 < 60 and p.poll() is None:
        time.sleep(0.02)
    p.send_signal(signal.SIGKILL)  # the driver dies without any chance to clean up
    p.wait()
    before = len(ResultStore(cut))
    assert 0 < before < 40, "the driver should have been killed mid-run"
    specs = [TaskSpec("synthetic", s, {"work_s": 0.05, "p_success": 0.6}) for s in range(40)]
    resumed = run_batch(specs, cut, progress=False)
    assert resumed.counts.skipped == before and resumed.counts.done == 40 - before
    full = tmp_path / "full"
    run_batch(specs, full, progress=False)
    assert outcomes(cut) == outcomes(full)
    assert len(outcomes(cut)) == 40


def test_bad_arguments(tmp_path):
    with pytest.raises(UnknownTaskKind, match="known kinds"):
        run_batch([TaskSpec("nope", 0)], tmp_path, progress=False)
    assert not list(tmp_path.glob("part-*"))
    with pytest.raises(InvalidInput, match="engine"):
        run_batch([TaskSpec("synthetic", 0)], tmp_path, engine="dask", progress=False)
    with pytest.raises(InvalidInput):
        run_batch([TaskSpec("synthetic", 0)], tmp_path, workers=0, progress=False)
    with pytest.raises(InvalidInput, match="Ray engine only"):
        run_batch([TaskSpec("synthetic", 0)], tmp_path, fault=Fault(("x:0",), str(tmp_path)), progress=False)


def test_custom_kind_by_import_path(tmp_path):
    spec = TaskSpec("robointel.batch.kinds.synthetic:synthetic", 3)
    run_batch([spec], tmp_path, progress=False)
    (row,) = ResultStore(tmp_path).rows()
    assert row["detail"].startswith("u = ") and row["category"] == "synthetic"
    with pytest.raises(UnknownTaskKind, match="cannot import"):
        run_batch([TaskSpec("robointel.nothing:here", 0)], tmp_path, progress=False)


def test_a_task_past_its_budget_is_stored_as_a_timeout_and_the_sweep_goes_on(tmp_path):
    specs = [TaskSpec("synthetic", s, {"work_s": 30.0 if s == 1 else 0.0, "p_success": 1.0}) for s in range(3)]
    run = run_batch(specs, tmp_path / "r", progress=False, timeout_s=0.5)
    rows = {r["seed"]: r for r in ResultStore(tmp_path / "r").rows()}
    assert [rows[s]["reason"] for s in range(3)] == ["none", "timeout", "none"]
    assert run.counts.failed == 1 and "0.5 s" in rows[1]["detail"] and "TaskTimeout" in rows[1]["traceback"]
    assert 0.4 <= rows[1]["wall_s"] < 10.0
    with pytest.raises(InvalidInput, match="timeout_s"):
        run_batch(specs, tmp_path / "bad", progress=False, timeout_s=0.0)
