"""Bad input for every ``robointel`` command: garbage numbers, foreign files, malformed programs and data.

The cases cover missing, empty, binary and foreign files, malformed programs, scenes, sweeps and
datasets, unknown names and numbers out of range.

Each case is ``(name, argv)``; :func:`cli_cases` writes the files it needs into a folder. A command
meets its contract on a case when it exits with code 2 and one ``error:`` line (no traceback, no
work started); :func:`judge` says so of one run's output.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import yaml

__all__ = ["Verdict", "cli_cases", "judge"]


@dataclass(frozen=True)
class Verdict:
    """How a command answered one bad-input case.

    Attributes:
        traceback: a Python traceback (or another raw exception) reached the user.
        refused: exit code 2 with an ``error:`` line (or the program refusal of ``robointel run``).
        one_line: the refusal is one line.
    """

    traceback: bool
    refused: bool
    one_line: bool


def judge(returncode: int, output: str) -> Verdict:
    """Classify a command's answer to a bad input from its exit code and its stdout + stderr."""
    lines = [ln for ln in output.splitlines() if ln.strip()]
    at = [i for i, ln in enumerate(lines) if ln.startswith(("error:", "refused before moving:"))]
    refused = returncode == 2 and bool(at)
    return Verdict("Traceback (most recent call last)" in output, refused,
                   refused and len(at) == 1 and at[0] == len(lines) - 1)


def _write(folder: Path, name: str, content: str | bytes) -> str:
    p = folder / name
    if isinstance(content, bytes):
        p.write_bytes(content)
    else:
        p.write_text(content)
    return str(p)


def _programs(folder: Path) -> list[tuple[str, str]]:
    base = {"format": "robointel.program/1", "name": "p", "scene": "table71",
            "waypoints": {"a": {"q_deg": [0, 10, -20, 0, -60, 0]}},
            "steps": [{"move": "a"}, {"wait": 0.1}]}
    edits = {
        "unknown step kind": lambda d: d["steps"].append({"fly": 1}),
        "set_io gripper 5": lambda d: d["steps"].append({"set_io": {"gripper": 5}}),
        "set_io value nan": lambda d: d["steps"].append({"set_io": {"lamp": math.nan}}),
        "move to an unknown waypoint": lambda d: d["steps"].append({"move": "nowhere"}),
        "wait -1": lambda d: d["steps"].append({"wait": -1}),
        "wait a string": lambda d: d["steps"].append({"wait": "long"}),
        "q_deg of 5 values": lambda d: d["waypoints"].__setitem__("b", {"q_deg": [0, 0, 0, 0, 0]}),
        "q_deg with 1e400": lambda d: d["waypoints"].__setitem__("b", {"q_deg": [0, 0, 0, 0, 0, "1e400"]}),
        "no steps": lambda d: d.__setitem__("steps", []),
        "steps a mapping": lambda d: d.__setitem__("steps", {"a": 1}),
        "no scene": lambda d: d.pop("scene"),
        "unknown scene": lambda d: d.__setitem__("scene", "nosuchscene"),
        "unknown format": lambda d: d.__setitem__("format", "robointel.program/9"),
        "unknown key": lambda d: d.__setitem__("speed", 3),
        "grasp an unknown category": lambda d: d["steps"].append({"grasp": {"category": "dragon"}}),
        "place at nan": lambda d: d["steps"].append({"place": {"at": [math.nan, 0.1]}}),
        "insert without its skill file": lambda d: d["steps"].append({"insert": {"skill": "none.skill.h5"}}),
        "objects a string": lambda d: d.__setitem__("objects", "cup"),
        "duplicate step names": lambda d: d.__setitem__("steps", [{"move": "a", "name": "x"},
                                                                  {"wait": 1, "name": "x"}]),
        "path speed 0": lambda d: d["steps"].append({"path": {"points": [[0.4, 0, 0.3], [0.4, 0.1, 0.3]],
                                                              "speed": 0}}),
    }
    out = []
    for k, (case, edit) in enumerate(edits.items()):
        d = json.loads(json.dumps(base))
        edit(d)
        out.append((f"run: {case}", _write(folder, f"program_{k:02d}.yaml", yaml.safe_dump(d))))
    return out


def _scenes(folder: Path) -> list[tuple[str, str]]:
    from robointel.planning.scene import SCENES

    base = yaml.safe_load((SCENES / "table71.yaml").read_text())
    edits = {
        "steps a string": lambda d: d.__setitem__("steps", "abc"),
        "a waypoint pose 5": lambda d: d["waypoints"].__setitem__(1, {"name": "pick", "pose": 5}),
        "limits a list": lambda d: d.__setitem__("limits", [1, 2]),
        "d_min 10**400": lambda d: d.__setitem__("d_min", int("1" + "0" * 400)),
        "one waypoint": lambda d: d.__setitem__("waypoints", d["waypoints"][:1]),
        "unknown robot": lambda d: d.__setitem__("robot", "nosuchrobot"),
        "obstacles a mapping": lambda d: d.__setitem__("obstacles", {"a": 1}),
        "an obstacle of unknown type": lambda d: d.__setitem__("obstacles", [{"type": "torus"}]),
        "negative velocity scale": lambda d: d.__setitem__("limits", {"velocity_scale": -1}),
        "dt nan": lambda d: d.__setitem__("dt", math.nan),
    }
    out = []
    for k, (case, edit) in enumerate(edits.items()):
        d = json.loads(json.dumps(base, default=str))
        edit(d)
        out.append((f"plan: {case}", _write(folder, f"scene_{k:02d}.yaml", yaml.safe_dump(d))))
    return out


def _sweeps(folder: Path) -> list[tuple[str, str]]:
    docs = {
        "a YAML list": "- 1\n- 2\n",
        "an unknown trial kind": "tasks:\n  - kind: nosuchkind\n    seeds: [0, 1]\n",
        "seeds a string": "tasks:\n  - kind: insertion\n    seeds: many\n",
        "no tasks": "name: x\n",
        "not YAML": "tasks: [\n  - : :\n",
    }
    return [(f"batch run: {case}", _write(folder, f"sweep_{k:02d}.yaml", text))
            for k, (case, text) in enumerate(docs.items())]


def cli_cases(folder: str | Path) -> list[tuple[str, list[str]]]:
    """Write the files of the bad-input cases into ``folder``; return ``(name, argv)`` for each (>= 100).

    Args:
        folder: an empty or new folder (created).

    Returns:
        The cases; ``argv`` is what follows ``robointel``.
    """
    from robointel.testing.corrupt_data import corrupt_lerobot, corrupt_robomimic

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    blob = os.urandom(4096)
    binary = {ext: _write(folder, f"blob.{ext}", blob) for ext in ("yaml", "h5", "hdf5", "json", "csv", "bvh", "npz",
                                                                    "urdf", "mcap")}
    empty = _write(folder, "empty.yaml", "")
    alist = _write(folder, "list.yaml", "- 1\n- 2\n")
    missing = str(folder / "does-not-exist.yaml")
    out_dir = str(folder / "out")
    no_dir = str(folder / "no-such-folder" / "x.mcap")
    cases: list[tuple[str, list[str]]] = [
        # numbers
        ("grasp trial --n -1", ["grasp", "trial", "--n", "-1"]),
        ("grasp trial --n 0", ["grasp", "trial", "--n", "0"]),
        ("grasp trial --n abc", ["grasp", "trial", "--n", "abc"]),
        ("grasp trial --seed -1", ["grasp", "trial", "--seed", "-1"]),
        ("grasp trial --category nosuch", ["grasp", "trial", "--category", "nosuch", "--n", "1"]),
        ("grasp classify --category nosuch", ["grasp", "classify", "--category", "nosuch"]),
        ("grasp classify --source nosuch", ["grasp", "classify", "--source", "nosuch"]),
        ("grasp transfer --db binary", ["grasp", "transfer", "--db", binary["h5"], "--out", out_dir + ".png"]),
        ("grasp execute --category nosuch", ["grasp", "execute", "--category", "nosuch"]),
        ("grasp execute --robot bogus", ["grasp", "execute", "--robot", "bogus://x"]),
        ("skill insert --time-limit nan", ["skill", "insert", "--time-limit", "nan"]),
        ("skill insert --time-limit -1", ["skill", "insert", "--time-limit", "-1"]),
        ("skill insert --time-limit inf", ["skill", "insert", "--time-limit", "inf"]),
        ("skill insert --clearance 0", ["skill", "insert", "--clearance", "0"]),
        ("skill insert --clearance nan", ["skill", "insert", "--clearance", "nan"]),
        ("skill insert --stall-ms -5", ["skill", "insert", "--stall-ms", "-5"]),
        ("skill insert --trials 0", ["skill", "insert", "--trials", "0"]),
        ("skill insert --demos 0", ["skill", "insert", "--demos", "0"]),
        ("skill insert --wrench bogus", ["skill", "insert", "--wrench", "bogus"]),
        ("skill insert --robot bogus", ["skill", "insert", "--robot", "bogus://"]),
        ("skill grind --stall-ms -5", ["skill", "grind", "--stall-ms", "-5"]),
        ("skill grind --speed 0", ["skill", "grind", "--speed", "0"]),
        ("skill grind --speed nan", ["skill", "grind", "--speed", "nan"]),
        ("skill grind --demos 0", ["skill", "grind", "--demos", "0"]),
        ("learn insertion --demos 0", ["learn", "insertion", "--demos", "0"]),
        ("learn insertion --trials -3", ["learn", "insertion", "--trials", "-3"]),
        ("learn insertion --labelled 0", ["learn", "insertion", "--labelled", "0"]),
        ("learn insertion --seed -1", ["learn", "insertion", "--seed", "-1"]),
        ("learn insertion --save binary", ["learn", "insertion", "--save", binary["h5"]]),
        ("learn grinding --demos 0", ["learn", "grinding", "--demos", "0"]),
        ("guide --scenario 7", ["guide", "--scenario", "7"]),
        ("guide --duration -1", ["guide", "--duration", "-1"]),
        ("guide --duration nan", ["guide", "--duration", "nan"]),
        ("guide --method bogus", ["guide", "--method", "bogus"]),
        ("guide --robot bogus", ["guide", "--robot", "bogus://"]),
        ("keypoints --tolerance 0", ["keypoints", "--tolerance", "0"]),
        ("keypoints --speed -1", ["keypoints", "--speed", "-1"]),
        ("keypoints --scenario 0", ["keypoints", "--scenario", "0"]),
        ("keypoints --duration nan", ["keypoints", "--duration", "nan"]),
        ("imitate --latency -5", ["imitate", "synthetic", "--scara", "--latency", "-5", "--out", out_dir]),
        ("imitate --latency nan", ["imitate", "synthetic", "--latency", "nan", "--out", out_dir]),
        ("imitate a missing recording", ["imitate", missing, "--out", out_dir]),
        ("imitate a binary .csv", ["imitate", binary["csv"], "--out", out_dir]),
        ("imitate a binary .bvh", ["imitate", binary["bvh"], "--out", out_dir]),
        ("imitate --record in a missing folder", ["imitate", "synthetic", "--record", no_dir, "--out", out_dir]),
        ("teleop --port 0", ["teleop", "--port", "0"]),
        ("teleop --port 99999", ["teleop", "--port", "99999"]),
        ("teleop --stream-port -1", ["teleop", "--stream-port", "-1"]),
        ("teleop --duration -1", ["teleop", "--duration", "-1"]),
        ("teleop --duration nan", ["teleop", "--duration", "nan"]),
        ("teleop --host 0.0.0.0 without token", ["teleop", "--host", "0.0.0.0", "--duration", "0.1"]),
        ("teleop a short token", ["teleop", "--host", "0.0.0.0", "--token", "short", "--duration", "0.1"]),
        ("teleop --record not .mcap", ["teleop", "--record", str(folder / "x.txt"), "--duration", "0.1"]),
        ("teleop --record in a missing folder", ["teleop", "--record", no_dir, "--duration", "0.1"]),
        ("teleop --robot bogus", ["teleop", "--robot", "bogus://x", "--duration", "0.1"]),
        ("jog no axis", ["jog", "--by", "5"]),
        ("jog no increment", ["jog", "--joint", "1"]),
        ("jog --joint 9", ["jog", "--joint", "9", "--by", "5"]),
        ("jog --axis w", ["jog", "--axis", "w", "--by", "5"]),
        ("jog --frame bogus", ["jog", "--axis", "x", "--frame", "bogus", "--by", "5"]),
        ("jog --by nan", ["jog", "--joint", "1", "--by", "nan"]),
        ("jog --speed 0", ["jog", "--joint", "1", "--by", "5", "--speed", "0"]),
        ("jog --hold -1", ["jog", "--joint", "1", "--hold", "-1"]),
        ("jog --server bogus", ["jog", "--joint", "1", "--by", "5", "--server", "http://x"]),
        ("jog --by beyond the limit", ["jog", "--joint", "1", "--by", "400"]),
        ("run a missing program", ["run", missing]),
        ("run a binary program", ["run", binary["yaml"]]),
        ("run an empty program", ["run", empty]),
        ("run a YAML list", ["run", alist]),
        ("run --from 99", ["run", "moves", "--from", "99", "--check"]),
        ("run --from nosuch", ["run", "moves", "--from", "nosuch", "--check"]),
        ("run --seed -1", ["run", "moves", "--seed", "-1"]),
        ("run --record not .mcap", ["run", "moves", "--record", str(folder / "x.txt")]),
        ("run --robot bogus", ["run", "moves", "--robot", "bogus://x"]),
        ("program-from-teleop a missing file", ["program-from-teleop", missing, str(folder / "p.yaml")]),
        ("program-from-teleop a binary file", ["program-from-teleop", binary["yaml"], str(folder / "p.yaml")]),
        ("plan a missing scene", ["plan", missing, "--no-plots", "--out", str(folder / "t.npz")]),
        ("plan a binary scene", ["plan", binary["yaml"], "--no-plots", "--out", str(folder / "t.npz")]),
        ("plan an empty scene", ["plan", empty, "--no-plots", "--out", str(folder / "t.npz")]),
        ("plan --mbm binary", ["plan", "--mbm", binary["json"], "--robot", binary["urdf"]]),
        ("plan --d-min nan", ["plan", "table71", "--d-min", "nan", "--no-plots", "--out", str(folder / "t.npz")]),
        ("plan --time-budget -1", ["plan", "table71", "--time-budget", "-1", "--no-plots",
                                   "--out", str(folder / "t.npz")]),
        ("info a binary URDF", ["info", binary["urdf"]]),
        ("info an unknown robot", ["info", "nosuchrobot"]),
        ("dataset export an unknown source", ["dataset", "export", "nosuch:thing", "--out", out_dir]),
        ("dataset export --format bogus", ["dataset", "export", "guidance:1", "--out", out_dir, "--format", "x"]),
        ("dataset export a binary .h5", ["dataset", "export", binary["h5"], "--out", out_dir]),
        ("dataset export --guidance-seconds -1", ["dataset", "export", "guidance:1", "--out", out_dir,
                                                  "--guidance-seconds", "-1"]),
        ("dataset import a missing path", ["dataset", "import", missing]),
        ("dataset import a binary file", ["dataset", "import", binary["hdf5"]]),
        ("batch run a binary file", ["batch", "run", binary["yaml"], "--out", out_dir]),
        ("batch run a missing file", ["batch", "run", missing, "--out", out_dir]),
        ("batch run --workers 0", ["batch", "run", alist, "--workers", "0", "--out", out_dir]),
        ("batch run --timeout -1", ["batch", "run", alist, "--timeout", "-1", "--out", out_dir]),
        ("batch run --cpus-per-task 0", ["batch", "run", alist, "--cpus-per-task", "0", "--out", out_dir]),
        ("batch run --worker-niceness 30", ["batch", "run", alist, "--worker-niceness", "30", "--out", out_dir]),
        ("batch report a missing store", ["batch", "report", missing]),
        ("batch report --confidence 2", ["batch", "report", out_dir, "--confidence", "2"]),
        ("an unknown command", ["nosuchcommand"]),
        ("an unknown option", ["run", "moves", "--speed", "3"]),
    ]
    (folder / "programs").mkdir(exist_ok=True)
    cases += [(name, ["run", path, "--check"]) for name, path in _programs(folder / "programs")]
    cases += [(name, ["plan", path, "--no-plots", "--out", str(folder / "t.npz")])
              for name, path in _scenes(folder)]
    cases += [(name, ["batch", "run", path, "--out", out_dir]) for name, path in _sweeps(folder)]
    data = corrupt_lerobot(folder / "lerobot")[::4] + corrupt_robomimic(folder / "robomimic")[::4]
    cases += [(f"dataset import: {case}", ["dataset", "import", str(path)]) for case, path in data]
    return cases
