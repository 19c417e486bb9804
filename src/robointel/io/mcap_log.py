"""Record a robot run as a ROS 2 bag in MCAP, written as the run goes (``mcap`` writer, ``rosbags`` types; no ROS).

The file opens in Foxglove, ``ros2 bag`` and the ``mcap`` reader.

Topics (ROS 2 Humble message definitions, CDR):

- ``/joint_states`` -- ``sensor_msgs/msg/JointState``: measured position (rad) and velocity (rad/s);
- ``/ft_sensor/wrench`` -- ``geometry_msgs/msg/WrenchStamped``: measured wrench (N, N m), when there is one;
- ``/joint_command`` -- ``sensor_msgs/msg/JointState``: every joint position command sent (rad);
- ``/planned_trajectory`` -- ``trajectory_msgs/msg/JointTrajectory``: each trajectory executed.

Header stamps are the robot's clock (simulated time for ``sim``); the bag's log time is wall time.

Crash safety: the control loop only appends each message to a list; a writer thread serialises
them and writes them to the file in chunks, closing a chunk at least every ``flush_s`` (0.5 s by
default), so a process killed outright (SIGKILL, power cut of the process) loses at most the last
``flush_s`` plus the writer's wake-up (0.1 s) and leaves a file whose complete chunks
:func:`read_recording` (and Foxglove) read; :meth:`McapRecorder.close` (also on Ctrl-C) writes the
rest and the summary. The file is created with the first message (or :meth:`McapRecorder.start`),
never by the constructor, which only checks the path.
"""
from __future__ import annotations

import collections
import threading
import time
from pathlib import Path
from struct import error as struct_error
from types import TracebackType
from typing import IO, TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robointel._extras import optional_module
from robointel.errors import InvalidInput

if TYPE_CHECKING:
    from mcap import exceptions as mcap_exceptions
    from mcap import records as mcap_records
    from mcap import stream_reader as mcap_stream_reader
    from mcap import writer as mcap_writer
    from rosbags import typesys
else:
    _why = "recording a run as a ROS 2 bag"
    mcap_exceptions = optional_module("mcap.exceptions", "datasets", _why)
    mcap_records = optional_module("mcap.records", "datasets", _why)
    mcap_stream_reader = optional_module("mcap.stream_reader", "datasets", _why)
    mcap_writer = optional_module("mcap.writer", "datasets", _why)
    typesys = optional_module("rosbags.typesys", "datasets", _why)

JOINT_STATES = "/joint_states"
WRENCH = "/ft_sensor/wrench"
COMMAND = "/joint_command"
TRAJECTORY = "/planned_trajectory"

_JS, _WS, _JT = "sensor_msgs/msg/JointState", "geometry_msgs/msg/WrenchStamped", "trajectory_msgs/msg/JointTrajectory"


TYPES = {JOINT_STATES: _JS, COMMAND: _JS, WRENCH: _WS, TRAJECTORY: _JT}
FLUSH_S = 0.5  # s between chunk flushes (at most)
_WAKE_S = 0.1  # s between wake-ups of the writer thread


class McapRecorder:
    """Collect states, commands and trajectories of a run; write them to one ``.mcap`` file as the run goes.

    Args:
        path: output file (``.mcap``); its directory must exist.
        joint_names: n joint names for the JointState / JointTrajectory messages.
        frame_id: frame of the wrench messages.
        flush_s: the longest time, s, a message waits before it is in a complete chunk on disk.

    Raises:
        InvalidInput: the path does not end in ``.mcap``, its directory does not exist, it is a
            directory, or ``flush_s`` is not in (0, 10] s (nothing is created then).
        MissingExtra: mcap or rosbags is not installed (the ``datasets`` extra).
    """

    def __init__(self, path: str | Path, joint_names: list[str], *, frame_id: str = "ft_sensor",
                 flush_s: float = FLUSH_S) -> None:
        self.path = Path(path)
        if self.path.suffix != ".mcap" or not self.path.parent.is_dir() or self.path.is_dir():
            raise InvalidInput(f"record path must be a .mcap file in an existing directory, got {path}",
                               value=str(path))
        if not (isinstance(flush_s, int | float) and 0.0 < flush_s <= 10.0):
            raise InvalidInput(f"flush_s must be in (0, 10] s, got {flush_s!r}", value=flush_s)
        self.joint_names = list(joint_names)
        self.frame_id = frame_id
        self.flush_s = float(flush_s)
        self._items: collections.deque[tuple[str, int, Any]] = collections.deque()
        self._lock = threading.Lock()  # the writer (file, channels, counts)
        self._ts = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
        self._closed = False
        self._file: IO[bytes] | None = None
        self._writer: mcap_writer.Writer | None = None
        self._channels: dict[str, int] = {}
        self._thread: threading.Thread | None = None
        self._wake = threading.Event()
        self._last_flush = 0.0
        self.error: BaseException | None = None  # why the writer thread stopped, if it did
        self.counts: dict[str, int] = {}

    # ------------------------------------------------------------------ the Recorder protocol
    def joint_state(self, state: Any) -> None:
        """Queue a state (``t``, ``q``, ``qd``, optional ``wrench``) for /joint_states and the wrench topic."""
        now = time.time_ns()
        self._items.append((JOINT_STATES, now, (state.t, np.array(state.q), np.array(state.qd))))
        if state.wrench is not None:
            self._items.append((WRENCH, now, (state.t, np.array(state.wrench))))
        self._started()

    def command(self, t: float, q: npt.NDArray[np.float64]) -> None:
        """Queue a joint position command (n,) rad sent at robot time ``t`` s."""
        self._items.append((COMMAND, time.time_ns(), (t, np.array(q))))
        self._started()

    def trajectory(self, t: float, trajectory: Any) -> None:
        """Queue a trajectory (``t``, ``q``, ``qd``, ``qdd`` arrays) started at robot time ``t`` s."""
        self._items.append((TRAJECTORY, time.time_ns(),
                            (t, np.array(trajectory.t), np.array(trajectory.q), np.array(trajectory.qd),
                             np.array(trajectory.qdd))))
        self._started()

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
    def _started(self) -> None:
        if self._thread is None and not self._closed:
            self.start()

    def start(self) -> McapRecorder:
        """Create the file and start the writer thread (the first message does it otherwise); idempotent.

        Raises:
            InvalidInput: the recorder was closed.
        """
        with self._lock:
            if self._closed:
                raise InvalidInput(f"the recording {self.path} is closed", value=str(self.path))
            if self._thread is not None:
                return self
            self._file = open(self.path, "wb")  # noqa: SIM115 - closed in close()
            self._writer = mcap_writer.Writer(self._file, chunk_size=256 * 1024)
            self._writer.start(profile="ros2", library="robointel")
            self._last_flush = time.monotonic()
            self._thread = threading.Thread(target=self._run, name="robointel-mcap", daemon=True)
            self._thread.start()
        return self

    def _channel(self, topic: str) -> int:
        assert self._writer is not None
        if topic not in self._channels:
            typ = TYPES[topic]
            text, _ = self._ts.generate_msgdef(typ, ros_version=2)
            sid = self._writer.register_schema(typ, "ros2msg", text.encode())
            self._channels[topic] = self._writer.register_channel(topic, "cdr", sid)
        return self._channels[topic]

    def _drain(self, force_flush: bool) -> None:
        """Serialise and write the queued messages; close the chunk when ``flush_s`` has passed (or forced)."""
        with self._lock:
            if self._writer is None:
                return
            k = 0
            while self._items:
                topic, stamp, data = self._items.popleft()
                raw = self._ts.serialize_cdr(self._message(topic, data), TYPES[topic])
                self._writer.add_message(self._channel(topic), log_time=stamp, data=bytes(raw), publish_time=stamp)
                self.counts[topic] = self.counts.get(topic, 0) + 1
                k += 1
                if k % 16 == 0:  # let the control thread in (~1 ms of serialising at a time)
                    self._lock.release()
                    time.sleep(0)
                    self._lock.acquire()
                    if self._writer is None:
                        return
            now = time.monotonic()
            if force_flush or now - self._last_flush >= self.flush_s:
                self._writer.flush()
                self._last_flush = now

    def _run(self) -> None:
        while not self._closed:
            self._wake.wait(_WAKE_S)
            self._wake.clear()
            try:
                self._drain(False)
            except BaseException as exc:  # noqa: BLE001 - kept, reported by close()
                self.error = exc
                return

    def flush(self) -> Path:
        """Write everything queued so far as complete chunks now; return the path."""
        if self._thread is None and not self._items:
            return self.path
        self._started()
        self._drain(True)
        return self.path

    def close(self) -> Path:
        """Write the rest and the file's summary, stop recording (idempotent); return the path.

        A recorder that never got a message creates an empty recording (no messages).
        """
        if self._closed:
            return self.path
        if self._thread is None:
            self.start()
        self._closed = True
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        try:
            self._drain(True)
        finally:
            with self._lock:
                if self._writer is not None:
                    self._writer.finish()
                    self._writer = None
                if self._file is not None:
                    self._file.close()
                    self._file = None
        return self.path

    def __enter__(self) -> McapRecorder:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def read_recording(path: str | Path) -> dict[str, list[tuple[int, Any]]]:
    """Read the messages of a recording, also of one cut short (a process killed while recording).

    Records are read in file order up to the end or up to a record that is cut short; complete
    chunks before it are all read.

    Args:
        path: the ``.mcap`` file.

    Returns:
        topic -> ``[(log time ns, message)]`` (deserialised ROS 2 messages) in file order.

    Raises:
        DataMissing: no such file.
        InvalidInput: not an MCAP file.
    """
    from robointel.errors import DataMissing

    path = Path(path)
    if not path.is_file():
        raise DataMissing(f"recording {path} does not exist", value=str(path))
    ts = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}
    out: dict[str, list[tuple[int, Any]]] = {}
    with open(path, "rb") as f:
        try:
            for rec in mcap_stream_reader.StreamReader(f, skip_magic=False, emit_chunks=False).records:
                if isinstance(rec, mcap_records.Schema):
                    schemas[rec.id] = rec.name
                elif isinstance(rec, mcap_records.Channel):
                    channels[rec.id] = (rec.topic, schemas.get(rec.schema_id, ""))
                elif isinstance(rec, mcap_records.Message) and rec.channel_id in channels:
                    topic, typ = channels[rec.channel_id]
                    out.setdefault(topic, []).append((rec.log_time, ts.deserialize_cdr(rec.data, typ)))
        except (mcap_exceptions.McapError, EOFError, ValueError, struct_error) as exc:
            if not schemas:
                raise InvalidInput(f"{path} is not an MCAP recording ({type(exc).__name__}: {exc})",
                                   value=str(path)) from None
    return out
