"""The FANUC emulator logs its own stalls (the evidence ``tests/conftest.py`` reruns a failed test on)."""
import os
import signal
import time

from robointel.testing.emulator import RIG_STALL_S, RIG_STALLS, EmulatorProcess


def test_a_paused_emulator_logs_its_stall_and_a_running_one_none():
    with EmulatorProcess() as emu:
        time.sleep(0.5)
        os.kill(emu._proc.pid, signal.SIGSTOP)
        time.sleep(0.15)
        os.kill(emu._proc.pid, signal.SIGCONT)
        time.sleep(0.2)
    assert any(g >= 0.14 for g in emu.stalls), emu.stalls
    assert all(g > RIG_STALL_S for g in emu.stalls)
    assert (emu.url, max(emu.stalls)) in RIG_STALLS
