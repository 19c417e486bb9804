"""The demonstration file refuses names that would escape its index and reports corrupt files."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.io.demonstrations import DemonstrationFile
from robointel.learning.demonstration import Demonstration


def _demo(name: str = "d0") -> Demonstration:
    n = 40
    return Demonstration.create(np.arange(n) * 0.01, np.tile(np.eye(4), (n, 1, 1)), np.zeros((n, 6)), name=name)


@pytest.mark.parametrize("name", ["a/b", "/abs", "..", ".", "tab\there"])
def test_names_outside_the_index_are_refused(tmp_path, name):
    f = DemonstrationFile(tmp_path / "d.h5")
    f.append(_demo())
    with pytest.raises(InvalidInput, match="not allowed"):
        f.append(_demo(), name=name)
    assert f.names() == ["d0"]                      # nothing hidden was stored
    assert [d.name for d in f.load_all()] == ["d0"]


def test_truncated_and_foreign_files_are_reported(tmp_path):
    good = tmp_path / "d.h5"
    DemonstrationFile(good).extend([_demo("d0"), _demo("d1")])
    raw = good.read_bytes()
    cut = tmp_path / "cut.h5"
    cut.write_bytes(raw[: len(raw) // 2])
    with pytest.raises(InvalidInput, match="truncated"):
        DemonstrationFile(cut).load_all()
    with pytest.raises(InvalidInput, match="truncated"):
        DemonstrationFile(cut).append(_demo("d2"))
    text = tmp_path / "notes.h5"
    text.write_text("not hdf5")
    with pytest.raises(InvalidInput, match="not a readable HDF5"):
        DemonstrationFile(text).names()
