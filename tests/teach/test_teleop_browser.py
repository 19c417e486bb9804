"""The teleoperation page driven in headless Chromium (Debian's ``chromium``) with Playwright:
connect, drag the gizmo (the hand) with the mouse and record, type a second pose and record, replay,
check the simulated robot reached them,
check an unreachable pose is shown and not sent, save the program. With a token: each browser is
its own session, one that has not logged in gets nothing about the robot and cannot command it, the
token is never sent back; a logged-in one types an orientation, moves single joints, jogs by a step
and while a button is held, and lists, edits and deletes waypoints.

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
                _wait(lambda: any(s.built for s in app.sessions.values()), what="the session's page")
                hand = next(iter(app.sessions.values()))._hand  # this browser's gizmo
                hand0 = np.array(hand.position)
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
                        _wait(lambda: np.array(hand.position)[0] > hand0[0] + 0.02, timeout=10, what="drag")
                        break
                    except AssertionError:
                        if attempt == 2:
                            raise
                last = [np.array(hand.position), time.monotonic()]

                def settled():  # no pointer event still in flight: unchanged for 0.5 s
                    p = np.array(hand.position)
                    if not np.array_equal(p, last[0]):
                        last[:] = [p, time.monotonic()]
                    return time.monotonic() - last[1] > 0.5

                _wait(settled, what="hand settled")
                dragged = np.array(hand.position)
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


TOKEN = "page-token-0123456789-abc"


def test_sessions_with_a_token_and_the_operator_controls(lrmate, tmp_path):
    """Two browsers on a page with a token: B never logs in, A does and uses the controls."""
    _need_browser()
    from playwright.sync_api import sync_playwright

    from robointel.teach.streaming import StreamingController
    from robointel.teach.teleop import TeleopApp
    from robointel.testing.page_frames import about_robot, mentions

    app = TeleopApp(StreamingController(lrmate), port=_free_port(), token=TOKEN,
                    program_path=tmp_path / "prog.yaml").start()
    profile = tempfile.mkdtemp(prefix="robointel-chromium-")
    frames: dict[str, list] = {"A": [], "B": []}
    try:
        with sync_playwright() as pw:
            ctx = pw.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, args=ARGS, headless=True,
                                                         viewport={"width": 900, "height": 900})
            try:
                pages = {}
                for name in ("B", "A"):
                    pg = ctx.new_page()
                    pg.set_default_timeout(30000)
                    pg.on("websocket", lambda ws, n=name: ws.on("framereceived", lambda f, n=n: frames[n].append(f)))
                    pg.goto(app.url)
                    pg.get_by_role("button", name="Log in").wait_for()
                    pages[name] = pg
                A, B = pages["A"], pages["B"]

                def field(page, label):
                    return page.get_by_text(label, exact=True).locator("xpath=ancestor::div[.//input][1]").locator(
                        "input")

                # a wrong token first: refused, the session stays at the prompt
                field(A, "Token").fill("wrong-token-0123456789")
                A.get_by_role("button", name="Log in").click()
                A.get_by_text("wrong token (1 of 5)").wait_for()
                field(A, "Token").fill(TOKEN)
                A.get_by_role("button", name="Log in").click()
                A.get_by_text("Record waypoint").wait_for()
                _wait(lambda: sum(s.authed for s in app.sessions.values()) == 1, what="A logged in")
                # B typed nothing: it was sent nothing about the robot and has no control to use
                time.sleep(1.0)
                assert about_robot(frames["B"]) == 0
                assert B.get_by_text("Record waypoint").count() == 0 and B.get_by_text("Stop").count() == 0
                assert app.controller.accepted == 0

                # A: a typed orientation (position and roll/pitch/yaw)
                def type_vec(label, v):
                    boxes = field(A, label)
                    for k in range(3):
                        boxes.nth(k).fill(f"{v[k]:.3f}")
                        boxes.nth(k).press("Enter")

                type_vec("Hand position [m]", (0.45, 0.05, 0.35))
                type_vec("Hand roll, pitch, yaw [deg]", (0.0, 90.0, 30.0))
                from scipy.spatial.transform import Rotation

                want = Rotation.from_euler("xyz", [0.0, 90.0, 30.0], degrees=True).as_matrix()
                _wait(lambda: app.desired is not None and np.allclose(lrmate.fk(app.desired)[:3, :3], want, atol=1e-6)
                      and np.allclose(lrmate.fk(app.desired)[:3, 3], [0.45, 0.05, 0.35], atol=1e-6),
                      what="IK of the typed pose and orientation")
                _wait(lambda: np.max(np.abs(app.controller.wc.q - app.desired)) < 2e-3, what="arm at the pose")

                # A: one joint moved with its slider (J6 to 20 deg), the others kept
                A.get_by_text("Joints", exact=True).click()
                before = app.desired.copy()
                box = field(A, "joint_6 [deg]").last
                box.fill("20")
                box.press("Enter")
                _wait(lambda: abs(np.degrees(app.desired[5]) - 20.0) < 1e-6, what="J6 slider")
                np.testing.assert_allclose(app.desired[:5], before[:5], atol=1e-12)
                _wait(lambda: np.max(np.abs(app.controller.wc.q - app.desired)) < 2e-3, what="arm at J6 20 deg")

                # A: jog J1 by one 2 deg step, then while "hold >" is held
                box = field(A, "Jog step [deg | mm]")
                box.fill("2")
                box.press("Enter")
                q_before = app.desired.copy()
                A.get_by_role("button", name="+ step").click()
                _wait(lambda: not app._ramp and abs(np.degrees(app.desired[0] - q_before[0]) - 2.0) < 1e-6,
                      what="one jog step")
                q_before = app.desired.copy()
                btn = A.get_by_role("button", name="hold >")
                btn.hover()
                t_down = time.monotonic()
                A.mouse.down()
                # held: the joint keeps moving (several callbacks' worth, however slowly the page sends them)
                _wait(lambda: np.degrees(app.desired[0] - q_before[0]) > 3.0, what="the held jog moving on")
                A.mouse.up()
                t_held = time.monotonic() - t_down
                _wait(lambda: not app._ramp, what="the held jog's last steps")
                held = np.degrees(app.desired[0] - q_before[0])
                assert 3.0 < held <= 10.0 * t_held + 2.0      # at most 10 deg/s while held, then the ramp's last steps
                np.testing.assert_allclose(app.desired[1:], q_before[1:], atol=1e-12)
                q_release = app.desired.copy()
                time.sleep(0.5)
                np.testing.assert_array_equal(app.desired, q_release)

                # A: record three waypoints, list them, edit one, delete one
                for _ in range(3):
                    n = len(app.waypoints)
                    A.get_by_role("button", name="Record waypoint").click()
                    _wait(lambda: len(app.waypoints) == n + 1, what="recorded")
                    A.get_by_role("button", name="- step").click()
                    _wait(lambda: not app._ramp, what="jog step")
                _wait(lambda: field(A, "Waypoints").first.input_value() == "3", what="the page's waypoint count")
                edited = np.degrees(app.waypoints[1]).round(3)
                edited[2] += 5.0
                edit = field(A, "Waypoint joints [deg]")
                A.get_by_label("Waypoint", exact=True).click()     # the list: pick waypoint 2
                A.get_by_role("option").nth(1).click()
                _wait(lambda: edit.input_value() != "" and abs(float(edit.input_value().split(",")[0])
                                                              - edited[0]) < 1e-3, what="waypoint 2 selected")
                edit.fill(", ".join(f"{v:.3f}" for v in edited))
                edit.press("Enter")
                A.get_by_role("button", name="Apply edit").click()
                _wait(lambda: np.allclose(np.degrees(app.waypoints[1]), edited, atol=1e-6), what="waypoint edited")
                keep = [app.waypoints[0].copy(), app.waypoints[1].copy()]
                A.get_by_role("button", name="Delete waypoint").click()   # the selected one: waypoint 2
                _wait(lambda: len(app.waypoints) == 2, what="waypoint deleted")
                np.testing.assert_allclose(app.waypoints[0], keep[0])
                assert not np.allclose(app.waypoints[1], keep[1])
                _wait(lambda: field(A, "Waypoints").first.input_value() == "2", what="the page's waypoint count")

                # Stop from the page latches
                A.get_by_role("button", name="Stop").click()
                _wait(lambda: app.controller.latched, what="stop latched")
            finally:
                ctx.close()
        assert mentions(frames["A"], TOKEN) == 0 and mentions(frames["B"], TOKEN) == 0  # never sent back
    finally:
        app.stop()
        shutil.rmtree(profile, ignore_errors=True)
