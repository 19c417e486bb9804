"""The teleoperation page driven in headless Chromium (Debian's ``chromium``) with Playwright:
connect, drag the gizmo (the hand) with the mouse and record, type a second pose and record, replay,
check the simulated robot reached them,
check an unreachable pose is shown and not sent, save the program.

Needs /usr/bin/chromium (or $ROBOINTEL_CHROMIUM). Skips without it, fails when CI=true.
"""
from __future__ import annotations

import os
import shutil
import socket
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = os.environ.get("ROBOINTEL_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def _need_browser():
    if not Path(CHROMIUM).exists():
        msg = f"chromium not found at {CHROMIUM}: install Debian's 'chromium' package (apt-get install chromium)"
        if os.environ.get("CI", "").lower() == "true" or os.environ.get("ROBOINTEL_REQUIRE_DATA") == "1":
            pytest.fail(msg)
        pytest.skip(msg)
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        pytest.fail("playwright (Python) is a dev dependency: pip install -e '.[dev]'")


def _free_port() -> int:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def _wait(pred, timeout=20.0, what=""):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def test_page_record_replay_save(lrmate, tmp_path):
    _need_browser()
    from playwright.sync_api import sync_playwright

    from robointel.teach.streaming import StreamingController
    from robointel.teach.teleop import TeleopApp, load_program

    app = TeleopApp(StreamingController(lrmate), port=_free_port(), program_path=tmp_path / "prog.yaml").start()
    profile = tempfile.mkdtemp(prefix="robointel-chromium-")
    try:
        with sync_playwright() as pw:
            ctx = pw.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, args=ARGS, headless=True,
                                                         viewport={"width": 800, "height": 500})
            try:
                page = ctx.new_page()
                page.set_default_timeout(30000)
                page.goto(app.url)
                page.get_by_text("Record waypoint").wait_for()
                row = page.get_by_text("Hand position [m]").locator("xpath=ancestor::div[.//input][1]")
                boxes = row.locator("input")
                assert boxes.count() == 3

                def field(label):
                    row = page.get_by_text(label, exact=True).locator("xpath=ancestor::div[.//input][1]")
                    return row.locator("input")

                def type_hand(p):
                    for box, v in zip([boxes.nth(i) for i in range(3)], p):
                        box.fill(f"{v:.3f}")
                        box.press("Enter")

                # 1) drag the gizmo (the operator's hand) along its world-x arrow with the mouse
                _wait(lambda: len(app.server.get_clients()) > 0, what="browser client")
                cam = list(app.server.get_clients().values())[0].camera
                hand0 = np.array(app._hand.position)
                want = hand0 + np.array([0.0, -0.8, 0.15])  # look along +y at the hand
                cam.position = tuple(want)
                cam.look_at = tuple(hand0)
                _wait(lambda: np.allclose(cam.position, want, atol=1e-3), what="camera placed")
                time.sleep(0.5)
                from scipy.spatial.transform import Rotation

                vw = page.viewport_size

                def project(p):
                    Rc = Rotation.from_quat(np.r_[cam.wxyz[1:], cam.wxyz[0]]).as_matrix()  # OpenCV camera
                    pc = Rc.T @ (np.asarray(p) - np.asarray(cam.position))
                    f = 0.5 * vw["height"] / np.tan(0.5 * cam.fov)
                    return 0.5 * vw["width"] + f * pc[0] / pc[2], 0.5 * vw["height"] + f * pc[1] / pc[2]

                for attempt in range(3):  # a loaded machine may drop the first pointer events
                    grab = project(hand0 + np.array([0.10, 0.0, 0.0]))  # on the arrow along world +x
                    page.mouse.move(*grab)
                    page.mouse.down()
                    for k in range(1, 4):
                        page.mouse.move(grab[0] + 20 * k, grab[1])
                    page.mouse.up()
                    try:
                        _wait(lambda: np.array(app._hand.position)[0] > hand0[0] + 0.02, timeout=10, what="drag")
                        break
                    except AssertionError:
                        if attempt == 2:
                            raise
                last = [np.array(app._hand.position), time.monotonic()]

                def settled():  # no pointer event still in flight: unchanged for 0.5 s
                    p = np.array(app._hand.position)
                    if not np.array_equal(p, last[0]):
                        last[:] = [p, time.monotonic()]
                    return time.monotonic() - last[1] > 0.5

                _wait(settled, what="hand settled")
                dragged = np.array(app._hand.position)
                np.testing.assert_allclose(dragged[1:], hand0[1:], atol=1e-6)  # moved along x only
                _wait(lambda: app.desired is not None and
                      np.linalg.norm(lrmate.fk(app.desired)[:3, 3] - dragged) < 1e-6, what="IK of the dragged hand")
                _wait(lambda: np.linalg.norm(lrmate.fk(app.controller.wc.q)[:3, 3] - dragged) < 2e-3,
                      what="robot follows the hand")
                page.get_by_text("Record waypoint").click()
                _wait(lambda: field("Waypoints").input_value() == "1", what="waypoint count")

                # 2) type a second hand pose
                targets = [tuple(dragged), (0.40, -0.15, 0.45)]
                type_hand(targets[1])
                _wait(lambda: np.linalg.norm(lrmate.fk(app.desired)[:3, 3] - np.array(targets[1])) < 1e-6,
                      what="IK of the typed pose")
                page.get_by_text("Record waypoint").click()
                _wait(lambda: field("Waypoints").input_value() == "2", what="waypoint count")
                recorded = [w.copy() for w in app.waypoints]
                assert len(recorded) == 2

                # an unreachable hand pose is shown and not sent
                before = app.desired.copy()
                type_hand((1.6, 0.0, 0.5))
                _wait(lambda: "UNREACHABLE" in field("IK").input_value(), what="unreachable shown")
                assert app.unreachable_moves >= 1
                np.testing.assert_array_equal(app.desired, before)
                assert not any(np.linalg.norm(lrmate.fk(np.array(app.controller.state()["target"]))[:3, 3]
                                              - [1.6, 0.0, 0.5]) < 0.5 for _ in [0])

                # replay: sample the simulated robot while it runs
                trace, stop = [], threading.Event()

                def sample():
                    while not stop.is_set():
                        trace.append(app.controller.wc.q)
                        time.sleep(0.005)

                th = threading.Thread(target=sample, daemon=True)
                th.start()
                page.get_by_text("Replay", exact=True).click()
                _wait(lambda: field("Status").input_value().startswith("replayed 2"), timeout=40, what="replay")
                stop.set()
                th.join()
                trace = np.array(trace)
                for w in recorded:  # the robot reached each recorded waypoint
                    assert np.min(np.max(np.abs(trace - w), axis=1)) < 2e-3
                np.testing.assert_allclose(app.controller.wc.q, recorded[-1], atol=2e-3)
                for w, p in zip(recorded, targets):
                    np.testing.assert_allclose(lrmate.fk(w)[:3, 3], p, atol=1e-6)

                page.get_by_text("Save program").click()
                _wait(lambda: (tmp_path / "prog.yaml").exists(), what="program file")
                prog = load_program(tmp_path / "prog.yaml")
                np.testing.assert_allclose(prog["waypoints"], np.array(recorded))
            finally:
                ctx.close()
        # the page is gone: its keep-alive stream stops and the deadman stops the robot
        _wait(lambda: len(app.server.get_clients()) == 0, what="client gone")
        _wait(lambda: app.controller.mode == "stopped", what="deadman stop after the page closed")
    finally:
        app.stop()
        shutil.rmtree(profile, ignore_errors=True)
