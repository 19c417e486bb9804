"""What the package promises a user who installs it: a light core, extras that say when they are missing,
a light ``import robointel``, and a wheel that holds every file the code reads."""
from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import textwrap
import tomllib
from importlib.metadata import distribution
from pathlib import Path

import pytest

from robointel import _extras
from robointel.errors import MissingExtra, RobointelError

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def _tool(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "tools" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _dist(requirement: str) -> str:
    name = requirement.split(";")[0].split("[")[0]
    for sep in "<>=!~ ":
        name = name.split(sep)[0]
    return name.strip().lower().replace("_", "-")


def test_core_is_at_most_16_packages_and_every_extra_is_named():
    assert len(PYPROJECT["dependencies"]) <= 16, PYPROJECT["dependencies"]
    extras = PYPROJECT["optional-dependencies"]
    assert set(_extras.EXTRAS) <= set(extras)
    everything = {e.strip() for e in extras["all"][0].split("[", 1)[1].rstrip("]").split(",")}
    assert everything == set(_extras.EXTRAS)


def _import_names(dist: str) -> set[str]:
    """Top-level import names a distribution installs (also those under a ``cmeel.prefix`` site-packages)."""
    names = set()
    for f in distribution(dist).files or []:
        parts = f.parts
        if "site-packages" in parts:
            parts = parts[parts.index("site-packages") + 1:]
        if parts and (f.suffix in (".py", ".so") or len(parts) > 1) and not parts[0].endswith((".dist-info", ".pth")):
            names.add(parts[0].split(".")[0] if len(parts) == 1 else parts[0])
    return names


@pytest.mark.parametrize("extra", sorted(_extras.EXTRAS))
def test_each_extra_brings_the_packages_it_is_named_for(extra):
    """The import names of :data:`robointel._extras.EXTRAS` come from the distributions pyproject lists."""
    provided = set().union(*(_import_names(_dist(r)) for r in PYPROJECT["optional-dependencies"][extra]))
    assert set(_extras.EXTRAS[extra]) <= provided, (extra, sorted(set(_extras.EXTRAS[extra]) - provided))


def test_import_robointel_and_planning_load_neither_mujoco_nor_h5py():
    code = ("import sys, robointel, robointel.planning\n"
            "from robointel import Environment, MotionPlan, MotionSettings, Robot, Trajectory, load_scene, "
            "plan_motion\n"
            "print(sorted(m for m in ('mujoco', 'h5py', 'viser', 'pyarrow', 'airo_fanuc') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr


def test_needs_extra_names_the_extra_and_passes_other_import_errors(monkeypatch):
    monkeypatch.setitem(_extras.EXTRAS, "fake", ("robointel_fake_optional",))
    with pytest.raises(MissingExtra) as err, _extras.needs_extra("fake", "the fake feature"):
        import robointel_fake_optional  # noqa: F401
    assert str(err.value) == ("the fake feature needs the 'fake' extra (robointel_fake_optional is not installed): "
                              "pip install 'robointel[fake]'")
    assert err.value.value == "fake" and isinstance(err.value, RobointelError | ImportError)
    with pytest.raises(ModuleNotFoundError), _extras.needs_extra("fake", "the fake feature"):
        import robointel_other_missing  # noqa: F401
    stand_in = _extras.optional_module("robointel_fake_optional.sub", "fake", "the fake feature")
    with pytest.raises(MissingExtra, match=r"pip install 'robointel\[fake\]'"):
        stand_in.anything  # noqa: B018
    with pytest.raises(MissingExtra, match="robointel_fake_optional"):
        _extras.require_extra("fake", "the fake feature")
    assert _extras.optional_module("json", "fake", "x").dumps([1]) == "[1]"


#: the core install, simulated: every package an extra brings is made unimportable before robointel loads
CORE_ONLY = textwrap.dedent("""
    import importlib.abc, sys
    from robointel._extras import EXTRAS
    BLOCKED = {p for ps in EXTRAS.values() for p in ps}

    class CoreOnly(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in BLOCKED:
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
            return None

    sys.meta_path.insert(0, CoreOnly())
""")


def test_the_core_install_runs_the_command_and_names_missing_extras(tmp_path):
    program = ROOT / "src" / "robointel" / "program" / "examples" / "moves.yaml"
    script = CORE_ONLY + textwrap.dedent(f"""
        import importlib, json
        from typer.testing import CliRunner
        from robointel.cli import app
        for part in ("robot", "geometry", "planning", "sim", "control", "interface", "io", "learning", "teach",
                     "skills", "program", "report", "io.lerobot", "io.mcap_log"):
            importlib.import_module("robointel." + part)
        runner = CliRunner()
        calls = {{"help": ["--help"], "teleop": ["teleop", "--duration", "1"], "batch": ["batch", "kinds"],
                 "fanuc": ["run", {str(program)!r}, "--robot", "fanuc://127.0.0.1", "--report", {str(tmp_path)!r}],
                 "record": ["run", {str(program)!r}, "--record", {str(tmp_path / "r.mcap")!r},
                            "--report", {str(tmp_path)!r}],
                 "lerobot": ["dataset", "export", "guidance:1", "--out", {str(tmp_path / "ds")!r}]}}
        out = {{}}
        for name, args in calls.items():
            r = runner.invoke(app, args)
            out[name] = [r.exit_code, [ln for ln in r.output.splitlines() if ln.startswith("error:")]]
        print(json.dumps(out))
    """)
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    out = json.loads(p.stdout.strip().splitlines()[-1])
    assert out.pop("help")[0] == 0
    want = {"teleop": "teleop", "batch": "batch", "fanuc": "fanuc", "record": "datasets", "lerobot": "datasets"}
    for name, (code, errors) in out.items():
        assert code == 2 and len(errors) == 1, (name, code, errors)
        assert errors[0].endswith(f"pip install 'robointel[{want[name]}]'"), (name, errors)


def test_the_wheel_holds_exactly_the_package_files(tmp_path):
    """Built from the tracked files as CI builds it (CI goes through the sdist too); compared file by file."""
    wc = _tool("wheel_check")
    step, wheel = wc.build(ROOT, tmp_path, sdist=False)
    assert wheel is not None, step["tail"]
    expected = wc.package_files(wc.tracked_files(ROOT))
    # the folders and scripts the code reads at run time, as the code names them
    from robointel.interface.sim_stream import _SCRIPT
    from robointel.planning.scene import SCENES
    from robointel.program.format import EXAMPLES
    from robointel.robot.catalogue import DESCRIPTIONS

    src = ROOT / "src"
    read = {p for d in (DESCRIPTIONS, SCENES, EXAMPLES) for p in Path(d).rglob("*") if p.is_file()} | {Path(_SCRIPT)}
    read = {p.resolve().relative_to(src).as_posix() for p in read if "__pycache__" not in p.parts}
    assert len(read) >= 9 and read <= expected, sorted(read - expected)
    found = wc.wheel_contents(wheel, expected)
    assert found["missing"] == [] and found["unexpected"] == [], found
    assert len(found["core_requires"]) == len(PYPROJECT["dependencies"])
    assert set(_extras.EXTRAS) <= set(found["extras"]) and found["console_scripts"] == ["robointel"]


def test_demo_runs_the_chosen_stages_and_skips_one_whose_extra_is_missing(tmp_path):
    from typer.testing import CliRunner

    from robointel.cli import app
    from robointel.report.demo import StageResult, run_demo

    bad = CliRunner().invoke(app, ["demo", "--quick", "--stages", "core,nope", "--out", str(tmp_path / "x")])
    assert bad.exit_code == 2 and "unknown demo stage 'nope'" in bad.output and "planning" in bad.output

    def needs_teleop(ctx):
        raise _extras.missing_extra("teleop", "the teleoperation stage", "viser")

    def runs(ctx):
        return StageResult(title="runs", text="ran")

    page = run_demo([needs_teleop, runs], tmp_path / "report", quick=True).read_text()
    assert "skipped: the teleoperation stage needs the &#x27;teleop&#x27; extra" in page and "ran" in page


def test_wheel_contents_finds_missing_and_unexpected_files(tmp_path):
    import zipfile

    wheel = tmp_path / "robointel-0.1.0-py3-none-any.whl"
    with zipfile.ZipFile(wheel, "w") as z:
        for name in ("robointel/__init__.py", "robointel/robot/model.py", "robointel/stray.txt"):
            z.writestr(name, "")
        z.writestr("robointel-0.1.0.dist-info/METADATA",
                   "Name: robointel\nRequires-Dist: numpy>=1.26\nRequires-Dist: viser>=0.2; extra == \"teleop\"\n"
                   "Provides-Extra: teleop\n")
        z.writestr("robointel-0.1.0.dist-info/entry_points.txt", "[console_scripts]\nrobointel = robointel.cli:app\n")
    expected = {"robointel/__init__.py", "robointel/robot/model.py", "robointel/robot/descriptions/arm.urdf"}
    found = _tool("wheel_check").wheel_contents(wheel, expected)
    assert found["missing"] == ["robointel/robot/descriptions/arm.urdf"]
    assert found["unexpected"] == ["robointel/stray.txt"]
    assert found["core_requires"] == ["numpy>=1.26"] and found["extras"] == ["teleop"]
    assert found["console_scripts"] == ["robointel"] and found["files"] == 3
