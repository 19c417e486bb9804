"""Print the front door's figures as one JSON object, and fail when one falls short of its target.

Figures and targets:

- ``readme_lines`` (<= 150): lines of ``README.md``.
- ``process_words`` (0): words about how the work was organised (sessions, leads, helpers, branches, issue
  numbers, merge hashes, ...) anywhere in the files git tracks; :data:`PROCESS_WORDS` is the expression, and
  ``process_word_hits`` lists ``path:line: match``. Product words (a Stream Motion or RMI session,
  lead-through, a lead twist, IK branches, pytest's ``scope="session"``) do not match.
- ``import_cycles`` (0): strongly connected groups of modules inside ``src/robointel`` in the import graph
  that grimp builds (every import statement counts: module level, inside functions and under
  ``TYPE_CHECKING``; ``from package import submodule`` is an import of the submodule); ``cycles`` lists
  each with the import lines that close it.
- ``core_dependencies`` (<= 16): ``[project] dependencies`` of ``pyproject.toml``.
- ``mkdocs_strict`` (true): ``mkdocs build --strict`` passes (false when there is no ``mkdocs.yml``).
- ``wheel_quickstart`` (true): the wheel built, installed in a fresh virtual environment outside the
  repository, and the first quickstart ran there (``tools/wheel_check.py``, or its saved report).

Usage: ``python tools/docs_check.py [--json] [--root DIR] [--wheel-report FILE | --skip-wheel]
[--no-mkdocs | --mkdocs-passed]``.
Exit code 0 when every figure meets its target, 1 otherwise.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import re
import subprocess
import sys
import tempfile
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "robointel"

#: how the work was organised, not what the product does
PROCESS_WORDS = re.compile(
    r"\b[Ss]ession[- ][0-9]+"                                   # the word and a number
    r"|\b[Ss]essions [0-9]+"                                    # sessions 20-22
    r"|\b(?:[Tt]his|[Ll]ast|[Pp]revious|[Nn]ext|[Ee]arlier|[Ll]ater|[Oo]ther|[Ee]very|[Aa]ll) sessions?\b"
    r"|\bper-session\b"
    r"|\b[Tt]he lead\b(?![- ](?:through|twist|task|velocity|vector|screw|time|angle|direction|axis))"
    r"|\blead's\b|\bleads' "
    r"|\(helpers?\b|\bhelpers? (?:run|branch|session)s?\b"
    r"|\b[Mm]erged? main\b|\bmerged? (?:tree|code)\b|\b[Tt]he merge\b|\bnot (?:yet )?merged\b"
    r"|\b(?:[Tt]his|[Mm]y|[Oo]ur|[Oo]ther|[Tt]hat|[Ii]ntegration|[Ff]eature) branch(?:es)?\b"
    r"|\bon the branch\b|\bbranch (?:run|alone)\b|\binteg\b"
    r"|\b[Ii]ssues? #?[0-9]+|\b(?:[Tt]his|[Tt]he|[Tt]hat) issue(?:'s)?\b|\bPRs? #?[0-9]+|\bpull request"
    r"|\bcommit [0-9a-f]{7,40}\b|\bmain [0-9a-f]{7,40}\b"
    r"|\bworktrees?\b|\bCEO\b|\bsub-?agents?\b"
    r"|\b(?:another|other|smoothing|docs|packaging|speed|grasp|anyarm|hardening|workflows) engineers?\b"
)
#: a line can match only if it holds one of these (lower case): a fast filter before the expression
_KEYS = ("session", "lead", "helper", "merge", "branch", "integ", "issue", "pr ", "pr#", "prs ", "pull request",
         "commit", "main ", "worktree", "ceo", "agent", "engineer")
#: the files that state the expression (and the test that feeds it examples) are not scanned
PROCESS_WORDS_EXEMPT = ("tools/docs_check.py", "tests/test_docs_check.py")

TARGETS: dict[str, Callable[[Any], bool]] = {
    "readme_lines": lambda v: v is not None and v <= 150,
    "process_words": lambda v: v == 0,
    "import_cycles": lambda v: v == 0,
    "core_dependencies": lambda v: v <= 16,
    "mkdocs_strict": lambda v: v is True,
    "wheel_quickstart": lambda v: v is True,
}


def tracked_files(root: Path) -> list[str]:
    """Paths git tracks in ``root`` plus new files it does not ignore (all files when it is no git tree)."""
    out = subprocess.run(["git", "-C", str(root), "ls-files", "--cached", "--others", "--exclude-standard"],
                         capture_output=True, text=True)
    if out.returncode != 0:
        return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file() and ".git" not in p.parts)
    return sorted({p for p in out.stdout.splitlines() if p and (root / p).is_file()})


def readme_lines(root: Path) -> int | None:
    """Number of lines of ``README.md`` (None when there is none)."""
    readme = root / "README.md"
    return len(readme.read_text(encoding="utf-8").splitlines()) if readme.is_file() else None


def process_words(root: Path) -> list[str]:
    """Every match of :data:`PROCESS_WORDS` in the text files of ``root``, as ``path:line: match``."""
    hits = []
    for rel in tracked_files(root):
        if rel in PROCESS_WORDS_EXEMPT:
            continue
        try:
            text = (root / rel).read_text(encoding="utf-8")
        except (UnicodeDecodeError, OSError):
            continue  # binary files (meshes, HDF5)
        for n, line in enumerate(text.splitlines(), 1):
            low = line.lower()
            if any(k in low for k in _KEYS):
                hits += [f"{rel}:{n}: {m.group(0)}" for m in PROCESS_WORDS.finditer(line)]
    return hits


def import_graph(src: Path, package: str = PACKAGE) -> Any:
    """The import graph (grimp's) of ``package`` as found in ``src``, imports of other packages left out.

    Raises:
        RuntimeError: ``package`` resolves to a copy outside ``src``.
    """
    import grimp

    sys.path.insert(0, str(src))
    try:
        spec = importlib.util.find_spec(package)
        origin = Path(spec.origin).resolve() if spec is not None and spec.origin else None
        if origin is None or not origin.is_relative_to(src.resolve()):
            raise RuntimeError(f"{package} resolves to {origin}, not to the copy in {src}")
        return grimp.build_graph(package, cache_dir=None)
    finally:
        sys.path.remove(str(src))


def import_cycles(graph: Any) -> list[dict[str, Any]]:
    """The import cycles of ``graph``, with the imports that close them.

    A cycle is a strongly connected group of two or more modules (or a module importing itself); its
    imports are those inside the group, as ``importer -> imported (line N)``.

    Returns:
        One ``{"modules": [...], "imports": [...]}`` per group, sorted.
    """
    modules = sorted(graph.modules)
    edges = {m: set(graph.find_modules_directly_imported_by(m)) for m in modules}
    groups = _strongly_connected(modules, edges)
    cycles = []
    for group in groups:
        members = set(group)
        if len(group) == 1 and group[0] not in edges[group[0]]:
            continue
        imports = []
        for a in sorted(members):
            for b in sorted(edges[a] & members):
                lines = sorted({d["line_number"] for d in graph.get_import_details(importer=a, imported=b)})
                imports.append(f"{a} -> {b} (line {', '.join(map(str, lines))})")
        cycles.append({"modules": sorted(members), "imports": imports})
    return sorted(cycles, key=lambda c: c["modules"])


def _strongly_connected(nodes: list[str], edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components (scipy's, on the adjacency matrix)."""
    import numpy as np
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    index = {m: i for i, m in enumerate(nodes)}
    pairs = [(index[a], index[b]) for a in nodes for b in edges[a] if b in index]
    rows, cols = (np.array(x, dtype=np.int64) for x in zip(*pairs)) if pairs else (np.zeros(0, np.int64),) * 2
    adjacency = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(nodes), len(nodes)))
    _, labels = connected_components(adjacency, directed=True, connection="strong")
    groups: dict[int, list[str]] = {}
    for m, lab in zip(nodes, labels):
        groups.setdefault(int(lab), []).append(m)
    return list(groups.values())


def core_dependencies(root: Path) -> list[str]:
    """The ``[project] dependencies`` of ``root/pyproject.toml``."""
    return list(tomllib.loads((root / "pyproject.toml").read_text())["project"].get("dependencies", []))


def mkdocs_strict(root: Path) -> tuple[bool, str]:
    """Whether ``mkdocs build --strict`` passes in ``root``, and why not."""
    if not (root / "mkdocs.yml").is_file():
        return False, "no mkdocs.yml"
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    with tempfile.TemporaryDirectory() as site:
        p = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet", "--site-dir", site],
                           cwd=root, capture_output=True, text=True, env=env)
    tail = (p.stdout + p.stderr).strip().splitlines()[-5:]
    return p.returncode == 0, "passed" if p.returncode == 0 else " | ".join(tail)


def wheel_quickstart(root: Path, report_file: Path | None) -> tuple[bool, dict[str, Any]]:
    """Whether the wheel was built, installed in a fresh environment and ran the first quickstart.

    Args:
        root: the repository.
        report_file: a report ``tools/wheel_check.py --out`` wrote (None: run the check now).

    Returns:
        The figure and the report's summary.
    """
    if report_file is not None:
        if not report_file.is_file():
            return False, {"error": f"no wheel report at {report_file}"}
        report = json.loads(report_file.read_text())
    else:
        p = subprocess.run([sys.executable, str(root / "tools" / "wheel_check.py"), "--root", str(root)],
                           capture_output=True, text=True)
        try:
            report = json.loads(p.stdout)
        except ValueError:
            return False, {"error": (p.stdout + p.stderr).strip()[-400:]}
    summary = {k: report.get(k) for k in ("ok", "wheel", "quickstart", "packages", "venv_mb", "seconds")}
    return bool(report.get("wheel_quickstart")), summary


def figures(root: Path, *, wheel_report: Path | None = None, skip_wheel: bool = False,
            mkdocs: bool | None = True) -> dict[str, Any]:
    """Measure every figure of ``root``.

    Args:
        root: the repository.
        wheel_report: read ``wheel_quickstart`` from this ``tools/wheel_check.py`` report instead of running it.
        skip_wheel: do not check the wheel (``wheel_quickstart`` is then false).
        mkdocs: build the documentation (False: ``mkdocs_strict`` is false; None: it passed already,
            as ``make docs`` before ``make docs-check`` ensures, and is not built again).

    Returns:
        The figures, the details behind them, and ``failing``: the figures that miss their target.
    """
    out: dict[str, Any] = {"readme_lines": readme_lines(root)}
    hits = process_words(root)
    out["process_words"] = len(hits)
    per_file: dict[str, int] = {}
    for h in hits:
        per_file[h.split(":", 1)[0]] = per_file.get(h.split(":", 1)[0], 0) + 1
    out["process_words_per_file"] = per_file
    # files with few hits first (a stray word in the code), then the rest, 200 at most
    out["process_word_hits"] = sorted(hits, key=lambda h: per_file[h.split(":", 1)[0]])[:200]
    cycles = import_cycles(import_graph(root / "src"))
    out["import_cycles"] = len(cycles)
    out["cycles"] = cycles
    deps = core_dependencies(root)
    out["core_dependencies"] = len(deps)
    if mkdocs is None:
        out["mkdocs_strict"], out["mkdocs"] = (root / "mkdocs.yml").is_file(), "passed before (--mkdocs-passed)"
    elif mkdocs:
        out["mkdocs_strict"], out["mkdocs"] = mkdocs_strict(root)
    else:
        out["mkdocs_strict"], out["mkdocs"] = False, "not built (--no-mkdocs)"
    if skip_wheel:
        out["wheel_quickstart"], out["wheel"] = False, {"error": "not checked (--skip-wheel)"}
    else:
        out["wheel_quickstart"], out["wheel"] = wheel_quickstart(root, wheel_report)
    out["failing"] = [k for k, ok in TARGETS.items() if not ok(out[k])]
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the figures (JSON with ``--json``, else one line each).

    Returns:
        0 when every figure meets its target, else 1.
    """
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--root", type=Path, default=ROOT, help="the repository (default: this script's)")
    ap.add_argument("--wheel-report", type=Path, help="the JSON report of an earlier tools/wheel_check.py --out")
    ap.add_argument("--skip-wheel", action="store_true", help="do not build and install the wheel")
    ap.add_argument("--no-mkdocs", action="store_true", help="do not build the documentation")
    ap.add_argument("--mkdocs-passed", action="store_true",
                    help="mkdocs build --strict passed just before (make docs): do not build it again")
    args = ap.parse_args(argv)
    out = figures(args.root.resolve(), wheel_report=args.wheel_report, skip_wheel=args.skip_wheel,
                  mkdocs=None if args.mkdocs_passed else not args.no_mkdocs)
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        for k in TARGETS:
            print(f"{k}: {out[k]}{'' if k not in out['failing'] else '  <- misses its target'}")
    return 1 if out["failing"] else 0


if __name__ == "__main__":
    sys.exit(main())
