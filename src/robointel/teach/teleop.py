"""Browser teleoperation (Ch. 3.4): a ``viser`` page replaces the VR headset.

The page shows the robot (its URDF collision primitives, posed from the simulated joints), the
table and the obstacles. A transform gizmo is the operator's hand: every move is solved by IK
(closest to the current target); a reachable pose is streamed to the robot through the same
validated path as the WebSocket interface (:class:`~robointel.teach.streaming.StreamingController`),
an unreachable one is shown in red and **not sent**. The hand can also be typed as a position
(m) and roll/pitch/yaw (deg). Buttons record the current target as a waypoint, replay the recorded
program on the robot, clear it, and save it as a YAML scene (robot, obstacles, waypoints) that
``robointel plan`` loads (:func:`save_program` / :func:`load_program`).

While a target is live and a page is connected, the app keeps streaming it at ``stream_hz``, so the
controller's deadman (100 ms) stops the robot when the page closes or its link stalls.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel._extras import needs_extra
from robointel._validate import as_array
from robointel.errors import IKFailure, InvalidInput
from robointel.robot import Robot
from robointel.teach.streaming import StreamingController, check_bind
from robointel.teach.teleop_program import (  # noqa: F401 (the page's file API)
    PROGRAM_FORMAT,
    load_program,
    save_program,
    shape_to_dict,
)


# ----------------------------------------------------------------------------- the page
def _quat_wxyz(R: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z])


def _matrix(wxyz: npt.ArrayLike) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    w, x, y, z = np.asarray(wxyz, float)
    return Rotation.from_quat([x, y, z, w]).as_matrix()


class TeleopApp:
    """The teleoperation page on a streaming controller.

    Args:
        controller: a started or not yet started :class:`StreamingController` (owns the robot).
        host: where the page is served (127.0.0.1 by default; others need ``token``, which must
            then be typed into the page's token field before anything is sent).
        port: the page's port.
        obstacles: robointel.geometry shapes drawn in the scene and saved with the program.
        program_path: where "Save" writes the program.
        stream_hz: keep-alive streaming rate of the live target.
        reach_tol: joint distance [rad] at which a replayed waypoint counts as reached.
    """

    def __init__(self, controller: StreamingController, *, host: str = "127.0.0.1", port: int = 8080,
                 obstacles: Sequence[Any] = (), program_path: str | Path = "teleop_program.yaml",
                 stream_hz: float = 50.0, reach_tol: float = 2e-3, token: str | None = None) -> None:
        check_bind(host, token)
        if not 0 <= int(port) <= 65535:
            raise InvalidInput(f"port must be in 0..65535, got {port}", value=port)
        self.controller = controller
        r = controller.robot
        self.robot = Robot(r.urdf, name=r.name, urdf_path=r.urdf_path, flange_frame=r.flange_frame, tool=r.tool)
        self.host, self.port, self.token = host, int(port), token
        self.obstacles = list(obstacles)
        self.program_path = Path(program_path)
        self.stream_hz = float(stream_hz)
        self.reach_tol = float(reach_tol)
        self.waypoints: list[np.ndarray] = []
        self.desired: np.ndarray | None = None
        self.reachable = True
        self.sent = 0
        self.unreachable_moves = 0
        self.replaying = False
        self._lock = threading.RLock()
        self._running = False
        self._threads: list[threading.Thread] = []
        self.server: Any = None  # the viser.ViserServer once started
        self._wp_handles: list[Any] = []
        self._links: dict[str, Any] = {}
        self._syncing = False
        self._authed = token is None
        self.client = "teleop-page"  # the page's client id at the controller (it acquires control to move)
        self.refused = 0
        self.last_error: str | None = None

    # ------------------------------------------------------------------ logic (no browser needed)
    def move_hand(self, position: npt.ArrayLike, wxyz: npt.ArrayLike) -> bool:
        """The operator's hand moved: IK closest to the current target; stream it when reachable.

        Args:
            position: (3,) hand position, m, robot root frame.
            wxyz: (4,) hand orientation quaternion [w, x, y, z].

        Returns:
            Whether the pose is reachable and was accepted (unreachable poses are never sent).

        Raises:
            ShapeError, NotFinite: bad position or quaternion.
        """
        p = as_array(position, "position", (3,))
        R = _matrix(as_array(wxyz, "wxyz", (4,)))
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, p
        with self._lock:
            ref = self.desired if self.desired is not None else self.controller.q_ref
            try:
                q = self.robot.ik(T, q_ref=ref)[0]
            except IKFailure:
                self.reachable = False
                self.unreachable_moves += 1
                self._show_reachability(False)
                return False
            self.reachable = True
            if not self.replaying:
                if not self._send(q):  # refused (table, floor, self-collision, control): not kept either
                    self._show_reachability(False)
                    return False
                self.desired = q
        self._show_reachability(True)
        return True

    def _send(self, q: npt.ArrayLike) -> bool:
        """Stream a joint target through the controller's checks; True when the controller accepted it.

        The checks: control, latch, limits, table, floor and self-collision; a refusal is shown on
        the page and nothing moves.
        """
        if not self._authed:
            return False
        if self.controller.owner != self.client:
            reply = self.controller.submit({"type": "acquire"}, client=self.client)
            if reply is not None and reply["type"] == "error":
                self.last_error = reply["message"]
                self._status(f"not sent: {reply['message']}")
                return False
        reply = self.controller.submit({"type": "joint_target", "q": [float(v) for v in np.asarray(q, float)]},
                                       client=self.client)
        if reply is None:
            self.sent += 1
            return True
        self.refused += 1
        self.last_error = reply["message"]
        self._status(f"not sent ({reply['code']}): {reply['message']}")
        return False

    def record(self) -> int:
        """Record the current target (or the robot's pose) as a waypoint; returns the count."""
        with self._lock:
            q = self.desired if self.desired is not None else self.controller.measured()[1]
            self.waypoints.append(np.array(q, float))
            n = len(self.waypoints)
        self._refresh_gui()
        return n

    def clear(self) -> None:
        """Forget the recorded waypoints."""
        with self._lock:
            self.waypoints.clear()
        self._refresh_gui()

    def save(self, path: str | Path | None = None) -> Path:
        """Save the recorded program with :func:`save_program` (default: ``program_path``); returns the path.

        Raises:
            InvalidInput: fewer than 2 waypoints.
        """
        p = save_program(path or self.program_path, self.robot, self.waypoints, obstacles=self.obstacles)
        self._status(f"saved {len(self.waypoints)} waypoints to {p} (robointel plan {p})")
        return p

    def replay(self, *, timeout_per_waypoint: float = 10.0, dwell: float = 0.2) -> list[float]:
        """Drive the robot through the recorded waypoints (streaming each until reached).

        Args:
            timeout_per_waypoint: the longest time spent streaming one waypoint, s.
            dwell: time a waypoint must stay reached before the next, s.

        Returns:
            The joint error (max over joints), rad, at each waypoint when it was left.
        """
        with self._lock:
            program = [w.copy() for w in self.waypoints]
            self.replaying = True
        errors = []
        try:
            for i, w in enumerate(program):
                self._status(f"replay: waypoint {i + 1}/{len(program)}")
                t_end = time.monotonic() + timeout_per_waypoint
                reached_at = None
                while time.monotonic() < t_end:
                    with self._lock:
                        self.desired = w
                    self._send(w)
                    err = float(np.max(np.abs(self.controller.measured()[1] - w)))
                    if err < self.reach_tol and reached_at is None:
                        reached_at = time.monotonic()
                    if reached_at is not None and time.monotonic() - reached_at >= dwell:
                        break
                    time.sleep(1.0 / self.stream_hz)
                errors.append(float(np.max(np.abs(self.controller.measured()[1] - w))))
            self._status(f"replayed {len(program)} waypoints, max error {max(errors, default=0.0):.2e} rad")
        finally:
            with self._lock:
                self.replaying = False
        return errors

    # ------------------------------------------------------------------ page
    def _show_reachability(self, ok: bool) -> None:
        if self.server is None:
            return
        self._bad.visible = not ok
        self._reach_text.value = "reachable: streaming" if ok else "UNREACHABLE: not sent"

    def _status(self, text: str) -> None:
        if self.server is not None:
            self._status_text.value = text

    def _refresh_gui(self) -> None:
        if self.server is None:
            return
        with self._lock:
            pts = [self.robot.fk(w)[:3, 3] for w in self.waypoints]
        self._count.value = str(len(pts))
        for h in self._wp_handles:
            h.remove()
        self._wp_handles = [self.server.scene.add_icosphere(f"/waypoints/{i}", radius=0.015, color=(30, 110, 250),
                                                            position=p) for i, p in enumerate(pts)]

    def _build_scene(self) -> None:
        with needs_extra("teleop", "browser teleoperation"):
            import viser

        s = self.server
        s.scene.add_grid("/table", width=1.6, height=1.6, cell_size=0.1, section_size=0.5, position=(0.3, 0, 0))
        self._links = {}
        colors = [(240, 200, 40), (200, 200, 200), (240, 200, 40), (200, 200, 200), (240, 200, 40), (90, 90, 90)]
        for k, (link, prims) in enumerate(self.robot.collision_primitives().items()):
            frame = s.scene.add_frame(f"/robot/{link}", show_axes=False)
            self._links[link] = frame
            for i, pr in enumerate(prims):
                pos, wxyz = pr["origin"][:3, 3], _quat_wxyz(pr["origin"][:3, :3])
                c = colors[k % len(colors)]
                name = f"/robot/{link}/g{i}"
                if pr["type"] == "box":
                    s.scene.add_box(name, color=c, dimensions=tuple(pr["size"]), position=pos, wxyz=wxyz)
                elif pr["type"] in ("cylinder", "capsule"):
                    s.scene.add_cylinder(name, radius=float(pr["size"][0]), height=float(pr["size"][1]), color=c,
                                         position=pos, wxyz=wxyz)
                elif pr["type"] == "sphere":
                    s.scene.add_icosphere(name, radius=float(pr["size"][0]), color=c, position=pos)
        for j, o in enumerate(self.obstacles):
            d = shape_to_dict(o)
            name = f"/obstacles/{d['name']}_{j}"
            if d["type"] == "sphere":
                s.scene.add_icosphere(name, radius=d["radius"], color=(220, 60, 60), position=d["center"], opacity=0.6)
            elif d["type"] == "box":
                s.scene.add_box(name, color=(220, 60, 60), dimensions=tuple(d["size"]), position=d["center"],
                                wxyz=_quat_wxyz(np.array(d.get("rotation", np.eye(3)))), opacity=0.6)
            elif d["type"] in ("capsule", "cylinder"):
                a, b = np.array(d["a"]), np.array(d["b"])
                axis = b - a
                L = float(np.linalg.norm(axis))
                from scipy.spatial.transform import Rotation

                rot, _ = Rotation.align_vectors([axis / max(L, 1e-9)], [[0, 0, 1.0]])
                x, y, z, w = rot.as_quat()
                s.scene.add_cylinder(name, radius=d["radius"], height=L, color=(220, 60, 60),
                                     position=0.5 * (a + b), wxyz=(w, x, y, z), opacity=0.6)
        T = self.robot.fk(self.controller.measured()[1])
        self._hand = s.scene.add_transform_controls("/hand", scale=0.18, position=T[:3, 3], wxyz=_quat_wxyz(T[:3, :3]))
        self._bad = s.scene.add_icosphere("/hand/unreachable", radius=0.035, color=(255, 0, 0), opacity=0.7,
                                          visible=False)
        self._wp_handles = []

        @self._hand.on_update
        def _on_hand(_event: Any) -> None:
            if self._syncing:
                return
            self.move_hand(np.array(self._hand.position), np.array(self._hand.wxyz))
            self._syncing = True
            try:
                self._pos_in.value = tuple(np.round(np.array(self._hand.position), 4))
            finally:
                self._syncing = False

        g = s.gui
        g.add_markdown("**robointel teleoperation** - drag the gizmo (your hand) or type a pose.")
        if self.token is not None:
            tok = g.add_text("Token", "")

            @tok.on_update
            def _on_token(_e: Any) -> None:
                import hmac

                self._authed = self.token is not None and hmac.compare_digest(tok.value, self.token)
                self._status("token accepted" if self._authed else "wrong token: nothing is sent")
        self._pos_in = g.add_vector3("Hand position [m]", tuple(np.round(T[:3, 3], 4)), step=0.001)
        self._reach_text = g.add_text("IK", "reachable", disabled=True)
        self._count = g.add_text("Waypoints", "0", disabled=True)
        self._status_text = g.add_text("Status", "ready", disabled=True)
        b_rec = g.add_button("Record waypoint")
        b_play = g.add_button("Replay")
        b_clear = g.add_button("Clear")
        b_save = g.add_button("Save program")

        @self._pos_in.on_update
        def _on_position(_event: Any) -> None:
            if self._syncing:
                return
            p = np.array(self._pos_in.value, float)
            self._syncing = True
            try:
                self._hand.position = tuple(p)
            finally:
                self._syncing = False
            self.move_hand(p, np.array(self._hand.wxyz))

        @b_rec.on_click
        def _on_record(_e: Any) -> None:
            n = self.record()
            self._status(f"recorded waypoint {n}")

        @b_play.on_click
        def _on_replay(_e: Any) -> None:
            if not self.replaying:
                threading.Thread(target=self.replay, daemon=True).start()

        @b_clear.on_click
        def _on_clear(_e: Any) -> None:
            self.clear()
            self._status("cleared")

        @b_save.on_click
        def _on_save(_e: Any) -> None:
            try:
                self.save()
            except InvalidInput as exc:
                self._status(f"not saved: {exc}")

        _ = viser  # imported for its side effects on failure reporting

    def _display_loop(self) -> None:
        while self._running:
            q = self.controller.measured()[1]
            poses = self.robot.link_poses(q)
            with self.server.atomic():
                for link, frame in self._links.items():
                    T = poses[link]
                    frame.position = T[:3, 3]
                    frame.wxyz = _quat_wxyz(T[:3, :3])
            time.sleep(1 / 30)

    def _stream_loop(self) -> None:
        """Keep the live target alive while a browser is connected.

        When the last page closes (or its link dies) the stream stops and the controller's deadman
        brings the robot to rest.
        """
        while self._running:
            with self._lock:
                q = None if (self.replaying or self.desired is None) else self.desired.copy()
            if q is not None and self.server is not None and len(self.server.get_clients()) > 0:
                self._send(q)
            time.sleep(1.0 / self.stream_hz)

    def start(self) -> TeleopApp:
        """Serve the page (viser), start the controller's control thread and the display and stream threads."""
        with needs_extra("teleop", "browser teleoperation"):
            import viser

        self._syncing = False
        self.server = viser.ViserServer(host=self.host, port=self.port, verbose=False)
        self.port = self.server.get_port()
        self.controller.start()
        self._build_scene()
        self._running = True
        for fn in (self._display_loop, self._stream_loop):
            t = threading.Thread(target=fn, daemon=True)
            t.start()
            self._threads.append(t)
        return self

    @property
    def url(self) -> str:
        """The page's address."""
        return f"http://{self.host}:{self.port}"

    def stop(self) -> None:
        """Stop the display and stream threads (the controller and the page server keep running)."""
        self._running = False
        for t in self._threads:
            t.join(timeout=2.0)
        self._threads.clear()
        if self.server is not None:
            self.server.stop()
            self.server = None
        self.controller.release(self.client)
