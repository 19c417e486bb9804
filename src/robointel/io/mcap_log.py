"""Record a robot run as a ROS 2 bag in MCAP (``rosbags``; no ROS install).

The file opens in Foxglove, ``ros2 bag`` and the ``mcap`` reader.

Topics (ROS 2 Humble message definitions, CDR):

- ``/joint_states`` -- ``sensor_msgs/msg/JointState``: measured position (rad) and velocity (rad/s);
- ``/ft_sensor/wrench`` -- ``geometry_msgs/msg/WrenchStamped``: measured wrench (N, N m), when there is one;
- ``/joint_command`` -- ``sensor_msgs/msg/JointState``: every joint position command sent (rad);
- ``/planned_trajectory`` -- ``trajectory_msgs/msg/JointTrajectory``: each trajectory executed.

Header stamps are the robot's clock (simulated time for ``sim``); the bag's log time is wall time.
Messages are buffered in memory and written at :meth:`McapRecorder.close` (or :meth:`flush`), so
recording costs the control loop a list append per message.
"""
from __future__ import annotations

import shutil
import tempfile
import threading
import time
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robointel._extras import optional_module
from robointel.errors import InvalidInput

if TYPE_CHECKING:
    from rosbags import rosbag2, typesys
else:
    rosbag2 = optional_module("rosbags.rosbag2", "datasets", "recording a run as a ROS 2 bag")
    typesys = optional_module("rosbags.typesys", "datasets", "recording a run as a ROS 2 bag")

JOINT_STATES = "/joint_states"
WRENCH = "/ft_sensor/wrench"
COMMAND = "/joint_command"
TRAJECTORY = "/planned_trajectory"

_JS, _WS, _JT = "sensor_msgs/msg/JointState", "geometry_msgs/msg/WrenchStamped", "trajectory_msgs/msg/JointTrajectory"


class McapRecorder:
    """Collect states, commands and trajectories of a run; write one ``.mcap`` file on close.

    Args:
        path: output file (``.mcap``); its directory must exist.
        joint_names: n joint names for the JointState / JointTrajectory messages.
        frame_id: frame of the wrench messages.

    Raises:
        InvalidInput: the path does not end in ``.mcap`` or its directory does not exist.
        MissingExtra: rosbags is not installed (the ``datasets`` extra).
    """

    def __init__(self, path: str | Path, joint_names: list[str], *, frame_id: str = "ft_sensor") -> None:
        self.path = Path(path)
        if self.path.suffix != ".mcap" or not self.path.parent.is_dir():
            raise InvalidInput(f"record path must be a .mcap file in an existing directory, got {path}",
                               value=str(path))
        self.joint_names = list(joint_names)
        self.frame_id = frame_id
        self._items: list[tuple[str, int, Any]] = []
        self._lock = threading.Lock()
        self._ts = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
        self._closed = False
        self.counts: dict[str, int] = {}

    # ------------------------------------------------------------------ the Recorder protocol
    def joint_state(self, state: Any) -> None:
        """Buffer a state (``t``, ``q``, ``qd``, optional ``wrench``) for /joint_states and the wrench topic."""
        now = time.time_ns()
        with self._lock:
            self._items.append((JOINT_STATES, now, (state.t, np.array(state.q), np.array(state.qd))))
            if state.wrench is not None:
                self._items.append((WRENCH, now, (state.t, np.array(state.wrench))))

    def command(self, t: float, q: npt.NDArray[np.float64]) -> None:
        """Buffer a joint position command (n,) rad sent at robot time ``t`` s."""
        with self._lock:
            self._items.append((COMMAND, time.time_ns(), (t, np.array(q))))

    def trajectory(self, t: float, trajectory: Any) -> None:
        """Buffer a trajectory (``t``, ``q``, ``qd``, ``qdd`` arrays) started at robot time ``t`` s."""
        with self._lock:
            self._items.append((TRAJECTORY, time.time_ns(),
                                (t, np.array(trajectory.t), np.array(trajectory.q), np.array(trajectory.qd),
                                 np.array(trajectory.qdd))))

    # ------------------------------------------------------------------ messages
    def _stamp(self, t: float) -> Any:
        T = self._ts.types
        sec = int(np.floor(t))
        return T["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((t - sec) * 1e9)) % 1_000_000_000)

    def _header(self, t: float, frame: str = "") -> Any:
        return self._ts.types["std_msgs/msg/Header"](stamp=self._stamp(t), frame_id=frame)

    def _message(self, topic: str, data: Any) -> Any:
        T = self._ts.types
        if topic in (JOINT_STATES, COMMAND):
            t, q = data[0], data[1]
            qd = data[2] if topic == JOINT_STATES else np.zeros(0)
            return T[_JS](header=self._header(t), name=self.joint_names, position=np.asarray(q, dtype=np.float64),
                          velocity=np.asarray(qd, dtype=np.float64), effort=np.zeros(0))
        if topic == WRENCH:
            t, w = data
            V = T["geometry_msgs/msg/Vector3"]
            return T[_WS](header=self._header(t, self.frame_id),
                          wrench=T["geometry_msgs/msg/Wrench"](force=V(x=float(w[0]), y=float(w[1]), z=float(w[2])),
                                                               torque=V(x=float(w[3]), y=float(w[4]),
                                                                        z=float(w[5]))))
        t, ts, q, qd, qdd = data
        Pt, Dur = T["trajectory_msgs/msg/JointTrajectoryPoint"], T["builtin_interfaces/msg/Duration"]
        pts = []
        for k in range(len(ts)):
            dt = float(ts[k] - ts[0])
            s = int(np.floor(dt))
            pts.append(Pt(positions=q[k].astype(np.float64), velocities=qd[k].astype(np.float64),
                          accelerations=qdd[k].astype(np.float64), effort=np.zeros(0),
                          time_from_start=Dur(sec=s, nanosec=int(round((dt - s) * 1e9)) % 1_000_000_000)))
        return T[_JT](header=self._header(t), joint_names=self.joint_names, points=pts)

    # ------------------------------------------------------------------ output
    def flush(self) -> Path:
        """Write everything buffered so far to :attr:`path` (rewriting it); return the path."""
        with self._lock:
            items = list(self._items)
        types = {JOINT_STATES: _JS, COMMAND: _JS, WRENCH: _WS, TRAJECTORY: _JT}
        with tempfile.TemporaryDirectory(dir=self.path.parent) as tmp:
            bag = Path(tmp) / "bag"
            counts: dict[str, int] = {}
            with rosbag2.Writer(bag, version=9, storage_plugin=rosbag2.StoragePlugin.MCAP) as w:
                conns = {}
                for topic in (JOINT_STATES, WRENCH, COMMAND, TRAJECTORY):
                    if any(it[0] == topic for it in items):
                        conns[topic] = w.add_connection(topic, types[topic], typestore=self._ts)
                for topic, stamp, data in items:
                    msg = self._message(topic, data)
                    w.write(conns[topic], stamp, self._ts.serialize_cdr(msg, types[topic]))
                    counts[topic] = counts.get(topic, 0) + 1
            shutil.move(str(next(bag.glob("*.mcap"))), self.path)
        self.counts = counts
        return self.path

    def close(self) -> Path:
        """Write the file and stop recording (idempotent); return the path."""
        if not self._closed:
            self.flush()
            self._closed = True
        return self.path

    def __enter__(self) -> McapRecorder:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
