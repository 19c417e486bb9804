"""``robointel dataset export|import``: demonstration files, teleoperated programs, both formats."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from robointel.cli import app
from robointel.io.lerobot import read_lerobot
from robointel.learning.demonstration import Demonstration, load_demonstrations, save_demonstrations
from robointel.teach.teleop import save_program

runner = CliRunner()


def demonstration(seed: int) -> Demonstration:
    rng = np.random.default_rng(seed)
    t = np.arange(150) / 100.0
    pose = np.tile(np.eye(4), (len(t), 1, 1))
    pose[:, :3, :3] = Rotation.from_rotvec(np.outer(np.sin(t), [0.0, 0.1, 0.05])).as_matrix()
    pose[:, :3, 3] = np.stack([0.4 + 0.02 * t, 0.01 * np.sin(3 * t), 0.3 - 0.05 * t], axis=1)
    wrench = rng.normal(0.0, 1.0, (len(t), 6)) + np.array([0.0, 0.0, -5.0, 0.0, 0.0, 0.0])
    labels = np.minimum(t // 0.5, 2).astype(np.int64)
    return Demonstration.create(t, pose, wrench, labels, action_names=("approach", "insert", "done"),
                                name=f"demo_{seed}", meta={"seed": seed})


def test_demonstration_file_to_lerobot_and_robomimic_and_back(tmp_path):
    src = tmp_path / "demos.h5"
    save_demonstrations(src, [demonstration(0), demonstration(1)])
    res = runner.invoke(app, ["dataset", "export", str(src), "--out", str(tmp_path / "ds")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "ds" / "meta" / "info.json").exists() and "2 episode(s), 300 frames" in res.output
    res = runner.invoke(app, ["dataset", "export", str(src), "--format", "robomimic",
                              "--out", str(tmp_path / "d.hdf5")])
    assert res.exit_code == 0, res.output
    for dataset in (tmp_path / "ds", tmp_path / "d.hdf5"):
        out = tmp_path / f"back_{dataset.stem}.h5"
        res = runner.invoke(app, ["dataset", "import", str(dataset), "--demonstrations", str(out)])
        assert res.exit_code == 0, res.output
        assert "demo_0" in res.output and "device" in res.output
        for a, b in zip(load_demonstrations(src), load_demonstrations(out)):
            assert np.array_equal(a.pose, b.pose) and np.array_equal(a.labels, b.labels) and a.meta == b.meta


def test_teleop_program_export(tmp_path, lrmate):
    ready = np.array([0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0])
    program = save_program(tmp_path / "prog.yaml", lrmate, [ready, ready + [0.2, 0.1, 0.0, 0.0, 0.1, 0.0]])
    res = runner.invoke(app, ["dataset", "export", f"teleop:{program}", "--out", str(tmp_path / "tele")])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["dataset", "import", str(tmp_path / "tele")])
    # the table's title wraps where the path ends (longer under pytest-xdist: .../popen-gw0/...)
    assert res.exit_code == 0 and "1 episode(s)" in " ".join(res.output.split())
    (ep,) = read_lerobot(tmp_path / "tele")
    assert ep.kind == "teleoperation" and ep.name == "prog" and ep.observations["state"].shape[1] == 6


def test_bad_sources_and_formats_are_clear_errors(tmp_path):
    res = runner.invoke(app, ["dataset", "export", "nothing:here", "--out", str(tmp_path / "x")])
    assert res.exit_code == 2 and "unknown source" in res.output
    res = runner.invoke(app, ["dataset", "export", "teleop:x.yaml", "--format", "zarr", "--out", str(tmp_path / "x")])
    assert res.exit_code == 2 and "--format" in res.output
    res = runner.invoke(app, ["dataset", "import", str(tmp_path)])
    assert res.exit_code == 2 and "neither" in res.output
