"""Jogging from the CLI as the docs tell it (``robointel jog`` through ``subprocess``) against the FANUC
controller emulator: the emulated arm moves by the increment asked, read back from the emulator itself."""
from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np

from robointel.robot import Robot
from robointel.testing.emulator import fanuc_url, running_fake

READY = np.radians([10.0, 20.0, -10.0, 0.0, -60.0, 0.0])


def _jog(url: str, *args: str) -> dict:
    r = subprocess.run([sys.executable, "-m", "robointel.cli", "jog", "--robot", url, *args, "--json"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "Traceback" not in r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def _settled(fake) -> np.ndarray:
    last = np.radians(fake.q_meas_deg[:6])
    for _ in range(200):  # the plant's first-order lag closes on the last command
        q = np.radians(fake.q_meas_deg[:6])
        if np.max(np.abs(q - last)) < 1e-6:
            return q
        last = q
        time.sleep(0.05)
    return last


def test_a_jog_moves_the_arm_by_the_increment_asked():
    lr = Robot.load("lrmate200id7l")
    with running_fake(READY) as fake:
        url = fanuc_url(fake)
        before = _settled(fake)
        out = _jog(url, "--joint", "2", "--by", "5")            # J2 by 5 deg
        after = _settled(fake)
        moved = np.degrees(after - before)
        np.testing.assert_allclose(moved, [0, 5, 0, 0, 0, 0], atol=0.03)
        assert out["dropped"] == 0 and out["refused"] is None
        out = _jog(url, "--axis", "z", "--frame", "world", "--by", "-10")   # the TCP 10 mm down
        tcp = lr.fk(_settled(fake))[:3, 3] - lr.fk(after)[:3, 3]
        np.testing.assert_allclose(tcp, [0, 0, -0.010], atol=2e-4)
        assert fake.violations == []
