"""tools/docs_check.py measures what it says, on a small repository written for the test."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TOOL = ROOT / "tools" / "docs_check.py"

#: how work was organised: each line must match once
PROCESS_LINES = [
    "Measured in sess" "ion 27.",  # split: the repository itself stays clean
    "figures of the merged tree",
    "this session moved the solver",
    "the le" "ad's run at load 6",
    "ask the le" "ad before merging",
    "loaded runs (helpers, docs)",
    "a hel" "per run of the suite",
    "figures as of mer" "ged main 8e37550",
    "see Iss" "ue #12",
    "iss" "ue 13, item 4",
    "on this branch alone",
    "not the issue's reading",
    "fixed in commit 7e8afbe",
    "each worktree has its venv",
    "the docs engineer writes it",
]
#: what the product does: none may match
PRODUCT_LINES = [
    "Close the Stream Motion session and bring a new one up.",
    "ConnectionLost: the RMI session is down.",
    "lead-through teaching with the F/T sensor",
    "V_lead is the leading twist of the reading",
    "closed-form IK (all branches)",
    "the branch continuous with the last",
    '@pytest.fixture(scope="session")',
    "per session the packets before it",
    "one emulator session each",
    "Timing helper shared by the benchmark scripts",
    "Rotation helpers: thin wrappers",
    "clouds (merged into one gridded cloud)",
    "the leading edge of the pulse",
]


def _repo(tmp: Path, *, readme: int, deps: int, cycle: bool) -> Path:
    """A git repository with a README, a pyproject, a text file and a ``robointel`` package."""
    (tmp / "README.md").write_text("line\n" * readme)
    listed = ",\n".join(f'  "dep{i}>=1"' for i in range(deps))
    (tmp / "pyproject.toml").write_text(f'[project]\nname = "robointel"\ndependencies = [\n{listed}\n]\n')
    (tmp / "notes.txt").write_text("\n".join(PROCESS_LINES + PRODUCT_LINES) + "\n")
    pkg = tmp / "src" / "robointel"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from robointel.sub import b\n")  # the submodule, not the package
    # the way back: inside a function (a) and under TYPE_CHECKING (c -> b -> c)
    back = "def f():\n    from robointel import a\n" if cycle else ""
    (pkg / "sub" / "b.py").write_text("from robointel.sub import c\n" + back)
    (pkg / "sub" / "c.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from robointel.sub import b\n" if cycle else "")
    subprocess.run(["git", "init", "-q", str(tmp)], check=True)
    subprocess.run(["git", "-C", str(tmp), "add", "-A"], check=True)
    return tmp


def _check(root: Path, *extra: str) -> tuple[int, dict]:
    p = subprocess.run([sys.executable, str(TOOL), "--json", "--root", str(root), "--no-mkdocs", *extra],
                       capture_output=True, text=True, cwd=root)
    return p.returncode, json.loads(p.stdout)


def test_figures_of_a_repository_that_misses_every_target(tmp_path):
    rc, out = _check(_repo(tmp_path, readme=151, deps=17, cycle=True), "--skip-wheel")
    assert rc == 1
    assert out["readme_lines"] == 151 and out["core_dependencies"] == 17
    hits = [h.split(": ", 1)[1] for h in out["process_word_hits"]]
    assert out["process_words"] == len(PROCESS_LINES) == len(hits), hits
    assert all(h.startswith("notes.txt:") for h in out["process_word_hits"])
    lines = {int(h.split(":")[1]) for h in out["process_word_hits"]}
    assert lines == set(range(1, len(PROCESS_LINES) + 1)), "a product line matched, or a process line did not"
    assert out["import_cycles"] == 1
    assert out["cycles"][0]["modules"] == ["robointel.a", "robointel.sub.b", "robointel.sub.c"]
    assert "robointel.sub.c -> robointel.sub.b (line 3)" in out["cycles"][0]["imports"]
    assert out["mkdocs_strict"] is False and out["wheel_quickstart"] is False
    assert out["failing"] == ["readme_lines", "process_words", "import_cycles", "core_dependencies",
                              "mkdocs_strict", "wheel_quickstart"]


def test_figures_of_a_repository_that_meets_them(tmp_path):
    root = _repo(tmp_path, readme=150, deps=16, cycle=False)
    (root / "notes.txt").write_text("\n".join(PRODUCT_LINES) + "\n")
    report = tmp_path.parent / f"{tmp_path.name}-wheel.json"
    report.write_text(json.dumps({"ok": True, "wheel_quickstart": True, "wheel": "robointel-0.1.0-py3-none-any.whl"}))
    rc, out = _check(root, "--wheel-report", str(report))
    assert (out["readme_lines"], out["process_words"], out["import_cycles"], out["core_dependencies"]) == (
        150, 0, 0, 16)
    assert out["wheel_quickstart"] is True and out["wheel"]["wheel"] == "robointel-0.1.0-py3-none-any.whl"
    assert out["failing"] == ["mkdocs_strict"] and rc == 1  # no mkdocs.yml here
