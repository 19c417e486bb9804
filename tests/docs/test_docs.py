"""The README and the documentation site: their code runs, their pages are in the site, no process words.

Code blocks in the docs follow one rule: a ``python`` block runs (every block of a page in order, in one
namespace, in a fresh folder), a ``bash`` block holds ``robointel`` commands that run, and a block that
cannot run here carries a title saying so, shown on the rendered page:

- ``title="needs hardware: ..."``: a real controller or sensor; not run (a python block must compile);
- ``title="long run: ..."``: minutes of work (benchmarks, learning runs); each ``robointel`` line is parsed
  against the command (the command, its options and their values must exist), each ``python benchmarks/X.py``
  line must name a benchmark script that takes the options given.

``yaml`` blocks must parse; ``text`` blocks are layouts and outputs, not code. A ``python`` block made only of
``--8<-- "examples/quickstart_*.py"`` includes is a quickstart, run by ``test_quickstarts.py``.
"""
from __future__ import annotations

import importlib.util
import re
import shlex
from pathlib import Path

import pytest
import typer
import yaml
from typer.testing import CliRunner

from robointel.cli import app

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
README = ROOT / "README.md"


def _process_words() -> re.Pattern[str]:
    spec = importlib.util.spec_from_file_location("docs_check", ROOT / "tools" / "docs_check.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.PROCESS_WORDS


#: the house rule on words about how the code was written (tools/docs_check.py's expression, which make test runs)
PROCESS_WORDS = _process_words()
FENCE = re.compile(r"^(?P<indent> *)```(?P<lang>[\w-]*)(?P<info>[^\n]*)\n(?P<body>.*?)^(?P=indent)```", re.M | re.S)
QUICKSTART = re.compile(r"<!-- quickstart: (?P<path>examples/\S+\.py) -->\n```python\n(?P<body>.*?)^```", re.M | re.S)
LANGS = {"python", "bash", "yaml", "text"}
MARKS = ("needs hardware", "long run")
#: commands that serve until Ctrl-C, and the option that ends them (a runnable block must give it)
SERVERS = {"emulator": "--for", "teleop": "--duration", "view": "--for"}


def _blocks(page: Path) -> list[dict[str, str]]:
    """The fenced code blocks of a page: language, title ('' when none) and body (indent removed)."""
    out = []
    for m in FENCE.finditer(page.read_text()):
        title = re.search(r'title="([^"]*)"', m["info"])
        body = "\n".join(line[len(m["indent"]):] for line in m["body"].splitlines())
        out.append({"lang": m["lang"], "title": title[1] if title else "", "body": body})
    return out


def _mark(block: dict[str, str]) -> str:
    """'needs hardware', 'long run' or '' (runs)."""
    return next((m for m in MARKS if block["title"].startswith(m)), "")


def _is_quickstart_include(body: str) -> bool:
    lines = [line for line in body.splitlines() if line.strip()]
    return bool(lines) and all(re.fullmatch(r'--8<-- "examples/quickstart_\w+\.py"', line) for line in lines)


def _pages() -> list[Path]:
    return sorted(p for p in DOCS.rglob("*.md") if "_hooks" not in p.parts)


def _nav_files(nav: object) -> list[str]:
    if isinstance(nav, str):
        return [nav]
    if isinstance(nav, dict):
        return [f for v in nav.values() for f in _nav_files(v)]
    if isinstance(nav, list):
        return [f for v in nav for f in _nav_files(v)]
    return []


def _commands(body: str) -> list[str]:
    """The command lines of a bash block (comments and continuation lines joined)."""
    text = re.sub(r"\\\n\s*", " ", body)
    return [line.split(" #")[0].strip() for line in text.splitlines() if line.strip() and not line.startswith("#")]


# ------------------------------------------------------------------ README
def test_readme_is_a_front_door():
    lines = README.read_text().splitlines()
    assert len(lines) <= 150, f"README.md has {len(lines)} lines; keep it a front door (<= 150)"


def test_readme_quickstarts_are_the_example_files():
    found = {m["path"]: m["body"] for m in QUICKSTART.finditer(README.read_text())}
    assert len(found) == 3, f"expected three quickstarts in README.md, found {sorted(found)}"
    for path, body in found.items():
        assert (ROOT / path).read_text() == body, f"README.md's quickstart differs from {path}: keep them equal"


# ------------------------------------------------------------------ the site
def test_every_page_is_in_the_site_and_every_nav_entry_exists():
    class _Loader(yaml.SafeLoader):
        pass

    _Loader.add_multi_constructor("", lambda loader, suffix, node: None)  # mkdocs' !!python/name tags
    nav = _nav_files(yaml.load((ROOT / "mkdocs.yml").read_text(), Loader=_Loader)["nav"])
    missing = [f for f in nav if not (DOCS / f).is_file()]
    assert not missing, f"mkdocs.yml names pages that do not exist: {missing}"
    orphans = [str(p.relative_to(DOCS)) for p in _pages() if str(p.relative_to(DOCS)) not in nav]
    assert not orphans, f"pages not in mkdocs.yml's nav: {orphans}"


def test_no_words_about_how_the_code_was_written():
    files = [README, ROOT / "CHANGELOG.md", ROOT / "mkdocs.yml", *_pages(), *sorted((ROOT / "examples").iterdir())]
    hits = [f"{f.relative_to(ROOT)}:{n}: {line.strip()[:120]}" for f in files if f.is_file()
            for n, line in enumerate(f.read_text().splitlines(), 1) if PROCESS_WORDS.search(line)]
    assert not hits, "process words in the product's documentation:\n" + "\n".join(hits)


def test_every_code_block_runs_or_says_why_not():
    bad = []
    for page in _pages():
        for b in _blocks(page):
            where = f"{page.relative_to(ROOT)}: {b['lang'] or 'no language'} block {b['body'][:60]!r}"
            if b["lang"] not in LANGS:
                bad.append(f"{where}: use one of {sorted(LANGS)}")
            elif b["lang"] == "bash" and not _mark(b):
                others = [c for c in _commands(b["body"]) if not c.startswith("robointel ")]
                if others:
                    bad.append(f"{where}: a runnable bash block holds robointel commands only, not {others}")
                for c in _commands(b["body"]):
                    words = shlex.split(c)
                    stop = SERVERS.get(words[1] if len(words) > 1 else "")
                    if stop and not any(w.split("=")[0] == stop for w in words):
                        bad.append(f"{where}: {c!r} serves until Ctrl-C: give it {stop} or mark the block 'long run'")
            elif b["lang"] == "yaml":
                yaml.safe_load(b["body"])
            elif b["lang"] == "python" and _mark(b):
                compile(b["body"], where, "exec")  # not run here, but it must be Python
    assert not bad, "\n".join(bad)


def _parse_robointel(line: str) -> None:
    """Resolve ``robointel ...`` to its command; its options must exist and its arguments fit (nothing runs)."""
    args = shlex.split(line)[1:]
    cmd = typer.main.get_command(app)
    prog = ["robointel"]
    while hasattr(cmd, "commands") and args and args[0] in cmd.commands:
        prog.append(args[0])
        cmd = cmd.commands[args.pop(0)]
    assert not hasattr(cmd, "commands"), f"{line!r}: {' '.join(prog)} needs a subcommand"
    names = {o for p in cmd.params for o in (*p.opts, *p.secondary_opts)}
    unknown = [a for a in args if a.startswith("-") and a.split("=")[0] not in names]
    assert not unknown, f"{line!r}: {' '.join(prog)} has no option {unknown}"
    ctx = cmd.make_context(" ".join(prog), args, resilient_parsing=True)  # files need not exist here
    assert not ctx.args, f"{line!r}: unexpected arguments {ctx.args}"


def test_long_runs_name_real_commands_and_options():
    checked = 0
    for page in _pages():
        for b in _blocks(page):
            if b["lang"] != "bash" or _mark(b) != "long run":
                continue
            for line in _commands(b["body"]):
                if line.startswith("robointel "):
                    _parse_robointel(line)
                elif line.startswith("python benchmarks/"):
                    words = shlex.split(line)
                    script = ROOT / words[1]
                    assert script.is_file(), f"{page.name}: {line!r}: no {words[1]}"
                    for opt in (w for w in words[2:] if w.startswith("--")):
                        assert f'"{opt}"' in script.read_text(), f"{page.name}: {line!r}: {script.name} has no {opt}"
                checked += 1
    assert checked > 0


# ------------------------------------------------------------------ the guides' code runs
def _runnable_pages() -> list[Path]:
    return [p for p in _pages() if any(b["lang"] in ("python", "bash") and not _mark(b)
                                       and not _is_quickstart_include(b["body"]) for b in _blocks(p))]


@pytest.mark.parametrize("page", _runnable_pages(), ids=lambda p: str(p.relative_to(DOCS)))
def test_the_code_of_a_page_runs(page, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {"__name__": "__docs__"}
    runner = CliRunner()
    for b in _blocks(page):
        if _mark(b) or _is_quickstart_include(b["body"]):
            continue
        if b["lang"] == "python":
            exec(compile(b["body"], f"{page.name}:{b['body'][:40]!r}", "exec"), namespace)
        elif b["lang"] == "bash":
            for line in _commands(b["body"]):
                res = runner.invoke(app, shlex.split(line)[1:])
                assert res.exit_code == 0, f"{page.name}: {line!r} exited {res.exit_code}:\n{res.output[-2000:]}"
