"""Runs recorded as ROS 2 bags in MCAP read back with the ``mcap`` reader (sim and fanuc backends)."""
import time

import numpy as np
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_typestore

from robointel.interface import open_robot
from robointel.io.mcap_log import COMMAND, JOINT_STATES, TRAJECTORY, WRENCH, McapRecorder
from robointel.testing.emulator import fanuc_url, running_fake


def _read(path):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    topics, msgs = {}, {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        schemas = {c.topic: s.name for s, c in
                   ((reader.get_summary().schemas[c.schema_id], c) for c in reader.get_summary().channels.values())}
        for schema, channel, message in reader.iter_messages():
            topics[channel.topic] = topics.get(channel.topic, 0) + 1
            msgs.setdefault(channel.topic, []).append(ts.deserialize_cdr(message.data, schema.name))
    return topics, schemas, msgs


def test_sim_run_reads_back(tmp_path, frmp_segment):
    tr = frmp_segment
    path = tmp_path / "run.mcap"
    rec = McapRecorder(path, [f"joint_{i + 1}" for i in range(6)])
    with open_robot("sim", recorder=rec, q0=tr.q[0]) as robot:
        res = robot.execute(tr)
    rec.close()
    topics, schemas, msgs = _read(path)
    K = len(res.q_cmd)
    assert topics == {JOINT_STATES: K, WRENCH: K, COMMAND: K, TRAJECTORY: 1}
    assert schemas[JOINT_STATES] == "sensor_msgs/msg/JointState"
    assert schemas[WRENCH] == "geometry_msgs/msg/WrenchStamped"
    assert schemas[TRAJECTORY] == "trajectory_msgs/msg/JointTrajectory"
    np.testing.assert_allclose(np.array([m.position for m in msgs[COMMAND]]), res.q_cmd)
    traj = msgs[TRAJECTORY][0]
    assert len(traj.points) == len(tr.t) and list(traj.joint_names) == rec.joint_names
    np.testing.assert_allclose(traj.points[-1].positions, tr.q[-1])


def test_fanuc_run_reads_back(tmp_path):
    path = tmp_path / "fanuc.mcap"
    rec = McapRecorder(path, [f"joint_{i + 1}" for i in range(6)])
    with running_fake() as fake:
        with open_robot(fanuc_url(fake), recorder=rec) as robot:
            q0 = robot.state().q
            t0 = time.perf_counter()
            for k in range(50):
                robot.stream(q0 + 1e-3 * k)
                time.sleep(max(0.0, t0 + (k + 1) * 0.008 - time.perf_counter()))
            robot.hold()
        assert fake.violations == []
    rec.close()
    topics, _, msgs = _read(path)
    assert topics == {JOINT_STATES: 50, COMMAND: 50}  # v3 Stream Motion carries no wrench
    np.testing.assert_allclose(msgs[COMMAND][-1].position, q0 + 0.049)
