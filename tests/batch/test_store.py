import pyarrow.parquet as pq
import pytest

from robointel.batch import ResultStore, TaskSpec, execute
from robointel.batch.execute import failure_row
from robointel.errors import ResultStoreError
from robointel.outcome import Failure, TrialOutcome


def _rows(n, **params):
    return [execute(TaskSpec("synthetic", s, params).to_dict()) for s in range(n)]


def test_rows_flush_as_whole_files_and_reopen(tmp_path):
    st = ResultStore(tmp_path / "r")
    rows = _rows(5)
    assert sum(st.add(r) for r in rows[:3]) == 3
    assert st.files() == [] and st.pending == 3  # nothing on disk before a flush
    f = st.flush()
    assert f is not None and f.exists() and pq.read_table(f).num_rows == 3
    assert not list((tmp_path / "r").glob(".*.tmp"))  # the temporary name is gone after the rename
    st.extend(rows[3:])
    assert len(st.files()) == 2
    again = ResultStore(tmp_path / "r")  # a new driver sees every stored key
    assert again.done == {(r["spec_hash"], r["seed"]) for r in rows}
    got = again.rows()
    assert [r["seed"] for r in got] == [0, 1, 2, 3, 4]
    for r, g in zip(rows, got):
        assert TrialOutcome.from_record(g) == TrialOutcome.from_record(r)
        assert g["spec"] == r["spec"] and g["kind"] == "synthetic"


def test_a_key_is_recorded_once(tmp_path):
    st = ResultStore(tmp_path)
    r = _rows(1)[0]
    assert st.add(r) and not st.add(dict(r))
    st.flush()
    assert not st.add(r)
    assert st.flush() is None
    # two files holding one key (two drivers on one folder): the table keeps one row
    other = ResultStore(tmp_path / "x")
    other.extend([r])
    (tmp_path / "x" / other.files()[0].name).rename(tmp_path / other.files()[0].name)
    assert len(ResultStore(tmp_path).files()) == 2
    assert ResultStore(tmp_path).table().num_rows == 1
    f = ResultStore(tmp_path).compact()
    assert ResultStore(tmp_path).files() == [f] and pq.read_table(f).num_rows == 1


def test_interrupted_flush_leaves_no_partial_rows(tmp_path):
    st = ResultStore(tmp_path)
    st.extend(_rows(2))
    (tmp_path / ".part-deadbeef.parquet.tmp").write_bytes(b"PAR1 half a file")  # a flush cut by a crash
    assert ResultStore(tmp_path).table().num_rows == 2


def test_failures_keep_reason_and_traceback(tmp_path):
    st = ResultStore(tmp_path)
    st.extend(_rows(3, raise_on=[1]))
    bad = [r for r in st.rows() if not r["success"] and r["reason"] == "error"]
    assert len(bad) == 1 and bad[0]["seed"] == 1
    assert "RuntimeError: synthetic failure requested for seed 1" in bad[0]["traceback"]
    assert "Traceback (most recent call last)" in bad[0]["traceback"]
    dead = failure_row(TaskSpec("synthetic", 9), Failure.FAULT, "worker died", "WorkerCrashedError ...")
    st.extend([dead])
    r = [r for r in st.rows() if r["seed"] == 9][0]
    assert r["reason"] == "fault" and r["traceback"].startswith("WorkerCrashedError")


def test_bad_rows_and_folders(tmp_path):
    with pytest.raises(ResultStoreError, match="misses"):
        ResultStore(tmp_path).add({"spec_hash": "x", "seed": 0})
    (tmp_path / "file").write_text("x")
    with pytest.raises(ResultStoreError, match="not a folder"):
        ResultStore(tmp_path / "file")
