"""The teleoperation page driven in headless Chromium (Debian's ``chromium``) with Playwright:
connect, type two hand poses and record them, replay, check the simulated robot reached them,
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

    from robointel.programming.streaming import StreamingController
    from robointel.programming.teleop import TeleopApp, load_program

    app = TeleopApp(StreamingController(lrmate), port=_free_port(), program_path=tmp_path / "prog.yaml").start()
    profile = tempfile.mkdtemp(prefix="robointel-chromium-")
    try:
        with sync_playwright() as pw:
            ctx = pw.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, args=ARGS, headless=True)
            try:
                page = ctx.new_page()
                page.set_default_timeout(30000)
                page.goto(app.url)
                page.get_by_text("Record waypoint").wait_for()
                row = page.get_by_text("Hand position [m]").locator("xpath=ancestor::div[.//input][1]")
                boxes = row.locator("input")
                assert boxes.count() == 3

                def field(label):
                    return page.get_by_text(label, exact=True).locator("xpath=ancestor::div[.//input][1]").locator("input")

                def type_hand(p):
                    for box, v in zip([boxes.nth(i) for i in range(3)], p):
                        box.fill(f"{v:.3f}")
                        box.press("Enter")

                targets = [(0.45, 0.10, 0.55), (0.40, -0.15, 0.45)]
                for k, p in enumerate(targets):
                    type_hand(p)
                    _wait(lambda: app.desired is not None and
                          np.linalg.norm(lrmate.fk(app.desired)[:3, 3] - np.array(p)) < 1e-6, what=f"IK of {p}")
                    page.get_by_text("Record waypoint").click()
                    _wait(lambda: field("Waypoints").input_value() == str(k + 1), what="waypoint count")
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
    finally:
        app.stop()
        shutil.rmtree(profile, ignore_errors=True)
