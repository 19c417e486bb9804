"""The package's layering and its curated public API."""
from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

PACKAGES = ["robointel.io", "robointel.planning", "robointel.programming", "robointel.learning"]


@pytest.mark.parametrize("name", PACKAGES)
def test_every_public_name_resolves(name):
    mod = importlib.import_module(name)
    assert mod.__all__, f"{name} exports nothing"
    for attr in mod.__all__:
        assert getattr(mod, attr) is not None, f"{name}.{attr}"


def test_io_imports_no_phase():
    code = ("import sys, robointel.io, robointel.io.scene, robointel.io.grasp_db, robointel.io.demonstrations, "
            "robointel.io.trajectory, robointel.io.reference\n"
            "print(sorted(m for m in sys.modules if m.split('.')[:2] in "
            "(['robointel', 'learning'], ['robointel', 'planning'], ['robointel', 'programming'])))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout
