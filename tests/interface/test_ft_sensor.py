"""Lead-through on the FANUC emulator with a wrist F/T sensor over Net F/T RDT (UDP, 127.0.0.1)."""
import multiprocessing
import socket
import struct
import time

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.interface import open_robot
from robointel.interface.ft_sensor import RDT_RECORD, NetFTSensor, WrenchSource, open_ft_sensor
from robointel.robot import Robot
from robointel.teach.lead_through import lead_through
from robointel.testing.emulator import fanuc_url, running_fake

from ._waits import settled

CPF = 1e6


class SimulatedNetFT:
    """A Net F/T box on 127.0.0.1: after the RDT start command it streams ``wrench_of(t)`` at 500 Hz.

    The box runs in a forked process of its own, like the real sensor: a thread here would wait for
    the interpreter lock behind the real-time loop it feeds and send stale readings on a loaded machine.
    """

    def __init__(self, wrench_of, status=0):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.002)  # the record rate: one per receive timeout
        self.port = self.sock.getsockname()[1]
        ctx = multiprocessing.get_context("fork")
        self.wrench_of, self._status = wrench_of, ctx.Value("q", status)
        self.started = ctx.Event()
        self._stop = ctx.Event()
        self._proc = ctx.Process(target=self._run, daemon=True)
        self._proc.start()

    def _run(self):
        peer, seq, t0 = None, 0, 0.0
        while not self._stop.is_set():
            try:
                data, addr = self.sock.recvfrom(64)
                header, cmd, _ = struct.unpack(">HHI", data[:8])
                if header == 0x1234 and cmd == 2:  # start real-time streaming
                    peer, t0 = addr, time.perf_counter()
                    self.started.set()
                elif header == 0x1234 and cmd == 0:  # stop streaming
                    peer = None
            except (TimeoutError, OSError):
                pass
            if peer is not None:
                counts = np.round(np.asarray(self.wrench_of(time.perf_counter() - t0), float) * CPF).astype(int)
                seq += 1
                self.sock.sendto(RDT_RECORD.pack(seq, seq, self.status, *counts.tolist()), peer)

    @property
    def status(self):
        """The RDT status word the box sends (shared with its process)."""
        return self._status.value

    @status.setter
    def status(self, value):
        self._status.value = value

    def close(self):
        self._stop.set()
        self._proc.join(timeout=5)
        if self._proc.is_alive():
            self._proc.kill()
        self.sock.close()


def test_netft_reads_the_wrench_and_reports_faults_as_missing():
    box = SimulatedNetFT(lambda t: [1.0, -2.0, 3.0, 0.1, -0.2, 0.3])
    sensor = open_ft_sensor(f"netft://127.0.0.1:{box.port}")
    try:
        assert isinstance(sensor, WrenchSource)
        assert box.started.wait(10)
        w = None
        deadline = time.monotonic() + 10
        while w is None and time.monotonic() < deadline:
            w = sensor.read()
            time.sleep(0.005)
        np.testing.assert_allclose(w, [1.0, -2.0, 3.0, 0.1, -0.2, 0.3], atol=1e-6)
        box.status = 0x80000000  # a sensor fault: the reading is not used
        deadline = time.monotonic() + 10
        while sensor.read() is not None and time.monotonic() < deadline:
            time.sleep(0.005)
        assert sensor.read() is None
    finally:
        sensor.close()
        box.close()
    with pytest.raises(InvalidInput, match="unknown F/T sensor"):
        open_ft_sensor("ati://x")
    with pytest.raises(InvalidInput):
        NetFTSensor("127.0.0.1", counts_per_force=0.0)


def test_lead_through_on_the_emulator_follows_a_push_on_the_wrist_sensor():
    robot = Robot.load("lrmate200id7l")
    q0 = np.array([0.0, 0.2, -0.3, 0.0, -0.8, 0.0])
    R0 = robot.frame_pose(q0, robot.flange_frame)[:3, :3]
    push = R0.T @ np.array([0.0, 20.0, 0.0])  # 20 N along world +y, in the sensor frame
    released = multiprocessing.get_context("fork").Event()  # set here, read by the box's process

    def wrench_of(t):
        return np.concatenate([push, np.zeros(3)]) if not released.is_set() else np.zeros(6)

    box = SimulatedNetFT(wrench_of)
    p0 = robot.fk(q0)[:3, 3]
    try:
        with running_fake(q0) as fake:
            with open_robot(fanuc_url(fake), ft_sensor=f"netft://127.0.0.1:{box.port}") as arm:
                assert arm.has_wrench

                def on_cycle(k, step):
                    if k == 60:  # 0.48 s of push, then the hand lets go
                        released.set()

                res = lead_through(arm, robot, 1.0, on_cycle=on_cycle)
                q_end = settled(lambda: np.radians(fake.q_meas_deg[:6]), 1e-5, 0.2)  # the plant's lag closes
            assert fake.violations == []
    finally:
        box.close()
    d = robot.fk(q_end)[:3, 3] - p0
    assert d[1] > 0.02, d  # moved along the push
    assert abs(d[0]) < 0.3 * d[1] and abs(d[2]) < 0.3 * d[1]
    assert (~res.held).sum() > 0.9 * len(res.held)  # the sensor's readings drove it
    np.testing.assert_allclose(res.q_cmd[-1], res.q_cmd[-2], atol=1e-4)  # released: it stops
    np.testing.assert_allclose(q_end, res.q_cmd[-1], atol=2e-3)  # the controller reached the last target
