"""One browser session of the teleoperation page (:class:`robointel.teach.teleop.TeleopApp`).

Everything a session shows lives in its own viser scope (``client.scene``, ``client.gui``): nothing
is shared with, or broadcast to, another browser. A session of a page with a token first gets a
login prompt only; once the token typed into it matches (checked on the server), the prompt is
removed and the session gets the robot's scene and the controls:

- **Stop** / **Resume** (a stop latches until resumed);
- **Hand (TCP)**: a gizmo in the scene, and the pose typed as a position [m] and roll/pitch/yaw [deg];
- **Joints**: one slider per joint [deg];
- **Jog**: the frame (joint, world, tool), the axis, the step [deg or mm] and speed [deg/s or mm/s];
  ``- step`` / ``+ step`` jog by one step, ``< hold`` / ``hold >`` jog while the button is held;
- **Waypoints**: record, list (pick one), go to it, edit its joints [deg], replace it with the
  current target, delete it, replay them all, clear, save the program.

Five wrong tokens lock the session's login (a new page load starts a new session); each wrong token
is answered after 0.5 s.
"""
from __future__ import annotations

import threading
import time
import warnings
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from robointel.errors import RobointelError
from robointel.teach.jog import AXES, axis_index
from robointel.teach.teleop_program import shape_to_dict

__all__ = ["LOGIN_DELAY", "LOGIN_FAILURES", "PageSession", "quat_matrix", "quat_wxyz"]

_LINK_COLORS = [(240, 200, 40), (200, 200, 200), (240, 200, 40), (200, 200, 200), (240, 200, 40), (90, 90, 90)]
HOLD_HZ = 20.0  # callbacks per second while a jog button is held
LOGIN_FAILURES = 5  # wrong tokens before a session's login is locked (reload the page to try again)
LOGIN_DELAY = 0.5   # s before a wrong token is answered


def quat_wxyz(R: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """The quaternion [w, x, y, z] of a rotation matrix."""
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z])


def quat_matrix(wxyz: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """The rotation matrix of a quaternion [w, x, y, z] (normalised)."""
    w, x, y, z = np.asarray(wxyz, float)
    return np.asarray(Rotation.from_quat([x, y, z, w]).as_matrix())




def _rpy_deg(R: np.ndarray) -> tuple[float, float, float]:
    with warnings.catch_warnings():  # at pitch +-90 deg roll and yaw share one axis: any split is the pose
        warnings.simplefilter("ignore", UserWarning)
        r, p, y = Rotation.from_matrix(R).as_euler("xyz", degrees=True)
    return round(float(r), 3), round(float(p), 3), round(float(y), 3)


def _wxyz_of_rpy(rpy_deg: Any) -> np.ndarray:
    x, y, z, w = Rotation.from_euler("xyz", np.asarray(rpy_deg, float), degrees=True).as_quat()
    return np.array([w, x, y, z])


class PageSession:
    """One browser's view of the page: a login prompt until authenticated, then the scene and controls.

    Args:
        app: the teleoperation app (:class:`robointel.teach.teleop.TeleopApp`, which imports this module).
        client: the viser client handle of the browser.
    """

    def __init__(self, app: Any, client: Any) -> None:
        self.app, self.client = app, client
        self.authed = app.token is None
        self.failures = 0
        self._login: list[Any] = []
        self._links: dict[str, Any] = {}
        self._wp_handles: list[Any] = []
        self._syncing = False
        self._dragging = False
        self._shown = np.zeros(app.robot.nq)
        self._listed = 0  # waypoints in the list (a new one is selected when it grows)
        self._lock = threading.Lock()
        self.built = False

    # ------------------------------------------------------------------ login
    def begin(self) -> None:
        """Show the login prompt (with a token) or the page (without)."""
        if self.authed:
            self.build()
            return
        g = self.client.gui
        head = g.add_markdown("**robointel teleoperation** - type the token to log in.")
        tok = g.add_text("Token", "")
        btn = g.add_button("Log in")
        msg = g.add_markdown(" ")
        self._login = [head, tok, btn, msg]

        @btn.on_click
        def _on_login(_e: Any) -> None:
            self.login(tok.value)

    def login(self, given: Any) -> bool:
        """Check a typed token: the page on success, a delayed refusal otherwise (locked after 5)."""
        with self._lock:
            if self.authed:
                return True
            if self.failures >= LOGIN_FAILURES:
                return False
            if self.app.check_token(given):
                self.authed = True
                for h in self._login:
                    h.remove()
                self._login = []
            else:
                self.failures += 1
        if self.authed:
            self.build()
            return True
        time.sleep(LOGIN_DELAY)
        if len(self._login) == 4:
            self._login[1].value = ""
            locked = self.failures >= LOGIN_FAILURES
            self._login[3].content = ("too many wrong tokens: reload the page to try again" if locked
                                      else f"wrong token ({self.failures} of {LOGIN_FAILURES})")
            if locked:
                self._login[1].disabled = self._login[2].disabled = True
        return False

    # ------------------------------------------------------------------ what the app shows
    def show_status(self, text: str) -> None:
        """Put ``text`` into the status field (logged-in sessions)."""
        if self.built:
            self._status.value = text
            self._reach.value = "UNREACHABLE: not sent" if not self.app.reachable else "reachable: streaming"
            self._bad.visible = not self.app.reachable

    def show_robot(self, poses: dict[str, np.ndarray], q: np.ndarray, target: np.ndarray | None) -> None:
        """Pose the robot's links (the display thread, 30 Hz); the joint sliders follow the target."""
        if not self.built:
            return
        with self.client.atomic():
            for link, frame in self._links.items():
                T = poses[link]
                frame.position = T[:3, 3]
                frame.wxyz = quat_wxyz(T[:3, :3])
        shown = target if target is not None else q
        if not self._syncing and np.max(np.abs(shown - self._shown)) > 1e-6:
            self._shown = shown.copy()
            self._sync(shown)

    def show_waypoints(self) -> None:
        """List the recorded waypoints and mark them in the scene."""
        if not self.built:
            return
        with self.app._lock:
            wps = [w.copy() for w in self.app.waypoints]
        pts = [self.app.robot.fk(w)[:3, 3] for w in wps]
        self._count.value = str(len(pts))
        for h in self._wp_handles:
            h.remove()
        self._wp_handles = [self.client.scene.add_icosphere(f"/waypoints/{i}", radius=0.015, color=(30, 110, 250),
                                                            position=p) for i, p in enumerate(pts)]
        options = [f"{i + 1}: {', '.join(f'{1e3 * v:.0f}' for v in p)} mm" for i, p in enumerate(pts)] or ["(none)"]
        keep = self._selected()
        pick = len(options) - 1 if keep is None or len(pts) > self._listed or keep >= len(pts) else keep
        self._listed = len(pts)
        self._syncing = True
        try:
            self._pick.options = tuple(options)
            self._pick.value = options[pick]
        finally:
            self._syncing = False
        self._show_selected()

    # ------------------------------------------------------------------ the page
    def _sync(self, q: np.ndarray) -> None:
        """Joint sliders, typed pose and gizmo to ``q`` (without sending anything)."""
        T = self.app.robot.fk(q)
        self._syncing = True
        try:
            for s, v in zip(self._sliders, np.degrees(q)):
                s.value = float(np.clip(round(float(v), 2), s.min, s.max))
            self._pos.value = tuple(float(v) for v in np.round(T[:3, 3], 4))
            self._rpy.value = _rpy_deg(T[:3, :3])
            if not self._dragging:
                self._hand.position = tuple(T[:3, 3])
                self._hand.wxyz = tuple(quat_wxyz(T[:3, :3]))
        finally:
            self._syncing = False

    def _selected(self) -> int | None:
        v = str(self._pick.value)
        return int(v.split(":")[0]) - 1 if v[:1].isdigit() else None

    def _show_selected(self) -> None:
        i = self._selected()
        with self.app._lock:
            q = self.app.waypoints[i] if i is not None and i < len(self.app.waypoints) else None
        self._syncing = True
        try:
            self._edit.value = "" if q is None else ", ".join(f"{v:.3f}" for v in np.degrees(q))
        finally:
            self._syncing = False

    def _act(self, what: str, fn: Any, *args: Any, **kw: Any) -> Any:
        """Run a command of the page; a refusal is shown in the status field."""
        try:
            return fn(*args, **kw)
        except RobointelError as exc:
            self.app._say(f"{what} refused: {exc}")
            return None

    def _build_scene(self) -> None:
        s = self.client.scene
        s.add_grid("/table", width=1.6, height=1.6, cell_size=0.1, section_size=0.5, position=(0.3, 0, 0))
        robot = self.app.robot
        for k, (link, prims) in enumerate(robot.collision_primitives().items()):
            frame = s.add_frame(f"/robot/{link}", show_axes=False)
            self._links[link] = frame
            c = _LINK_COLORS[k % len(_LINK_COLORS)]
            for i, pr in enumerate(prims):
                pos, wxyz = pr["origin"][:3, 3], quat_wxyz(pr["origin"][:3, :3])
                name = f"/robot/{link}/g{i}"
                if pr["type"] == "box":
                    s.add_box(name, color=c, dimensions=tuple(pr["size"]), position=pos, wxyz=wxyz)
                elif pr["type"] in ("cylinder", "capsule"):
                    s.add_cylinder(name, radius=float(pr["size"][0]), height=float(pr["size"][1]), color=c,
                                   position=pos, wxyz=wxyz)
                elif pr["type"] == "sphere":
                    s.add_icosphere(name, radius=float(pr["size"][0]), color=c, position=pos)
        for j, o in enumerate(self.app.obstacles):
            d = shape_to_dict(o)
            name = f"/obstacles/{d['name']}_{j}"
            if d["type"] == "sphere":
                s.add_icosphere(name, radius=d["radius"], color=(220, 60, 60), position=d["center"], opacity=0.6)
            elif d["type"] == "box":
                s.add_box(name, color=(220, 60, 60), dimensions=tuple(d["size"]), position=d["center"],
                          wxyz=quat_wxyz(np.array(d.get("rotation", np.eye(3)))), opacity=0.6)
            elif d["type"] in ("capsule", "cylinder"):
                a, b = np.array(d["a"]), np.array(d["b"])
                L = float(np.linalg.norm(b - a))
                rot, _ = Rotation.align_vectors([(b - a) / max(L, 1e-9)], [[0, 0, 1.0]])
                x, y, z, w = rot.as_quat()
                s.add_cylinder(name, radius=d["radius"], height=L, color=(220, 60, 60), position=0.5 * (a + b),
                               wxyz=(w, x, y, z), opacity=0.6)

    def build(self) -> None:
        """The scene and the controls of a logged-in session."""
        app, g = self.app, self.client.gui
        self._build_scene()
        q0 = app.reference()
        T = app.robot.fk(q0)
        self._shown = q0.copy()
        self._hand = self.client.scene.add_transform_controls("/hand", scale=0.18, position=T[:3, 3],
                                                              wxyz=quat_wxyz(T[:3, :3]))
        self._bad = self.client.scene.add_icosphere("/hand/unreachable", radius=0.035, color=(255, 0, 0), opacity=0.7,
                                                    visible=False)

        @self._hand.on_update
        def _on_hand(_e: Any) -> None:
            if self._syncing:
                return
            self._dragging = True
            try:
                app.move_hand(np.array(self._hand.position), np.array(self._hand.wxyz))
            finally:
                self._dragging = False

        g.add_markdown("**robointel teleoperation** - drag the gizmo (your hand), type a pose, move a joint or jog.")
        b_stop = g.add_button("Stop", color="red")
        b_resume = g.add_button("Resume")
        b_stop.on_click(lambda _e: app.emergency_stop())
        b_resume.on_click(lambda _e: app.resume())
        self._status = g.add_text("Status", app.status, disabled=True)
        self._reach = g.add_text("IK", "reachable", disabled=True)
        with g.add_folder("Hand (TCP)"):
            self._pos = g.add_vector3("Hand position [m]", tuple(np.round(T[:3, 3], 4)), step=0.001)
            self._rpy = g.add_vector3("Hand roll, pitch, yaw [deg]", _rpy_deg(T[:3, :3]), step=0.1)

        def _typed(_e: Any) -> None:
            if self._syncing:
                return
            p, wxyz = np.array(self._pos.value, float), _wxyz_of_rpy(self._rpy.value)
            self._syncing = True
            try:
                self._hand.position, self._hand.wxyz = tuple(p), tuple(wxyz)
            finally:
                self._syncing = False
            self._act("move", app.move_hand, p, wxyz)

        self._pos.on_update(_typed)
        self._rpy.on_update(_typed)
        with g.add_folder("Joints", expand_by_default=False):
            self._sliders = []
            for j, name in enumerate(app.robot.joint_names):
                lo, hi = np.degrees(app.robot.lower[j]), np.degrees(app.robot.upper[j])
                sl = g.add_slider(f"{name} [deg]", float(round(lo, 1)), float(round(hi, 1)), 0.1,
                                  float(np.clip(round(float(np.degrees(q0[j])), 1), round(lo, 1), round(hi, 1))))
                sl.on_update(lambda _e, j=j, sl=sl: None if self._syncing else
                             self._act("joint move", app.move_joint, j, float(np.radians(sl.value))))
                self._sliders.append(sl)
        self._build_jog(g)
        self._build_waypoints(g)
        self.built = True
        self.show_waypoints()

    def _build_jog(self, g: Any) -> None:
        app = self.app
        joints = tuple(f"J{j + 1}" for j in range(app.robot.nq))
        with g.add_folder("Jog"):
            frame = g.add_dropdown("Jog frame", ("joint", "world", "tool"), initial_value="joint")
            axis = g.add_dropdown("Jog axis", joints, initial_value=joints[0])
            step = g.add_number("Jog step [deg | mm]", 1.0, min=0.01, max=90.0, step=0.01)
            speed = g.add_number("Jog speed [deg/s | mm/s]", 10.0, min=0.1, max=250.0, step=0.1)
            b_minus, b_plus = g.add_button("- step"), g.add_button("+ step")
            h_minus, h_plus = g.add_button("< hold"), g.add_button("hold >")

        @frame.on_update
        def _frame(_e: Any) -> None:
            axis.options = joints if frame.value == "joint" else AXES
            axis.value = axis.options[0]

        def units() -> tuple[str, int, float]:
            fr = str(frame.value)
            i = axis_index(fr, str(axis.value), app.robot.nq)
            return fr, i, np.radians(1.0) if fr == "joint" or i >= 3 else 1e-3

        def by(sign: float, amount: float | None) -> None:
            fr, i, u = units()
            self._act("jog", app.jog, fr, i, sign * u * (amount if amount is not None else float(step.value)),
                      speed=u * float(speed.value), lead=None if amount is None else 2.0 / HOLD_HZ)

        b_minus.on_click(lambda _e: by(-1.0, None))
        b_plus.on_click(lambda _e: by(1.0, None))
        # while held: each callback adds one callback period of motion at the jog speed (released: no more)
        h_minus.on_hold(lambda _e: by(-1.0, float(speed.value) / HOLD_HZ), callback_hz=HOLD_HZ)
        h_plus.on_hold(lambda _e: by(1.0, float(speed.value) / HOLD_HZ), callback_hz=HOLD_HZ)

    def _build_waypoints(self, g: Any) -> None:
        app = self.app
        with g.add_folder("Waypoint list"):
            self._count = g.add_text("Waypoints", "0", disabled=True)
            self._pick = g.add_dropdown("Waypoint", ("(none)",), initial_value="(none)")
            self._edit = g.add_text("Waypoint joints [deg]", "")
            b_rec = g.add_button("Record waypoint")
            b_go = g.add_button("Go to waypoint")
            b_apply = g.add_button("Apply edit")
            b_here = g.add_button("Replace with current")
            b_del = g.add_button("Delete waypoint")
            b_play = g.add_button("Replay")
            b_clear = g.add_button("Clear")
            b_save = g.add_button("Save program")

        self._pick.on_update(lambda _e: None if self._syncing else self._show_selected())

        def selected(what: str) -> int | None:
            i = self._selected()
            if i is None:
                app._say(f"{what}: no waypoint selected")
            return i

        @b_rec.on_click
        def _rec(_e: Any) -> None:
            app._say(f"recorded waypoint {app.record()}")

        @b_go.on_click
        def _go(_e: Any) -> None:
            i = selected("go to")
            if i is not None:
                self._act("go to", app.go_to, i)

        @b_apply.on_click
        def _apply(_e: Any) -> None:
            i = selected("edit")
            if i is None:
                return
            try:
                q = np.radians([float(v) for v in str(self._edit.value).replace(";", ",").split(",")])
            except ValueError:
                app._say(f"edit refused: give {app.robot.nq} numbers in deg, separated by commas")
                return
            try:
                app.edit(i, q)
                app._say(f"waypoint {i + 1} edited")
            except RobointelError as exc:
                app._say(f"edit refused: {exc}")

        @b_here.on_click
        def _here(_e: Any) -> None:
            i = selected("replace")
            if i is not None:
                self._act("replace", app.edit, i, app.reference())

        @b_del.on_click
        def _del(_e: Any) -> None:
            i = selected("delete")
            if i is not None:
                self._act("delete", app.delete, i)
                app._say(f"deleted waypoint {i + 1}")

        @b_play.on_click
        def _play(_e: Any) -> None:
            if not app.replaying:
                threading.Thread(target=app.replay, daemon=True).start()

        @b_clear.on_click
        def _clear(_e: Any) -> None:
            app.clear()
            app._say("cleared")

        @b_save.on_click
        def _save(_e: Any) -> None:
            self._act("save", app.save)

    def hand_pose(self) -> np.ndarray:
        """The session's hand gizmo as a 4x4 pose (for tests and tools)."""
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = quat_matrix(np.array(self._hand.wxyz)), np.array(self._hand.position)
        return T
