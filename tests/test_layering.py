"""The package's layering (DESIGN.md): no import cycles, data flowing one way, and the curated public API.

The import graph is grimp's (``tools/docs_check.py`` builds the same one): every import statement counts,
at module level, inside functions and under ``TYPE_CHECKING``, and ``from package import submodule`` is an
import of the submodule. There is no list of exceptions.
"""
from __future__ import annotations

import importlib
import importlib.util
import subprocess
import sys
from pathlib import Path

import grimp
import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ["robointel", "robointel.io", "robointel.planning", "robointel.teach", "robointel.learning"]
PHASES = ("teach", "learning", "planning")
ABOVE_PHASES = ("skills", "program", "batch", "report", "commands", "cli")
#: DESIGN.md's "data flows one way", top to bottom; a module may import only from its own layer or below
LAYERS = [
    ("cli", "commands", "report", "testing"),
    ("program", "batch"),
    ("skills", "teach", "learning", "planning"),
    ("interface", "sim", "control", "io"),
    ("robot", "geometry", "trajectory"),
    ("outcome", "_validate", "_extras", "_lazy"),
    ("errors",),
]


def _docs_check():
    spec = importlib.util.spec_from_file_location("docs_check", ROOT / "tools" / "docs_check.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def graph():
    return _docs_check().import_graph(ROOT / "src")


def _chains(graph, importer: str, imported: str) -> list[str]:
    chains = graph.find_shortest_chains(importer=f"robointel.{importer}", imported=f"robointel.{imported}",
                                        as_packages=True)
    return [" -> ".join(c) for c in sorted(chains)]


def test_no_import_cycles(graph):
    cycles = _docs_check().import_cycles(graph)
    assert cycles == [], "import cycles:\n" + "\n".join("; ".join(c["imports"]) for c in cycles)


@pytest.mark.parametrize("lower", ["io", "robot"])
def test_io_and_robot_import_no_phase(graph, lower):
    found = [c for upper in PHASES + ABOVE_PHASES for c in _chains(graph, lower, upper)]
    assert found == [], f"robointel.{lower} reaches a phase or above: {found}"


@pytest.mark.parametrize("phase", PHASES)
def test_a_phase_never_imports_the_command(graph, phase):
    found = [c for top in ("cli", "commands") for c in _chains(graph, phase, top)]
    assert found == [], found


def test_skills_sit_above_the_interface(graph):
    assert _chains(graph, "interface", "skills") == []


def test_data_flows_one_way(graph):
    layers = [grimp.Layer(*(f"robointel.{m}" for m in layer), independent=False) for layer in LAYERS]
    illegal = graph.find_illegal_dependencies_for_layers(layers=layers, containers=set())
    found = sorted(f"{d.importer} -> {d.imported}: " + " | ".join(
        " -> ".join([*r.heads, *r.middle, *r.tails]) for r in d.routes) for d in illegal)
    assert found == [], "\n".join(found)


def test_every_layer_module_exists(graph):
    top = {m.split(".")[1] for m in graph.modules if m.count(".") >= 1}
    listed = {m for layer in LAYERS for m in layer}
    assert listed <= top, sorted(listed - top)
    assert top <= listed, f"place these in LAYERS: {sorted(top - listed)}"


def test_the_graph_counts_function_and_type_checking_imports(graph):
    details = graph.get_import_details(importer="robointel.planning.frmp", imported="robointel.sim")
    assert details, "frmp imports the sim inside execute() and under TYPE_CHECKING"


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
