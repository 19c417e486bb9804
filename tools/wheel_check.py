"""Build robointel's wheel, install it in a fresh virtual environment outside the repository, and use it there.

Steps (each timed; the JSON printed at the end holds them all, ``ok`` is true when every one passed):

1. ``build``: the sdist, then the wheel from the sdist (``python -m build``), from a copy of the files git
   tracks (plus new ones not ignored): what a clean clone builds.
2. ``contents``: the wheel holds exactly the package's files (every module, robot description, scene,
   program and skill file under ``src/robointel``), no more, no fewer; its metadata lists the core
   dependencies and the ``robointel`` command.
3. ``venv`` and ``install``: ``python -m venv`` in a temporary folder, then ``pip install WHEEL[EXTRAS]``
   from the package registries pip is set up for (pip's own cache is reused); the number of packages and
   the size of the environment are reported.
4. ``smoke``: ``tools/wheel_smoke.py`` with that environment's interpreter, from a folder outside the
   repository, with no ``PYTHONPATH``: every packaged file loads, ``robointel`` comes from the
   environment, and a motion is planned for an arm from its URDF around a box.
5. ``quickstart``: ``examples/quickstart_plan.py`` (the README's first quickstart) run the same way, from a
   copy of ``examples/``, when the repository has it.
6. ``demo``: ``robointel demo --quick --stages STAGES`` with the environment's command.

Usage: ``python tools/wheel_check.py [--extras fanuc,teleop] [--stages core,planning] [--out FILE] [--keep]``.
Exit code 0 when ``ok``, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
import zipfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "robointel"
QUICKSTART = Path("examples") / "quickstart_plan.py"
#: what the build reads besides the package source
BUILD_FILES = ("pyproject.toml", "README.md", "LICENSE", "LICENSE.txt", "MANIFEST.in", "setup.cfg")


def tracked_files(root: Path) -> list[str]:
    """Paths (relative, POSIX) that git tracks in ``root``, plus new files it does not ignore.

    Raises:
        RuntimeError: ``root`` is not a git work tree.
    """
    out = subprocess.run(["git", "-C", str(root), "ls-files", "--cached", "--others", "--exclude-standard"],
                         capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{root} is not a git work tree: {out.stderr.strip()}")
    return sorted({p for p in out.stdout.splitlines() if p and (root / p).is_file()})


def package_files(files: list[str], package: str = PACKAGE) -> set[str]:
    """The package's files as a wheel names them (``robointel/...``), from the repository's ``src/`` paths."""
    prefix = f"src/{package}/"
    return {p[len("src/"):] for p in files if p.startswith(prefix) and "__pycache__" not in p
            and not p.endswith(".pyc")}


def wheel_contents(wheel: Path, expected: set[str]) -> dict[str, Any]:
    """Compare a wheel's files with ``expected`` and read its core requirements and commands.

    Args:
        wheel: the ``.whl`` file.
        expected: the package files it must hold (wheel names, e.g. ``robointel/robot/model.py``).

    Returns:
        ``files`` (count), ``missing`` and ``unexpected`` (sorted names), ``core_requires`` (the
        ``Requires-Dist`` entries without an extra marker), ``extras`` and ``console_scripts``.
    """
    with zipfile.ZipFile(wheel) as z:
        names = [n for n in z.namelist() if not n.endswith("/")]
        info = [n for n in names if n.split("/")[0].endswith(".dist-info")]
        meta_name = next(n for n in info if n.endswith("/METADATA"))
        meta = z.read(meta_name).decode()
        entry = next((z.read(n).decode() for n in info if n.endswith("/entry_points.txt")), "")
    inside = {n for n in names if n not in info}
    requires = [line.split(":", 1)[1].strip() for line in meta.splitlines() if line.startswith("Requires-Dist:")]
    extras = [line.split(":", 1)[1].strip() for line in meta.splitlines() if line.startswith("Provides-Extra:")]
    scripts = [line.split("=")[0].strip() for line in entry.split("[console_scripts]")[-1].splitlines()
               if "=" in line] if "[console_scripts]" in entry else []
    return {"files": len(inside), "missing": sorted(expected - inside), "unexpected": sorted(inside - expected),
            "core_requires": [r for r in requires if "extra ==" not in r], "extras": extras,
            "console_scripts": scripts}


def core_dependencies(root: Path) -> list[str]:
    """The ``[project] dependencies`` of ``root/pyproject.toml``."""
    return list(tomllib.loads((root / "pyproject.toml").read_text())["project"].get("dependencies", []))


def _run(name: str, cmd: list[str], *, cwd: Path, env: dict[str, str] | None = None,
         timeout: float = 1800.0) -> dict[str, Any]:
    """Run one step; return its name, command, exit code, seconds and the last lines of its output."""
    print(f"wheel_check: {name}: {' '.join(cmd)}", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
        rc, text = p.returncode, p.stdout + p.stderr
    except subprocess.TimeoutExpired as exc:
        rc, text = -1, f"timed out after {timeout:.0f} s: {exc}"
    seconds = time.perf_counter() - t0
    print(f"wheel_check: {name}: rc {rc}, {seconds:.1f} s", file=sys.stderr, flush=True)
    return {"name": name, "cmd": cmd, "rc": rc, "seconds": round(seconds, 2), "ok": rc == 0,
            "tail": text.strip().splitlines()[-12:]}


def build(root: Path, work: Path, *, sdist: bool = True) -> tuple[dict[str, Any], Path | None]:
    """Copy the build's inputs out of ``root`` and build the sdist and, from it, the wheel into ``work/dist``.

    Args:
        root: the repository.
        work: the folder to build in.
        sdist: build the sdist first and the wheel from it (False: the wheel straight from the copy).

    Returns:
        The step record and the wheel's path (None when the build failed).
    """
    src = work / "source"
    for rel in tracked_files(root):
        if rel.startswith(f"src/{PACKAGE}/") or rel in BUILD_FILES:
            (src / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(root / rel, src / rel)
    only = [] if sdist else ["--wheel"]
    step = _run("build", [sys.executable, "-m", "build", *only, "--outdir", str(work / "dist"), str(src)], cwd=work)
    wheels = sorted((work / "dist").glob("*.whl"))
    return step, (wheels[0] if step["ok"] and wheels else None)


def clean_env(venv: Path) -> dict[str, str]:
    """The environment a user of the installed package has: the venv's ``bin`` first, no ``PYTHONPATH``."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["VIRTUAL_ENV"] = str(venv)
    env.setdefault("MPLBACKEND", "Agg")
    return env


def _size_mb(path: Path) -> float:
    return round(sum(f.stat().st_size for f in path.rglob("*") if f.is_file() and not f.is_symlink()) / 2**20, 1)


def check(root: Path, work: Path, *, extras: str = "", stages: str = "core,planning") -> dict[str, Any]:
    """Run every step in ``work`` (a folder outside ``root``) and collect the results.

    Args:
        root: the repository.
        work: an empty folder outside it.
        extras: comma-separated extras to install with the wheel ("" for the core only).
        stages: the ``robointel demo --quick`` stages to run.

    Returns:
        The report: ``ok``, ``steps``, ``contents``, ``packages``, ``venv_mb``, ``quickstart`` and
        ``wheel_quickstart`` (built, installed, and the first quickstart ran).
    """
    report: dict[str, Any] = {"root": str(root), "work": str(work), "extras": extras, "steps": []}
    steps: list[dict[str, Any]] = report["steps"]
    step, wheel = build(root, work)
    steps.append(step)
    if wheel is None:
        return _finish(report)
    report["wheel"] = wheel.name
    contents = wheel_contents(wheel, package_files(tracked_files(root)))
    report["contents"] = contents
    ok = (not contents["missing"] and not contents["unexpected"] and PACKAGE in contents["console_scripts"]
          and len(contents["core_requires"]) == len(core_dependencies(root)))
    steps.append({"name": "contents", "ok": ok, "rc": 0 if ok else 1, "seconds": 0.0})
    venv = work / "venv"
    steps.append(_run("venv", [sys.executable, "-m", "venv", str(venv)], cwd=work))
    py = str(venv / "bin" / "python")
    env = clean_env(venv)
    target = f"{wheel}[{extras}]" if extras else str(wheel)
    steps.append(_run("install", [py, "-m", "pip", "install", "--disable-pip-version-check", target],
                      cwd=work, env=env))
    if not steps[-1]["ok"]:
        return _finish(report)
    listed = subprocess.run([py, "-m", "pip", "list", "--format=json"], capture_output=True, text=True, env=env)
    report["packages"] = len(json.loads(listed.stdout or "[]"))
    report["venv_mb"] = _size_mb(venv)
    run = work / "run"
    run.mkdir()
    shutil.copy2(Path(__file__).with_name("wheel_smoke.py"), run / "wheel_smoke.py")
    smoke = _run("smoke", [py, "wheel_smoke.py"], cwd=run, env=env)
    try:
        found = json.loads(smoke["tail"][-1])
        smoke["result"] = found
        inside = Path(found["robointel_file"]).resolve().is_relative_to(venv.resolve())
        smoke["ok"] = smoke["ok"] and inside and found["plan"]["straight_line_clearance_m"] < 0
    except (ValueError, KeyError, IndexError):
        smoke["ok"] = False
    steps.append(smoke)
    if (root / QUICKSTART).is_file():  # with the examples beside it, as a user who copied the folder has them
        shutil.copytree(root / QUICKSTART.parent, run / QUICKSTART.parent)
        steps.append(_run("quickstart", [py, str(QUICKSTART)], cwd=run, env=env))
        report["quickstart"] = str(QUICKSTART)
    else:
        report["quickstart"] = f"the motion of tools/wheel_smoke.py ({QUICKSTART} not found)"
    demo = _run("demo", [str(venv / "bin" / PACKAGE), "demo", "--quick", "--stages", stages, "--out",
                         str(run / "report")], cwd=run, env=env)
    demo["ok"] = demo["ok"] and (run / "report" / "index.html").is_file()
    steps.append(demo)
    return _finish(report)


def _finish(report: dict[str, Any]) -> dict[str, Any]:
    steps = {s["name"]: s for s in report["steps"]}
    report["ok"] = all(s["ok"] for s in report["steps"]) and "demo" in steps
    ran = steps.get("quickstart", steps.get("smoke"))
    report["wheel_quickstart"] = bool(steps.get("install", {}).get("ok") and ran is not None and ran["ok"])
    report["seconds"] = {s["name"]: s["seconds"] for s in report["steps"]}
    return report


def main(argv: list[str] | None = None) -> int:
    """Parse the arguments, run :func:`check` in a temporary folder, print the JSON report.

    Returns:
        0 when every step passed, else 1.
    """
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", type=Path, default=ROOT, help="the repository (default: this script's)")
    ap.add_argument("--extras", default="", help="extras installed with the wheel, comma-separated (default: none)")
    ap.add_argument("--stages", default="core,planning", help="robointel demo --quick stages")
    ap.add_argument("--out", type=Path, help="also write the JSON report here")
    ap.add_argument("--keep", action="store_true", help="keep the temporary folder (its path is in the report)")
    args = ap.parse_args(argv)
    root = args.root.resolve()
    work = Path(tempfile.mkdtemp(prefix="robointel-wheel-"))
    if work.resolve().is_relative_to(root):
        raise SystemExit(f"the temporary folder {work} is inside the repository {root}: set TMPDIR elsewhere")
    t0 = time.perf_counter()
    try:
        report = check(root, work, extras=args.extras, stages=args.stages)
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    report["total_s"] = round(time.perf_counter() - t0, 1)
    text = json.dumps(report, indent=1)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + "\n")
    print(text)
    return 0 if report["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
