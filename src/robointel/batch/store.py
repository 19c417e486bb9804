"""The result store: a folder holding a Parquet dataset, one row per (spec hash, seed).

Rows are appended as they finish: each flush writes one small Parquet file under a hidden
temporary name, syncs it and renames it into place (``os.replace`` is atomic on POSIX), so a
crash at any moment leaves only whole files: what was flushed is never lost, what was not is
simply run again on resume. The driver is the only writer. A key already present is never
written twice, and :meth:`ResultStore.table` keeps the first row of a key should two files
ever hold it (two drivers on one folder).

Schema (:data:`SCHEMA`): ``spec_hash`` string, ``seed`` int64, ``kind``, ``category``,
``spec`` (JSON of the :class:`TaskSpec`), ``success`` bool, ``reason`` (a :class:`Failure` value),
``detail``, ``figures`` and ``timings`` (map string -> float64, SI units / seconds),
``traceback`` (empty unless the trial raised), ``worker`` (host:pid), ``engine``, ``wall_s`` and
``cpu_s`` (wall and CPU seconds of the task in its worker), ``finished_at`` (timestamp, UTC).
"""

from __future__ import annotations

import json
import os
import uuid
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robointel._extras import optional_module
from robointel.errors import ResultStoreError

if TYPE_CHECKING:
    import pyarrow as pa
    import pyarrow.dataset as ds
    import pyarrow.parquet as pq
else:
    pa = optional_module("pyarrow", "batch", "a batch run's result store")
    ds = optional_module("pyarrow.dataset", "batch", "a batch run's result store")
    pq = optional_module("pyarrow.parquet", "batch", "a batch run's result store")

__all__ = ["SCHEMA", "ResultStore"]

SCHEMA = pa.schema([
    ("spec_hash", pa.string()), ("seed", pa.int64()), ("kind", pa.string()), ("category", pa.string()),
    ("spec", pa.string()), ("success", pa.bool_()), ("reason", pa.string()), ("detail", pa.string()),
    ("figures", pa.map_(pa.string(), pa.float64())), ("timings", pa.map_(pa.string(), pa.float64())),
    ("traceback", pa.string()), ("worker", pa.string()), ("engine", pa.string()), ("wall_s", pa.float64()),
    ("cpu_s", pa.float64()), ("finished_at", pa.timestamp("us", tz="UTC")),
])


def _column(rows: Sequence[Mapping[str, Any]], name: str) -> list[Any]:
    if name == "spec":
        return [json.dumps(r["spec"], sort_keys=True) for r in rows]
    if name in ("figures", "timings"):
        return [list(r[name].items()) for r in rows]
    return [r[name] for r in rows]


class ResultStore:
    """A Parquet result dataset in ``root`` (created if missing).

    Args:
        root: The dataset folder.

    Raises:
        ResultStoreError: ``root`` exists and is not a folder, or holds unreadable Parquet files.
    """

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        if self.root.exists() and not self.root.is_dir():
            raise ResultStoreError(f"result store {self.root} exists and is not a folder", value=str(self.root))
        self.root.mkdir(parents=True, exist_ok=True)
        self._done: set[tuple[str, int]] = set(self._read_keys())
        self._buffer: list[dict[str, Any]] = []

    # -- reading
    def files(self) -> list[Path]:
        """The dataset's Parquet files (temporary files of an interrupted flush are not part of it)."""
        return sorted(p for p in self.root.glob("part-*.parquet") if p.is_file())

    def _read_keys(self) -> list[tuple[str, int]]:
        files = self.files()
        if not files:
            return []
        try:
            t = ds.dataset([str(f) for f in files], format="parquet", schema=SCHEMA).to_table(
                columns=["spec_hash", "seed"])
        except (pa.ArrowInvalid, OSError) as exc:
            raise ResultStoreError(f"cannot read result store {self.root}: {exc}", value=str(self.root)) from None
        return list(zip(t.column("spec_hash").to_pylist(), t.column("seed").to_pylist()))

    @property
    def done(self) -> frozenset[tuple[str, int]]:
        """Keys ``(spec_hash, seed)`` already stored (flushed or waiting in the buffer)."""
        return frozenset(self._done)

    def __len__(self) -> int:
        return len(self._done)

    def __contains__(self, key: object) -> bool:
        return key in self._done

    def table(self) -> pa.Table:
        """All flushed rows, one per key (the first written wins), ordered by key."""
        files = self.files()
        if not files:
            return SCHEMA.empty_table()
        t = ds.dataset([str(f) for f in files], format="parquet", schema=SCHEMA).to_table()
        t = t.sort_by([("finished_at", "ascending")])
        keys = list(zip(t.column("spec_hash").to_pylist(), t.column("seed").to_pylist()))
        seen: set[tuple[str, int]] = set()
        keep = []
        for i, k in enumerate(keys):
            if k not in seen:
                seen.add(k)
                keep.append(i)
        if len(keep) < t.num_rows:
            t = t.take(pa.array(keep, pa.int64()))
        return t.sort_by([("spec_hash", "ascending"), ("seed", "ascending")])

    def rows(self) -> list[dict[str, Any]]:
        """:meth:`table` as a list of dicts (``spec`` parsed, ``figures``/``timings`` as dicts)."""
        out = []
        for r in self.table().to_pylist():
            r["spec"] = json.loads(r["spec"])
            r["figures"] = dict(r["figures"] or [])
            r["timings"] = dict(r["timings"] or [])
            out.append(r)
        return out

    # -- writing
    def add(self, row: Mapping[str, Any]) -> bool:
        """Buffer one result row; return False (and drop it) when its key is already stored.

        Raises:
            ResultStoreError: the row misses a column of :data:`SCHEMA`.
        """
        missing = [n for n in SCHEMA.names if n not in row]
        if missing:
            raise ResultStoreError(f"result row misses {missing}", value=missing)
        key = (str(row["spec_hash"]), int(row["seed"]))
        if key in self._done:
            return False
        self._done.add(key)
        self._buffer.append(dict(row))
        return True

    @property
    def pending(self) -> int:
        """Rows buffered but not yet flushed."""
        return len(self._buffer)

    def flush(self) -> Path | None:
        """Write the buffered rows as one new Parquet file (temporary name, fsync, atomic rename).

        Returns:
            The new file, or None when nothing was buffered.
        """
        if not self._buffer:
            return None
        rows, self._buffer = self._buffer, []
        table = pa.table({n: pa.array(_column(rows, n), type=SCHEMA.field(n).type) for n in SCHEMA.names},
                         schema=SCHEMA)
        name = f"part-{uuid.uuid4().hex}.parquet"
        tmp = self.root / f".{name}.tmp"
        pq.write_table(table, tmp)
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, self.root / name)
        dfd = os.open(self.root, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
        return self.root / name

    def extend(self, rows: Iterable[Mapping[str, Any]]) -> int:
        """Add rows and flush; return how many were new."""
        n = sum(self.add(r) for r in rows)
        self.flush()
        return n

    def compact(self) -> Path | None:
        """Rewrite the dataset as one deduplicated file; the old files go once the new one is in place.

        Returns:
            The new file (None for an empty store).
        """
        self.flush()
        old = self.files()
        if not old:
            return None
        t = self.table()
        name = f"part-{uuid.uuid4().hex}.parquet"
        tmp = self.root / f".{name}.tmp"
        pq.write_table(t, tmp)
        os.replace(tmp, self.root / name)
        for f in old:
            f.unlink()
        return self.root / name
