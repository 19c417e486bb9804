"""Print one JSON object of code-size and typing figures for ``src/robointel``.

Figures: ``modules`` (count of .py files), ``max_module_lines``, ``modules_over_500`` (paths),
``functions`` and ``typed_fraction`` (the fraction of functions and methods whose parameters, except
``self``/``cls``, and return are all annotated), ``inner_imports`` (imports of the package's own modules
inside a function body, the lazy ones) and ``inner_import_sites`` (``path:line`` of each).

Usage: ``python tools/code_stats.py [ROOT] [--exclude PART ...]`` (ROOT defaults to ``src/robointel``;
files whose path contains an excluded PART are left out).
"""

from __future__ import annotations

import argparse
import ast
import json
from pathlib import Path


def _fully_typed(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """Return whether every parameter (except self/cls) and the return of ``fn`` are annotated."""
    a = fn.args
    params = [*a.posonlyargs, *a.args, *a.kwonlyargs]
    if params and params[0].arg in ("self", "cls"):
        params = params[1:]
    if a.vararg is not None:
        params.append(a.vararg)
    if a.kwarg is not None:
        params.append(a.kwarg)
    return fn.returns is not None and all(p.annotation is not None for p in params)


def _inner_imports(tree: ast.AST, package: str) -> list[int]:
    """Return the line numbers of imports of ``package`` (absolute or relative) inside function bodies."""
    lines: set[int] = set()
    for fn in ast.walk(tree):
        if isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
            for node in ast.walk(fn):
                if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").split(".")[0] == package):
                    lines.add(node.lineno)
                elif isinstance(node, ast.Import) and any(a.name.split(".")[0] == package for a in node.names):
                    lines.add(node.lineno)
    return sorted(lines)


def code_stats(root: Path, exclude: tuple[str, ...] = ()) -> dict[str, object]:
    """Measure the modules under ``root``.

    Args:
        root: Package directory to scan recursively for ``*.py`` files.
        exclude: Files whose path contains any of these substrings are left out.

    Returns:
        A JSON-ready dict with ``modules``, ``max_module_lines``, ``modules_over_500``, ``functions``,
        ``typed_functions``, ``typed_fraction``, ``inner_imports`` and ``inner_import_sites``.
    """
    files = sorted(f for f in root.rglob("*.py") if not any(x in str(f) for x in exclude))
    lines = {str(f): len(f.read_text().splitlines()) for f in files}
    n_fn = n_typed = 0
    inner: list[str] = []
    for f in files:
        tree = ast.parse(f.read_text())
        inner += [f"{f}:{line}" for line in _inner_imports(tree, root.name)]
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n_fn += 1
                n_typed += _fully_typed(node)
    return {
        "modules": len(files),
        "max_module_lines": max(lines.values(), default=0),
        "modules_over_500": sorted(k for k, v in lines.items() if v > 500),
        "functions": n_fn,
        "typed_functions": n_typed,
        "typed_fraction": round(n_typed / n_fn, 4) if n_fn else 1.0,
        "inner_imports": len(inner),
        "inner_import_sites": inner,
    }


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("root", nargs="?", default="src/robointel")
    ap.add_argument("--exclude", nargs="*", default=[])
    args = ap.parse_args()
    print(json.dumps(code_stats(Path(args.root), tuple(args.exclude))))
