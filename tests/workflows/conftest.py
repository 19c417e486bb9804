"""The documented user workflows run as a user runs them: the `robointel` command in a subprocess."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest


def command() -> list[str]:
    """The `robointel` console script beside this interpreter, else ``python -m robointel.cli``."""
    exe = Path(sys.executable).with_name("robointel")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "robointel.cli"]


def run(*args: str, timeout: float = 900.0) -> subprocess.CompletedProcess[str]:
    """``robointel ARGS`` to completion, output captured (wide terminal: no wrapped lines)."""
    env = dict(os.environ, COLUMNS="200", MPLBACKEND="Agg")
    return subprocess.run([*command(), *args], capture_output=True, text=True, timeout=timeout, env=env)


@pytest.fixture
def robointel():
    """Call ``robointel("plan", "scene", ...)`` to run the command; returns the CompletedProcess."""
    return run


@pytest.fixture
def robointel_command():
    """The argv prefix that runs `robointel` (for commands that keep running, e.g. the emulator)."""
    return command()
