"""tools/code_stats.py measures what it says on a package written for the test."""
from __future__ import annotations

import importlib.util
from pathlib import Path

TOOL = Path(__file__).resolve().parents[1] / "tools" / "code_stats.py"


def _tool():
    spec = importlib.util.spec_from_file_location("code_stats", TOOL)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_typed_fraction_sizes_and_inner_imports(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "a.py").write_text(
        "import numpy as np\n"
        "from pkg import b\n\n"
        "def typed(x: int, *args: int, **kw: str) -> int:\n    return x\n\n"
        "def untyped(x):\n    from pkg.b import g\n    import pkg.b\n    return g(x)\n\n"
        "class C:\n    def m(self, y: float) -> float:\n        from . import b\n        return y\n"
        "    def n(self, y) -> None:\n        import numpy\n")
    (pkg / "b.py").write_text("def g(x: int) -> int:\n    return x\n" + "# filler\n" * 600)
    stats = _tool().code_stats(pkg)
    assert stats["functions"] == 5 and stats["typed_functions"] == 3 and stats["typed_fraction"] == 0.6
    assert stats["max_module_lines"] == 602 and stats["modules_over_500"] == [str(pkg / "b.py")]
    # two inside untyped() (one line each), the relative one inside m(); numpy is not the package's own
    assert stats["inner_imports"] == 3
    assert stats["inner_import_sites"] == [f"{pkg / 'a.py'}:8", f"{pkg / 'a.py'}:9", f"{pkg / 'a.py'}:14"]
