"""The package's layering and its curated public API."""
from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGES = ["robointel.io", "robointel.planning", "robointel.teach", "robointel.learning"]


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
            "(['robointel', 'learning'], ['robointel', 'planning'], ['robointel', 'teach'], ['robointel', 'skills'])))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


IO = Path(__file__).resolve().parents[1] / "src" / "robointel" / "io"
# the phases and everything above them (io reads and writes files only, under the phases)
ABOVE_IO = {"planning", "learning", "teach", "skills", "program", "batch", "report", "commands", "cli"}


def _robointel_imports(tree: ast.AST) -> list[tuple[str, str]]:
    """(enclosing top-level function or '', absolute module) of every robointel import in a module's AST."""
    found: list[tuple[str, str]] = []
    for top in ast.iter_child_nodes(tree):
        scope = top.name if isinstance(top, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef) else ""
        for node in ast.walk(top):
            if isinstance(node, ast.Import):
                found += [(scope, a.name) for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:  # relative: resolve against robointel.io
                    base = ["robointel", "io"][: 2 - (node.level - 1)]
                    found.append((scope, ".".join([*base, *(node.module or "").split(".")]).rstrip(".")))
                else:
                    found.append((scope, node.module or ""))
    return [(s, m) for s, m in found if m.split(".")[0] == "robointel"]


def test_io_source_imports_no_phase():
    files = sorted(IO.rglob("*.py"))
    assert len(files) >= 5
    offending = []
    for f in files:
        for scope, mod in _robointel_imports(ast.parse(f.read_text())):
            part = mod.split(".")[1] if "." in mod else ""
            if part in ABOVE_IO:
                offending.append(f"{f.name}: {mod}" + (f" (inside {scope})" if scope else ""))
    assert not offending, f"io/ imports a phase or above: {offending}"


def test_io_ast_walk_sees_function_level_imports():
    tree = ast.parse("def f():\n    from robointel.planning.scene import Scene\n\nimport robointel.learning as x\n")
    assert _robointel_imports(tree) == [("f", "robointel.planning.scene"), ("", "robointel.learning")]
