"""The streaming controller on the robot interface: the same stream drives the sim cell or a FANUC controller."""
import time

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.interface import RobotMode, open_robot
from robointel.teach.stream_control import LOCAL, StreamingController
from robointel.testing.emulator import EmulatorProcess, protocol_violations

READY = np.array([0.0, 0.0, 0.0, 0.0, -np.pi / 2, 0.0])


def _target():
    q = READY.copy()
    q[0] += 0.3
    q[2] += 0.1
    return q


def test_stream_drives_the_sim_interface_within_the_limits(lrmate):
    with open_robot("sim", q0=READY) as iface:
        ctl = StreamingController(lrmate, interface=iface, realtime=False, deadman=5.0)
        assert ctl.dt == pytest.approx(iface.period)
        ctl.submit({"type": "acquire"})
        tgt = _target()
        assert ctl.submit({"type": "joint_target", "q": tgt.tolist()}) is None
        cmds = []
        for _ in range(300):  # 2.4 s at the interface's 8 ms period
            ctl.advance(1)
            cmds.append(iface.state().q_cmd)
        s = ctl.state(LOCAL)
        assert s["mode"] == "tracking" and s["fault"] is None
        np.testing.assert_allclose(cmds[-1], tgt, atol=1e-9)  # the follower reached the target ...
        np.testing.assert_allclose(s["q"], tgt, atol=2e-3)      # ... and the simulated arm followed it
        speed = np.abs(np.diff(np.array(cmds), axis=0)) / iface.period
        assert np.all(speed <= lrmate.velocity_limit + 1e-9)
        with pytest.raises(InvalidInput):
            StreamingController(lrmate, interface=iface, q0=READY)


def test_interface_fault_stops_commanding_latches_and_resumes(lrmate):
    with open_robot("sim", q0=READY) as iface:
        ctl = StreamingController(lrmate, interface=iface, realtime=False, deadman=5.0)
        ctl.submit({"type": "acquire"})
        ctl.submit({"type": "joint_target", "q": _target().tolist()})
        ctl.advance(20)
        iface.stop("operator e-stop")  # the robot side stops
        n = len(iface.sent_times)
        ctl.advance(20)
        assert len(iface.sent_times) == n  # nothing was sent after the fault
        s = ctl.state(LOCAL)
        assert s["mode"] == "faulted" and s["latched"] and "operator e-stop" in s["fault"]
        reply = ctl.submit({"type": "joint_target", "q": READY.tolist()})
        assert reply["type"] == "error" and reply["code"] == "stopped"
        assert ctl.submit({"type": "resume"})["type"] == "ok"
        assert ctl.state(LOCAL)["fault"] is None and iface.state().mode is RobotMode.IDLE
        assert ctl.submit({"type": "joint_target", "q": READY.tolist()}) is None
        ctl.advance(300)
        np.testing.assert_allclose(iface.state().q_cmd, READY, atol=1e-9)


def test_stream_drives_the_fanuc_emulator_and_its_estop_stops_it(lrmate):
    with EmulatorProcess(READY) as emu:
        url = f"fanuc://127.0.0.1:{emu.rmi_port}?sm_port={emu.sm_port}"
        with open_robot(url) as iface:
            ctl = StreamingController(lrmate, interface=iface, deadman=5.0)
            ctl.start()
            try:
                ctl.submit({"type": "acquire"})
                tgt = _target()
                _drive_to(ctl, emu, tgt)
                t_inj = emu.timed("press_estop")[1]
                _wait_until(lambda: ctl.state(LOCAL)["mode"] == "faulted", timeout=5.0)  # the next status says so
                s = ctl.state(LOCAL)
                assert s["mode"] == "faulted" and s["latched"] and "e-stop" in s["fault"]
                t_rep = emu.call("first_stop_status_after", t_inj)  # the first status reporting the e-stop
                assert t_rep is not None
                assert len([t for t in iface.sent_times if t > t_rep]) <= 2
                n = len(iface.sent_times)
                time.sleep(0.1)
                assert len(iface.sent_times) == n
                emu.call("release_estop")
                time.sleep(0.1)
                reply = ctl.submit({"type": "resume"})
                assert reply["type"] == "ok", reply
                _drive_to(ctl, emu, READY)
            finally:
                ctl.stop()
        # every strict-conformance violation but the arrival-gap flag, as in tests/interface
        assert protocol_violations(emu.call("violations")) == []


def _drive_to(ctl, emu, q, attempts=3):
    """Stream ``q`` until the emulated arm is within 0.1 deg of it.

    A host too busy to feed the look-ahead for 10 controller periods is stopped by the interface
    ("command stream stalled"), which latches a fault: that is the designed answer to a stall, so the
    test resumes and sends the target again, as an operator would. Any other fault fails the test.
    """
    for _ in range(attempts):
        assert ctl.submit({"type": "joint_target", "q": q.tolist()}) is None
        _wait_until(lambda: _near(emu, q) or ctl.state(LOCAL)["mode"] == "faulted")
        if _near(emu, q):
            return
        s = ctl.state(LOCAL)
        assert s["mode"] == "faulted" and "stalled" in (s["fault"] or ""), s
        assert ctl.submit({"type": "resume"})["type"] == "ok"
    np.testing.assert_allclose(np.radians(emu.call("q_meas_deg")[:6]), q, atol=np.radians(0.1),
                               err_msg=str(ctl.state(LOCAL)))


def _near(emu, q):
    """The emulated arm within 0.1 deg of ``q`` on every joint."""
    return bool(np.max(np.abs(np.radians(emu.call("q_meas_deg")[:6]) - q)) <= np.radians(0.1))


def _wait_until(condition, timeout=15.0):
    """Poll until ``condition()`` holds or ``timeout`` s passed: a slow host stretches the plant's convergence."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not condition():
        time.sleep(0.02)
