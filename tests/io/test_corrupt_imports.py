"""Imports that fail whole: every corrupt LeRobot v3 / robomimic file is one robointel error naming the
file, through the readers and through ``robointel dataset import``; an import appends all of its
demonstrations or none."""
from __future__ import annotations

import pytest
from typer.testing import CliRunner

from robointel.cli import app
from robointel.errors import InvalidInput, RobointelError
from robointel.io.demonstrations import DemonstrationFile
from robointel.io.lerobot import read_lerobot, write_lerobot
from robointel.io.robomimic import read_robomimic, write_robomimic
from robointel.learning.demonstration_episode import episode_to_demonstration
from robointel.testing.corrupt_data import corrupt_lerobot, corrupt_robomimic, device_episodes

runner = CliRunner()


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    d = tmp_path_factory.mktemp("corrupt")
    return ([(c, p, read_lerobot) for c, p in corrupt_lerobot(d / "lerobot")]
            + [(c, p, read_robomimic) for c, p in corrupt_robomimic(d / "robomimic")])


def test_every_corrupt_file_is_one_robointel_error_naming_the_file(cases):
    assert len(cases) >= 30
    for case, path, reader in cases:
        with pytest.raises(RobointelError) as err:
            reader(path)
        assert str(path) in str(err.value), (case, str(err.value))


def test_the_cli_refuses_each_in_one_line(cases, tmp_path):
    store = tmp_path / "demos.h5"
    for case, path, _ in cases:
        r = runner.invoke(app, ["dataset", "import", str(path), "--demonstrations", str(store)])
        assert r.exception is None or isinstance(r.exception, SystemExit), (case, repr(r.exception))
        lines = [ln for ln in (r.stdout + r.stderr).splitlines() if ln.strip()]
        assert r.exit_code == 2 and lines[-1].startswith("error: "), (case, lines)
        assert "Traceback" not in r.output
    assert not store.exists()                      # nothing was appended by any of them


def test_an_import_appends_all_or_none(tmp_path):
    eps = device_episodes(3)
    src = write_robomimic(tmp_path / "three.hdf5", eps)
    store = DemonstrationFile(tmp_path / "demos.h5")
    store.append(episode_to_demonstration(eps[1]))  # the second one's name is taken already
    r = runner.invoke(app, ["dataset", "import", str(src), "--demonstrations", str(store.path)])
    assert r.exit_code == 2 and "demo_1" in r.output and "nothing was appended" in " ".join(r.output.split())
    assert store.names() == ["demo_1"]
    twice = write_lerobot(tmp_path / "twice", [eps[0], eps[0]])  # two episodes of one name
    r = runner.invoke(app, ["dataset", "import", str(twice), "--demonstrations", str(tmp_path / "new.h5")])
    assert r.exit_code == 2 and "twice" in r.output
    assert DemonstrationFile(tmp_path / "new.h5").names() == []
    r = runner.invoke(app, ["dataset", "import", str(src), "--demonstrations", str(tmp_path / "ok.h5")])
    assert r.exit_code == 0, r.output
    assert DemonstrationFile(tmp_path / "ok.h5").names() == ["demo_0", "demo_1", "demo_2"]


def test_fps_zero_is_refused_when_writing(tmp_path):
    with pytest.raises(InvalidInput, match="fps"):
        write_lerobot(tmp_path / "ds", device_episodes(1), fps=0)
