"""A trajectory player in the browser for any arm: viser's URDF viewer (``robointel view TRAJ --robot URDF``).

The arm's URDF (its visual meshes, or the collision geometry when it has none) is drawn by
:class:`viser.extras.ViserUrdf`; the trajectory plays in real time (or ``speed`` times it), looped, with a
play/pause button and a time slider in the page. Obstacles (boxes and spheres of a scene) are drawn beside.
The server binds 127.0.0.1 only.
"""
from __future__ import annotations

import io
import threading
import time
from collections.abc import Sequence
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from robointel._extras import optional_module
from robointel.errors import DescriptionError, InvalidInput
from robointel.geometry.obstacles import Box, Sphere
from robointel.geometry.rotations import matrix_to_quat
from robointel.trajectory import Trajectory

if TYPE_CHECKING:
    import viser
    import viser.extras
    import yourdfpy
else:
    viser = optional_module("viser", "teleop", "the trajectory viewer")
    optional_module("viser.extras", "teleop", "the trajectory viewer")  # viser.extras.ViserUrdf
    yourdfpy = optional_module("yourdfpy", "teleop", "the trajectory viewer")

__all__ = ["TrajectoryViewer"]

#: frames per second of the playback
FPS = 30.0


class TrajectoryViewer:
    """Play a joint trajectory on a URDF in the browser.

    Args:
        robot: The :class:`robointel.robot.Robot` (its ``urdf_path`` or URDF text is drawn).
        trajectory: The trajectory; its joint names pick the URDF's joints (others stay at 0, or the
            middle of their limits when 0 is outside them).
        obstacles: Boxes and spheres to draw (other shapes are skipped).
        port: TCP port on 127.0.0.1 (0: a free port).
        speed: Playback speed (1: real time).
        loop: Start over at the end.

    Raises:
        InvalidInput: a trajectory whose joints the URDF lacks, a bad speed or port.
        DescriptionError: the URDF cannot be loaded for drawing.
    """

    def __init__(self, robot: Any, trajectory: Trajectory, *, obstacles: Sequence[Any] = (), port: int = 8081,
                 speed: float = 1.0, loop: bool = True) -> None:
        if not (np.isfinite(speed) and speed > 0):
            raise InvalidInput(f"speed must be > 0, got {speed!r}", value=speed)
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise InvalidInput(f"port must be in [0, 65535], got {port!r}", value=port)
        self.trajectory, self.speed, self.loop = trajectory, float(speed), bool(loop)
        urdf = self._load(robot)
        names = list(urdf.actuated_joint_names)
        missing = [n for n in trajectory.joint_names if n not in names]
        if missing:
            raise InvalidInput(f"the trajectory's joints {missing} are not joints of {robot.name!r} ({names})",
                               value=missing)
        self._cols = [trajectory.joint_names.index(n) if n in trajectory.joint_names else -1 for n in names]
        rest = []
        for j in urdf.actuated_joints:
            lo = j.limit.lower if j.limit is not None and j.limit.lower is not None else -np.pi
            hi = j.limit.upper if j.limit is not None and j.limit.upper is not None else np.pi
            rest.append(0.0 if lo <= 0.0 <= hi else 0.5 * (lo + hi))
        self._rest = np.array(rest, float)
        self.server = viser.ViserServer(host="127.0.0.1", port=port, verbose=False)
        self.url = f"http://127.0.0.1:{self.server.get_port()}"
        self._urdf = viser.extras.ViserUrdf(self.server, urdf, root_node_name="/robot",
                               load_meshes=urdf.scene is not None, load_collision_meshes=urdf.scene is None)
        self.server.scene.add_grid("/table", width=2.0, height=2.0, position=(0.3, 0.0, 0.0))
        for k, o in enumerate(obstacles):
            name = f"/obstacles/{getattr(o, 'name', None) or k}"
            if isinstance(o, Box):
                self.server.scene.add_box(name, color=(200, 80, 60), dimensions=tuple(np.asarray(o.size, float)),
                                          position=tuple(np.asarray(o.center, float)), opacity=0.6,
                                          wxyz=tuple(matrix_to_quat(np.asarray(o.rotation, float))))
            elif isinstance(o, Sphere):
                self.server.scene.add_icosphere(name, radius=float(o.radius), color=(200, 80, 60), opacity=0.6,
                                                position=tuple(np.asarray(o.center, float)))
        T = float(trajectory.t[-1] - trajectory.t[0])
        self._play = self.server.gui.add_checkbox("play", initial_value=True)
        self._slider = self.server.gui.add_slider("t [s]", min=0.0, max=max(T, 1e-3), step=0.01, initial_value=0.0)
        self.duration = T
        self.frames = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="trajectory-player", daemon=True)
        self.show(0.0)
        self._thread.start()

    @staticmethod
    def _load(robot: Any) -> Any:
        """The robot's URDF as a yourdfpy model with its meshes (collision geometry only when meshes are missing)."""
        path = getattr(robot, "urdf_path", None)
        try:
            if path is not None and Path(path).is_file():
                handler = partial(_find_mesh, base=Path(path).resolve().parent)
                try:
                    return yourdfpy.URDF.load(str(path), filename_handler=handler, build_collision_scene_graph=True,
                                              load_collision_meshes=True)
                except (OSError, ValueError):  # a visual mesh it cannot read: draw the collision geometry
                    return yourdfpy.URDF.load(str(path), filename_handler=handler, load_meshes=False,
                                              build_scene_graph=False, build_collision_scene_graph=True,
                                              load_collision_meshes=True)
            return yourdfpy.URDF.load(io.StringIO(robot.urdf), build_collision_scene_graph=True,
                                      load_collision_meshes=True)
        except Exception as exc:  # yourdfpy raises many kinds; the user gets one message naming the file
            raise DescriptionError(f"cannot draw the URDF of {robot.name!r} ({path}): {exc}", value=str(path)) from None

    def configuration(self, t: float) -> np.ndarray:
        """The URDF's actuated joints (in its order) at trajectory time ``t`` (s after the start)."""
        tr = self.trajectory
        q = np.array([np.interp(tr.t[0] + t, tr.t, tr.q[:, c]) if c >= 0 else 0.0 for c in self._cols])
        return np.where(np.array(self._cols) >= 0, q, self._rest)

    def show(self, t: float) -> None:
        """Draw the arm at trajectory time ``t`` (s)."""
        self._urdf.update_cfg(self.configuration(float(np.clip(t, 0.0, self.duration))))
        self.frames += 1

    def _run(self) -> None:
        t, last = 0.0, time.perf_counter()
        while not self._stop.wait(1.0 / FPS):
            now = time.perf_counter()
            if self._play.value:
                t = float(self._slider.value) + (now - last) * self.speed
                if t > self.duration:
                    t = 0.0 if self.loop else self.duration
                self._slider.value = t  # type: ignore[misc]
            self.show(float(self._slider.value))
            last = now

    def close(self) -> None:
        """Stop the playback and the server (idempotent)."""
        if not self._stop.is_set():
            self._stop.set()
            self._thread.join(timeout=2.0)
            self.server.stop()



def _find_mesh(fname: str, base: Path) -> str:
    """A mesh path of the URDF resolved next to it, or the name unchanged when nothing is found.

    ``package://pkg/rel`` is looked for as ``rel`` or ``pkg/rel`` in the URDF's folder or a parent; ``file://``
    and relative paths next to the URDF.
    """
    name = fname[len("file://"):] if fname.startswith("file://") else fname
    if name.startswith("package://"):
        rel = name[len("package://"):]
        for d in (base, *base.parents):
            for cand in (d / rel, d / rel.split("/", 1)[-1]):
                if cand.is_file():
                    return str(cand)
        return fname
    q = Path(name)
    q = q if q.is_absolute() else base / q
    return str(q) if q.is_file() else fname
