"""Recording a ROS bag against iterating it with rosbags alone, side by side.

A bag of a survey in miniature is written here with rosbags' own writer
(default 100,000 messages): sensor_msgs/Imu at 100 Hz, tf2_msgs/TFMessage at
50 Hz, nav_msgs/Odometry at 20 Hz, sensor_msgs/NavSatFix at 5 Hz, as a ROS 1
bag (bz2-free, the recorder's default chunks) and as a ROS 2 bag folder
(sqlite3 storage). Per bag, timed in interleaved rounds (one of each per round,
so a load change hits all alike), median of the rounds:

  rosbags iterate      AnyReader.messages(): every message's bytes, nothing else
  rosbags + decode     the same, each message deserialized (AnyReader.deserialize):
                       what a user does with a bag, and like with like to `record`,
                       which decodes every message (a message that does not
                       decode with its schema is refused, not archived)
  record               recorders.record.record(workers=1) of a manifest naming the
                       bag: every message archived as itself (/<v>/ros/...), the
                       mapped ones (Imu, Odometry, NavSatFix) as ours too, the bag
                       attached, written to MCAP (zstd, CRCs)

and the ratio record / (rosbags + decode): the goal is at most 2x. Each call is timed by the wall clock and by
its process's CPU time (`time.process_time`): on a loaded machine the CPU figures are the ones that compare.

Run: .venv/bin/python bench/bench_rosbag.py [messages] [--repeats N]
(with PYTHONPATH set, the code of that tree is measured, as `bench/against.py` runs it)
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
# this tree's code, unless PYTHONPATH names a tree (another commit's, by bench/against.py or by hand)
sys.path.insert(0, str(ROOT)) if not os.environ.get("PYTHONPATH") else sys.path.append(str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import numpy as np
from common import print_table

from recorders.manifest import load_manifest
from recorders.record import record

NS = 10**9
T0 = 1476237600 * NS  # 2016-10-12 02:00:00 UTC
# topic, type, rate (Hz)
STREAMS = (("/imu/data", "sensor_msgs/msg/Imu", 100), ("/tf", "tf2_msgs/msg/TFMessage", 50),
           ("/odometry/filtered", "nav_msgs/msg/Odometry", 20), ("/gps/fix", "sensor_msgs/msg/NavSatFix", 5))
TF = "geometry_msgs/TransformStamped[] transforms\n"


def _store(ros1: bool) -> Any:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:   # Noetic's store has no tf2_msgs; the bag carries its definition
        store.register(get_types_from_msg(TF, "tf2_msgs/msg/TFMessage"))
    return store


def _messages(store: Any, ros1: bool, total: int) -> list[tuple[int, str, str, bytes]]:
    """(bag time, topic, type, serialized) of `total` messages at the streams' rates, in time order."""
    T = store.types
    V3, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    seconds = total / sum(rate for _, _, rate in STREAMS)

    def header(t: int, frame: str) -> Any:
        stamp = T["builtin_interfaces/msg/Time"](sec=t // NS, nanosec=t % NS)
        return T["std_msgs/msg/Header"](**({"seq": 0} if ros1 else {}), stamp=stamp, frame_id=frame)

    def build(msgtype: str, t: int, k: int) -> Any:
        yaw = 0.001 * k
        q = Q(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))
        if msgtype == "sensor_msgs/msg/Imu":
            return T[msgtype](header=header(t, "imu_link"), orientation=q, orientation_covariance=np.full(9, 1e-4),
                              angular_velocity=V3(x=0.01, y=-0.02, z=0.001), angular_velocity_covariance=np.zeros(9),
                              linear_acceleration=V3(x=0.1, y=0.0, z=9.81), linear_acceleration_covariance=np.zeros(9))
        if msgtype == "tf2_msgs/msg/TFMessage":
            tr = T["geometry_msgs/msg/TransformStamped"](
                header=header(t, "odom"), child_frame_id="base_link", transform=T["geometry_msgs/msg/Transform"](
                    translation=V3(x=0.5 * k / 50, y=1.0, z=-2.0), rotation=q))
            return T[msgtype](transforms=[tr])
        if msgtype == "nav_msgs/msg/Odometry":
            pose = T["geometry_msgs/msg/PoseWithCovariance"](pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=0.5 * k / 20, y=1.0, z=-2.0), orientation=q),
                covariance=np.eye(6).flatten())
            twist = T["geometry_msgs/msg/TwistWithCovariance"](twist=T["geometry_msgs/msg/Twist"](
                linear=V3(x=0.5, y=0.0, z=0.0), angular=V3(x=0.0, y=0.0, z=0.0)), covariance=np.eye(6).flatten())
            return T[msgtype](header=header(t, "odom"), child_frame_id="base_link", pose=pose, twist=twist)
        return T[msgtype](header=header(t, "gps"), status=T["sensor_msgs/msg/NavSatStatus"](status=0, service=1),
                          latitude=45.7 + 1e-7 * k, longitude=126.6, altitude=0.0,
                          position_covariance=np.eye(3).flatten(), position_covariance_type=2)

    out = []
    for topic, msgtype, rate in STREAMS:
        for k in range(int(seconds * rate)):
            t = T0 + k * NS // rate + 137
            msg = build(msgtype, t, k)
            data = store.serialize_ros1(msg, msgtype) if ros1 else store.serialize_cdr(msg, msgtype)
            out.append((t, topic, msgtype, bytes(data)))
    out.sort()
    return out


def write_bag(folder: Path, ros1: bool, total: int) -> tuple[Path, int]:
    """The bench's bag (a ROS 1 .bag, or a ROS 2 sqlite3 folder) and its message count."""
    store = _store(ros1)
    messages = _messages(store, ros1, total)
    if ros1:
        from rosbags.rosbag1 import Writer as Writer1
        path = folder / "survey.bag"
        with Writer1(path) as w:
            conns = {topic: w.add_connection(topic, msgtype, typestore=store) for topic, msgtype, _ in STREAMS}
            for t, topic, _, data in messages:
                w.write(conns[topic], t, data)
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer
        path = folder / "survey"
        with Writer(path, version=8, storage_plugin=StoragePlugin.SQLITE3) as w2:
            conns = {topic: w2.add_connection(topic, msgtype, typestore=store) for topic, msgtype, _ in STREAMS}
            for t, topic, _, data in messages:
                w2.write(conns[topic], t, data)
    return path, len(messages)


def rosbags_iterate(path: Path, decode: bool) -> Callable[[], int]:
    """Every message of the bag through rosbags' AnyReader, deserialized or not."""
    from rosbags.highlevel import AnyReader

    def run() -> int:
        n = 0
        with AnyReader([path], default_typestore=_store(False)) as reader:
            if decode:
                deserialize = reader.deserialize
                for conn, _, data in reader.messages():
                    deserialize(data, conn.msgtype)
                    n += 1
            else:
                for _ in reader.messages():
                    n += 1
        return n
    return run


def recording(folder: Path, path: Path) -> Callable[[], int]:
    """`record` of a manifest naming the bag, in-process."""
    rel = path.name + ("/" if path.is_dir() else "")
    (folder / "trial.toml").write_text(
        '[trial]\nname = "bench"\ndate = "2016-10-12"\n[[vehicles]]\nname = "auv"\nrole = "follower"\n'
        f'[[vehicles.logs]]\nformat = "rosbag"\npath = "{rel}"\norigin = [45.7, 126.6]\n')
    manifest = load_manifest(folder / "trial.toml")

    def run() -> int:
        return sum(f.messages for f in record(manifest, folder / "out.mcap", workers=1).files)
    return run


def interleaved_times(fns: dict[str, Callable[[], object]], repeats: int) -> dict[str, tuple[float, float]]:
    """(median wall s, median CPU s) of each function over `repeats` rounds, one call of each per round."""
    wall: dict[str, list[float]] = {name: [] for name in fns}
    cpu: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            fn()
            cpu[name].append(time.process_time() - start_cpu)
            wall[name].append(time.perf_counter() - start)
    return {name: (statistics.median(wall[name]), statistics.median(cpu[name])) for name in fns}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("messages", nargs="?", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    rows = []
    for ros1 in (True, False):
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            path, count = write_bag(folder, ros1, args.messages)
            fns = {"iterate": rosbags_iterate(path, False), "decode": rosbags_iterate(path, True),
                   "record": recording(folder, path)}
            archived = fns["record"]()
            assert fns["decode"]() == count
            times = interleaved_times(fns, args.repeats)
            wall = {name: w for name, (w, _) in times.items()}
            cpu = {name: c for name, (_, c) in times.items()}
            kind = "ROS 1 .bag" if ros1 else "ROS 2 sqlite3"
            rows.append((kind, count, archived, wall["iterate"], wall["decode"], wall["record"],
                         1e6 * wall["record"] / count, wall["record"] / wall["decode"], cpu["iterate"], cpu["decode"],
                         cpu["record"], cpu["record"] / cpu["decode"]))
    print_table(f"record a bag against rosbags iterating it (median of {args.repeats} interleaved rounds, s)",
                ("bag", "messages", "archived", "rosbags iterate", "rosbags + decode", "record", "record us/msg",
                 "record / decode", "CPU iterate", "CPU decode", "CPU record", "CPU record / decode"), rows)
    print("\ngoal: record / (rosbags + decode) <= 2x; 'archived' counts every archive message (each bag message as "
          "itself, the mapped ones as ours too)")


if __name__ == "__main__":
    main()
