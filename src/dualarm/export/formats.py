"""Writers of a time-parameterised trajectory in the formats robots read.

* Baxter SDK: the CSV that ``baxter_examples``' ``joint_trajectory_file_playback`` plays
  (and ``joint_recorder`` writes): ``time``, ``left_s0 .. left_w2``, ``left_gripper``,
  ``right_s0 .. right_w2``, ``right_gripper``; joints in rad, grippers in Baxter's percent
  (0 closed .. 100 open).
* ROS 2: a rosbag2 directory (``metadata.yaml`` and one MCAP file) written with ``rosbags``
  (no ROS install needed): ``/joint_trajectory`` holds one ``trajectory_msgs/msg/JointTrajectory``
  of the 14 arm joints (positions, velocities, accelerations, time_from_start);
  ``/gripper_trajectory`` one of ``left_gripper``, ``right_gripper`` (Baxter's percent);
  ``/joint_states`` a ``sensor_msgs/msg/JointState`` at every sample, for Foxglove and
  ``robot_state_publisher``.
"""

from __future__ import annotations

import csv
import io
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from dualarm.atomic import atomic_open
from dualarm.task import JOINT_COLUMNS
from dualarm.export.retime import Samples

BAXTER_COLUMNS = ("time", *JOINT_COLUMNS[:7], "left_gripper", *JOINT_COLUMNS[7:], "right_gripper")
GRIPPER_NAMES = ("left_gripper", "right_gripper")
TOPICS = {"trajectory": "/joint_trajectory", "gripper": "/gripper_trajectory",
          "states": "/joint_states"}
#: The message definitions of the ROS 2 distribution the bag is written for.
ROS_DISTRIBUTION = "ROS2_JAZZY"


def gripper_percent(closure: np.ndarray) -> np.ndarray:
    """Baxter's gripper position (0 closed .. 100 open) from closure (0 open .. 1 closed)."""
    return 100.0 * (1.0 - np.clip(closure, 0.0, 1.0))


def write_baxter_csv(path: str | Path, samples: Samples) -> None:
    """The Baxter SDK joint trajectory file (``BAXTER_COLUMNS``), atomically."""
    grip = gripper_percent(samples.grip)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(BAXTER_COLUMNS)
    for k, t in enumerate(samples.time):
        q = samples.joints[k]
        writer.writerow([f"{t:.6f}", *(f"{x:.6f}" for x in q[:7]), f"{grip[k, 0]:.2f}",
                         *(f"{x:.6f}" for x in q[7:]), f"{grip[k, 1]:.2f}"])
    with atomic_open(path) as f:
        f.write(out.getvalue().encode())


def _typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(getattr(Stores, ROS_DISTRIBUTION))


def _stamp(types, ns: int, kind: str):
    return types[f"builtin_interfaces/msg/{kind}"](sec=int(ns // 1_000_000_000),
                                                    nanosec=int(ns % 1_000_000_000))


def write_ros2_bag(path: str | Path, samples: Samples, start_ns: int | None = None) -> None:
    """A rosbag2 directory with MCAP storage at ``path`` (which must not exist). Written into
    a temporary sibling directory and renamed, so a failure leaves nothing at ``path``.

    Args:
        start_ns: the bag's start time (ns since the epoch; default: now).
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    path = Path(path)
    start_ns = time.time_ns() if start_ns is None else start_ns
    store = _typestore()
    types = store.types
    JT, JTP = types["trajectory_msgs/msg/JointTrajectory"], types["trajectory_msgs/msg/JointTrajectoryPoint"]
    Header, JointState = types["std_msgs/msg/Header"], types["sensor_msgs/msg/JointState"]
    header = Header(stamp=_stamp(types, start_ns, "Time"), frame_id="")
    t_ns = np.round(samples.time * 1e9).astype(np.int64)
    empty = np.zeros(0)
    grip = gripper_percent(samples.grip)
    grip_rate = -100.0 * np.gradient(samples.grip, samples.time, axis=0) if len(samples.time) > 1 \
        else np.zeros_like(grip)
    arm_points = [JTP(positions=samples.joints[k].astype(np.float64),
                      velocities=samples.velocity[k].astype(np.float64),
                      accelerations=samples.acceleration[k].astype(np.float64),
                      effort=empty, time_from_start=_stamp(types, t_ns[k], "Duration"))
                  for k in range(len(t_ns))]
    grip_points = [JTP(positions=grip[k], velocities=grip_rate[k], accelerations=empty,
                       effort=empty, time_from_start=_stamp(types, t_ns[k], "Duration"))
                   for k in range(len(t_ns))]
    path.parent.mkdir(parents=True, exist_ok=True)      # as every other format's writer does
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    bag = tmp / path.name
    try:
        with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            conns = {name: writer.add_connection(topic, msgtype, typestore=store)
                     for name, topic, msgtype in (
                         ("trajectory", TOPICS["trajectory"], JT.__msgtype__),
                         ("gripper", TOPICS["gripper"], JT.__msgtype__),
                         ("states", TOPICS["states"], JointState.__msgtype__))}
            writer.write(conns["trajectory"], start_ns, store.serialize_cdr(
                JT(header=header, joint_names=list(JOINT_COLUMNS), points=arm_points), JT.__msgtype__))
            writer.write(conns["gripper"], start_ns, store.serialize_cdr(
                JT(header=header, joint_names=list(GRIPPER_NAMES), points=grip_points), JT.__msgtype__))
            for k in range(len(t_ns)):
                stamp = start_ns + int(t_ns[k])
                msg = JointState(header=Header(stamp=_stamp(types, stamp, "Time"), frame_id=""),
                                 name=list(JOINT_COLUMNS), position=samples.joints[k].astype(np.float64),
                                 velocity=samples.velocity[k].astype(np.float64), effort=empty)
                writer.write(conns["states"], stamp, store.serialize_cdr(msg, JointState.__msgtype__))
        os.rename(bag, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def read_ros2_trajectories(path: str | Path) -> dict[str, object]:
    """The JointTrajectory messages of a bag written by ``write_ros2_bag``, by topic, and
    the JointState messages as a list under ``TOPICS['states']`` (for checks and tests)."""
    from rosbags.rosbag2 import Reader

    store = _typestore()
    out: dict[str, object] = {TOPICS["states"]: []}
    with Reader(Path(path)) as reader:
        for connection, _, raw in reader.messages():
            msg = store.deserialize_cdr(raw, connection.msgtype)
            if connection.topic == TOPICS["states"]:
                out[TOPICS["states"]].append(msg)
            else:
                out[connection.topic] = msg
    return out
