"""Every message of a ROS bag is kept as itself, in the encoding rosbag2's MCAP storage writes, and decodes by its
schema in the `mcap` library's own ROS decoders.

Bags are built here with rosbags' writers (ROS 1; ROS 2 in sqlite3 and MCAP storage, a folder or its storage file
alone), with common types, /tf, markers, the log topic and custom types, then recorded and read back with the `mcap`
library (CRCs checked) and mcap-ros1-support / mcap-ros2-support: the messages archived plus the records refused
with a reason equal the bag's own message count as rosbags reads it, and each decoded field equals the original.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import sqlite3
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap_ros1.decoder import DecoderFactory as Ros1Decoders
from mcap_ros2.decoder import DecoderFactory as Ros2Decoders

from formats import ros_messages as R
from formats import schemas as S
from formats.mcap_reader import ArchiveReader
from recorders.manifest import load_manifest
from recorders.record import record
from tests.trial_shapes import enu_quaternion, imu, navsatfix, odometry, ros1_typestore, ros_header, write_ros1

NS = 10**9
T0 = 1476237600 * NS  # 2016-10-12 02:00:00 UTC
LAT0, LON0 = 45.7, 126.6
TF = "geometry_msgs/TransformStamped[] transforms\n"
# a custom type of every kind of field: constants, scalars, a bounded and an unbounded array, bytes, text, a time
THRUSTERS = ("uint8 MODE_IDLE=0\nuint8 MODE_RUN=1\nstd_msgs/Header header\nuint8 mode\nstring name\n"
             "float32[] rpm\nint16[4] current_ma\nuint8[] raw\nbool armed\nfloat64 voltage\n")


def manifest(folder: Path, path: str, extra: str = "") -> Path:
    (folder / "trial.toml").write_text(
        '[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "auv"\nrole = "follower"\n'
        f'[[vehicles.logs]]\nformat = "rosbag"\npath = "{path}"\norigin = [{LAT0}, {LON0}]\n{extra}\n')
    return folder / "trial.toml"


def _register(store: Any, ros1: bool) -> None:
    from rosbags.typesys import get_types_from_msg
    if ros1:   # Noetic's store has no tf2_msgs: the bag carries its definition as every ROS 1 bag does
        store.register(get_types_from_msg(TF, "tf2_msgs/msg/TFMessage"))
    store.register(get_types_from_msg(THRUSTERS, "my_auv_msgs/msg/Thrusters"))


def _header(store: Any, t: int, frame: str, ros1: bool) -> Any:
    if ros1:
        return ros_header(store, t, frame)
    T = store.types
    return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=t // NS, nanosec=t % NS),
                                    frame_id=frame)


def bag_items(store: Any, ros1: bool, n: int = 4) -> list[tuple[str, str, int, Any]]:
    """(topic, type, bag time, message) of a small dive: fix, Imu, Odometry, /tf, markers, log lines, a custom
    type and a string topic, each a few times."""
    T = store.types
    V3, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    items = []
    for k in range(n):
        t = T0 + k * NS // 10
        if ros1:
            items += [navsatfix(store, t, LAT0 + k * 1e-6, LON0), imu(store, t + 1, enu_quaternion(store, 30.0 + k)),
                      odometry(store, t + 2, 1.0 * k, 2.0, -3.0, enu_quaternion(store, 40.0), 0.5)]
        else:
            items.append(("/gps/fix", "sensor_msgs/msg/NavSatFix", t, T["sensor_msgs/msg/NavSatFix"](
                header=_header(store, t, "gps", ros1), status=T["sensor_msgs/msg/NavSatStatus"](status=0, service=1),
                latitude=LAT0 + k * 1e-6, longitude=LON0, altitude=-1.5, position_covariance=np.eye(3).flatten(),
                position_covariance_type=2)))
            items.append(("/imu", "sensor_msgs/msg/Imu", t + 1, T["sensor_msgs/msg/Imu"](
                header=_header(store, t + 1, "imu_link", ros1), orientation=Q(x=0.0, y=0.0, z=0.1 * k, w=1.0),
                orientation_covariance=np.full(9, 0.01), angular_velocity=V3(x=0.1, y=-0.2, z=0.3 * k),
                angular_velocity_covariance=np.zeros(9), linear_acceleration=V3(x=0.0, y=0.0, z=9.81),
                linear_acceleration_covariance=np.zeros(9))))
        transform = T["geometry_msgs/msg/TransformStamped"](
            header=_header(store, t, "odom", ros1), child_frame_id="base_link",
            transform=T["geometry_msgs/msg/Transform"](translation=V3(x=1.0 * k, y=-2.0, z=0.5),
                                                       rotation=Q(x=0.0, y=0.0, z=0.0, w=1.0)))
        items.append(("/tf", "tf2_msgs/msg/TFMessage", t + 3, T["tf2_msgs/msg/TFMessage"](
            transforms=[transform, transform])))
        marker = T["visualization_msgs/msg/Marker"](
            header=_header(store, t, "map", ros1), ns="contacts", id=k, type=2, action=0,
            pose=T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=-k * 1.0),
                                             orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0)),
            scale=V3(x=1.0, y=1.0, z=1.0), color=T["std_msgs/msg/ColorRGBA"](r=1.0, g=0.5, b=0.0, a=1.0),
            lifetime=T["builtin_interfaces/msg/Duration"](sec=2, nanosec=500), frame_locked=False,
            points=[T["geometry_msgs/msg/Point"](x=0.5, y=0.25, z=0.0)], colors=[], text=f"contact {k}",
            mesh_resource="", mesh_use_embedded_materials=False,
            **({} if ros1 else {"texture_resource": "", "texture": T["sensor_msgs/msg/CompressedImage"](
                header=_header(store, t, "", ros1), format="", data=np.zeros(0, np.uint8)),
                "uv_coordinates": [], "mesh_file": T["visualization_msgs/msg/MeshFile"](
                    filename="", data=np.zeros(0, np.uint8))}))
        items.append(("/markers", "visualization_msgs/msg/MarkerArray", t + 4,
                      T["visualization_msgs/msg/MarkerArray"](markers=[marker])))
        if ros1:
            log = T["rosgraph_msgs/msg/Log"](header=_header(store, t, "", ros1), level=4, name="/pilot",
                                             msg=f"depth {k} m", file="pilot.py", function="run", line=10 + k,
                                             topics=["/cmd", "/odom"])
            items.append(("/rosout", "rosgraph_msgs/msg/Log", t + 5, log))
        else:
            log = T["rcl_interfaces/msg/Log"](stamp=T["builtin_interfaces/msg/Time"](sec=t // NS, nanosec=5),
                                              level=30, name="pilot", msg=f"depth {k} m", file="pilot.py",
                                              function="run", line=10 + k)
            items.append(("/rosout", "rcl_interfaces/msg/Log", t + 5, log))
        items.append(("/thrusters", "my_auv_msgs/msg/Thrusters", t + 6, T["my_auv_msgs/msg/Thrusters"](
            header=_header(store, t, "base_link", ros1), mode=1, name=f"aft{k}",
            rpm=np.array([1500.0 + k, -200.5], np.float32), current_ma=np.array([1, -2, 3, 400], np.int16),
            raw=np.array([0, 255, k], np.uint8), armed=k % 2 == 0, voltage=15.75)))
        items.append(("/status", "std_msgs/msg/String", t + 7, T["std_msgs/msg/String"](data=f"ok {k}")))
    return items


def write_ros2(folder: Path, store: Any, items: list[tuple], storage: str) -> None:
    """A ROS 2 bag folder; in sqlite3 storage without its definitions (as Humble writes one)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    with Writer(folder, version=8, storage_plugin=StoragePlugin.MCAP if storage == "mcap"
                else StoragePlugin.SQLITE3) as w:
        conns: dict[str, Any] = {}
        for topic, msgtype, t, msg in sorted(items, key=lambda x: x[2]):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=store)
            w.write(conns[topic], t, store.serialize_cdr(msg, msgtype))
    if storage == "sqlite3":
        with sqlite3.connect(next(folder.glob("*.db3"))) as con:
            con.execute("DELETE FROM message_definitions")


def rosbags_messages(path: Path) -> list[tuple[str, str, int, bytes]]:
    """(topic, type, bag time, bytes) of every message as rosbags itself reads the bag: its own count."""
    from rosbags.rosbag1 import Reader as Reader1
    from rosbags.rosbag2 import Reader as Reader2
    with (Reader1 if path.suffix == ".bag" else Reader2)(path) as reader:
        return [(c.topic, c.msgtype, t, bytes(d)) for c, t, d in reader.messages()]


def archived(path: Path) -> tuple[dict[str, list[tuple[Any, Any, Any]]], dict[str, list[Any]]]:
    """The ROS messages of an archive by topic, (schema, channel, message) as the `mcap` library reads them (CRCs
    checked), and each decoded by its schema with mcap-ros1-support / mcap-ros2-support; our topics' messages
    decoded as protobuf."""
    ros: dict[str, list[tuple[Any, Any, Any]]] = {}
    ours: dict[str, list[Any]] = {}
    factories = {"ros1": Ros1Decoders(), "cdr": Ros2Decoders()}
    with path.open("rb") as fh:
        for schema, channel, msg in make_reader(fh, validate_crcs=True).iter_messages():
            assert schema is not None
            if channel.message_encoding in factories:
                assert R.ENCODINGS[channel.message_encoding] == schema.encoding
                decode = factories[channel.message_encoding].decoder_for(channel.message_encoding, schema)
                assert decode is not None, schema.name
                ros.setdefault(channel.topic, []).append((schema, msg, decode(msg.data)))
            else:
                assert channel.message_encoding == "protobuf", channel
                ours.setdefault(channel.topic, []).append(S.MESSAGE_CLASSES[schema.name].FromString(msg.data))
    return ros, ours


def same(original: Any, decoded: Any, where: str = "") -> None:
    """Assert that a decoded ROS message holds the original's values (rosbags' dataclass), field by field."""
    if dataclasses.is_dataclass(original):
        if hasattr(decoded, "secs"):   # ROS 1 time/duration as genpy's
            assert (decoded.secs, decoded.nsecs) == (original.sec, original.nanosec), where
            return
        for f in dataclasses.fields(original):
            if f.name in ("__msgtype__", "structure_needs_at_least_one_member") or f.name.isupper():
                continue   # rosbags' ROS 2 classes hold the constants as fields; a decoded message has none
            same(getattr(original, f.name), getattr(decoded, f.name), f"{where}.{f.name}")
    elif isinstance(original, np.ndarray):
        assert list(original.tolist()) == list(decoded), where
    elif isinstance(original, list):
        assert len(original) == len(decoded), where
        for i, (a, b) in enumerate(zip(original, decoded)):
            same(a, b, f"{where}[{i}]")
    elif isinstance(original, float):
        assert original == decoded or (math.isnan(original) and math.isnan(decoded)), where
    else:
        assert original == decoded, (where, original, decoded)


def check_every_message(archive: Path, expected: list[tuple[str, str, int, bytes]], store: Any,
                        ros1: bool) -> dict[str, list[Any]]:
    """Every bag message archived once as itself: the bag's bytes, at its bag time, of its type's schema, and
    decoding to the original's values; our decoded topics returned."""
    ros, ours = archived(archive)
    assert sum(len(v) for v in ros.values()) == len(expected)
    by_topic: dict[str, list[tuple[str, str, int, bytes]]] = {}
    for m in expected:
        by_topic.setdefault(m[0], []).append(m)
    assert set(ros) == {"/auv/ros/" + topic.strip("/") for topic in by_topic}
    for topic, messages in by_topic.items():
        got = ros["/auv/ros/" + topic.strip("/")]
        for (schema, msg, decoded), (_, msgtype, t, data) in zip(got, messages):
            assert (msg.log_time, msg.publish_time, msg.data) == (t, t, data)
            assert schema.name == (msgtype.replace("/msg/", "/") if ros1 else msgtype)
            assert schema.encoding == ("ros1msg" if ros1 else "ros2msg")
            original = store.deserialize_ros1(data, msgtype) if ros1 else store.deserialize_cdr(data, msgtype)
            same(original, decoded, topic)
    return ours


# ---------------------------------------------------------------- ROS 1

def test_every_ros1_message_is_archived_as_itself_and_decodes_by_its_schema(tmp_path, capsys):
    from replay.commands.record import print_summary
    store = ros1_typestore()
    _register(store, ros1=True)
    write_ros1(tmp_path / "dive.bag", store, bag_items(store, ros1=True))
    expected = rosbags_messages(tmp_path / "dive.bag")
    assert len(expected) == 4 * 8
    summary = record(load_manifest(manifest(tmp_path, "dive.bag")), tmp_path / "a.mcap", workers=1)
    stats = summary.files[0]
    ours = check_every_message(tmp_path / "a.mcap", expected, store, ros1=True)
    # archived + refused == the bag's count; every record archived
    assert stats.parsed == len(expected) and stats.skipped == 0
    # the string topic's text is no vendor's sentences: it gives none of ours, and says so
    assert stats.ignored == 4 and all("/status" in reason for reason in stats.ignored_reasons), stats.ignored_reasons
    # the schema is the bag's own definition text, dependencies and all
    from rosbags.rosbag1 import Reader
    with Reader(tmp_path / "dive.bag") as r:
        bag_defs = {c.topic: c.msgdef.data for c in r.connections}
    with (tmp_path / "a.mcap").open("rb") as fh:
        summary_ = make_reader(fh).get_summary()
    assert summary_ is not None
    for channel in summary_.channels.values():
        if channel.message_encoding == "ros1":
            schema = summary_.schemas[channel.schema_id]
            assert schema.data.decode() == bag_defs["/" + channel.topic.removeprefix("/auv/ros/")]
    assert "MSG: geometry_msgs/TransformStamped" in bag_defs["/tf"]
    # mapped ones are archived as ours as well
    assert len(ours["/auv/gps"]) == 4 and len(ours["/auv/ins"]) == 4 and len(ours["/auv/ins/imu"]) == 4
    assert [f.latitude for f in ours["/auv/gps"]] == pytest.approx([LAT0 + k * 1e-6 for k in range(4)])
    # the note names each topic with its count
    print_summary(summary)
    out = capsys.readouterr().out
    assert "note: dive.bag: 32 messages archived as themselves on /auv/ros/...: " in out
    assert all(f"{name} 4" in out for name in ("tf", "markers", "rosout", "thrusters", "gps/fix", "imu", "odom"))


def test_a_topic_of_two_types_is_two_channels_and_the_parallel_archive_is_the_same(tmp_path):
    store = ros1_typestore()
    _register(store, ros1=True)
    T = store.types
    items = bag_items(store, ros1=True, n=2) + [
        ("/status", "std_msgs/msg/Float64", T0 + k, T["std_msgs/msg/Float64"](data=0.5 * k)) for k in range(3)]
    from rosbags.rosbag1 import Writer
    with Writer(tmp_path / "dive.bag") as w:   # a connection per topic and type
        conns: dict[tuple[str, str], Any] = {}
        for topic, msgtype, t, msg in sorted(items, key=lambda x: x[2]):
            if (topic, msgtype) not in conns:
                conns[(topic, msgtype)] = w.add_connection(topic, msgtype, typestore=store)
            w.write(conns[(topic, msgtype)], t, store.serialize_ros1(msg, msgtype))
    expected = rosbags_messages(tmp_path / "dive.bag")
    m = load_manifest(manifest(tmp_path, "dive.bag"))
    stats = record(m, tmp_path / "one.mcap", workers=1).files[0]
    record(m, tmp_path / "two.mcap", workers=2)
    assert (tmp_path / "one.mcap").read_bytes() == (tmp_path / "two.mcap").read_bytes()
    ros, _ = archived(tmp_path / "one.mcap")
    # the first type on the topic keeps it (the Float64s come first), the other goes below it
    assert [d.data for _, _, d in ros["/auv/ros/status"]] == [0.0, 0.5, 1.0]
    assert [d.data for _, _, d in ros["/auv/ros/status/std_msgs_String"]] == ["ok 0", "ok 1"]
    assert sum(len(v) for v in ros.values()) == len(expected) == stats.parsed
    with ArchiveReader(tmp_path / "two.mcap") as reader:   # our reader keeps them as bytes, no damage
        kept = [m.message for m in reader.messages(["/auv/ros/status/std_msgs_String"])]
        assert reader.warning() is None
    assert [k.data for k in kept] == [d for _, msgtype, _, d in expected if msgtype == "std_msgs/msg/String"]
    assert kept[0].schema_name == "std_msgs/String" and kept[0].message_encoding == "ros1"


# ---------------------------------------------------------------- ROS 2

def _ros2_store() -> Any:
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS2_HUMBLE)
    _register(store, ros1=False)
    return store


def _thrusters_msg(folder: Path) -> str:
    pkg = folder / "defs" / "my_auv_msgs" / "msg"
    pkg.mkdir(parents=True)
    (pkg / "Thrusters.msg").write_text(THRUSTERS)
    return 'msg_paths = ["defs"]'


@pytest.mark.parametrize(("storage", "path"), [("sqlite3", "dive/"), ("sqlite3", "dive/dive.db3"),
                                               ("mcap", "dive/")])
def test_every_ros2_message_is_archived_as_cdr_and_decodes_by_its_ros2msg_schema(tmp_path, storage, path):
    store = _ros2_store()
    write_ros2(tmp_path / "dive", store, bag_items(store, ros1=False), storage)
    expected = rosbags_messages(tmp_path / "dive")
    assert len(expected) == 4 * 7
    # a Humble database carries no definitions: the custom type's come from msg_paths (an MCAP bag carries them)
    extra = _thrusters_msg(tmp_path) if storage == "sqlite3" else ""
    stats = record(load_manifest(manifest(tmp_path, path, extra)), tmp_path / "a.mcap", workers=1).files[0]
    ours = check_every_message(tmp_path / "a.mcap", expected, store, ros1=False)
    assert stats.parsed == len(expected) and stats.skipped == 0 and stats.ignored == 4
    assert len(ours["/auv/gps"]) == 4 and len(ours["/auv/ins"]) == 4
    # the Imu decoded as ours too, its rates turned from FLU to FRD
    assert [s.angular_velocity_z_radps for s in ours["/auv/ins"]] == pytest.approx([-0.3 * k for k in range(4)])
    with (tmp_path / "a.mcap").open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    text = {s.name: s.data.decode() for s in summary.schemas.values() if s.encoding == "ros2msg"}
    # rosbag2's layout: the type's fields, then each type it uses after a separator line and its MSG: name
    assert text["tf2_msgs/msg/TFMessage"].startswith("geometry_msgs/TransformStamped[] transforms\n")
    assert ("=" * 80 + "\nMSG: builtin_interfaces/Time\n") in text["tf2_msgs/msg/TFMessage"]
    assert "uint8 MODE_RUN=1" in text["my_auv_msgs/msg/Thrusters"]


def test_a_type_defined_nowhere_is_refused_with_its_reason_and_the_rest_archived(tmp_path):
    store = _ros2_store()
    write_ros2(tmp_path / "dive", store, bag_items(store, ros1=False), "sqlite3")
    expected = rosbags_messages(tmp_path / "dive")
    stats = record(load_manifest(manifest(tmp_path, "dive/")), tmp_path / "a.mcap", workers=1).files[0]
    ros, _ = archived(tmp_path / "a.mcap")
    archived_count = sum(len(v) for v in ros.values())
    # archived + refused with a reason == rosbags' count; only the custom type's 4 refused
    assert archived_count + stats.skipped == len(expected) and stats.skipped == 4
    assert archived_count == stats.parsed and "/auv/ros/thrusters" not in ros
    assert archived_count / len(expected) == 24 / 28
    with ArchiveReader(tmp_path / "a.mcap") as reader:
        lines = [m.message.message for m in reader.messages(["/diagnostics"])]
    assert len(lines) == 4 and all("/thrusters" in x and "no definition of my_auv_msgs/Thrusters" in x
                                   for x in lines)


# ---------------------------------------------------------------- the schema text of every common type

@functools.cache
def _common_store(ros1: bool) -> Any:
    """rosbags' own store of the common types (built once: each build takes most of a second)."""
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)


def _example(store: Any, msgtype: str, draw: Any, ros1: bool) -> Any:
    """A message of `msgtype` with values drawn for every field (hypothesis `draw`), built through the store."""
    if msgtype in ("builtin_interfaces/msg/Time", "builtin_interfaces/msg/Duration"):
        # ROS 1's time is unsigned and genpy carries whole seconds out of nsecs: a time within both types' range
        sec = draw(st.integers(0 if ros1 else -2**31, 2**31 - 1))
        return store.types[msgtype](sec=sec, nanosec=draw(st.integers(0, 999_999_999)))
    _, fields = store.fielddefs[msgtype]
    return store.types[msgtype](**{name: _value(store, desc, draw, ros1) for name, desc in fields})


_NUMPY = {"bool": np.bool_, "int8": np.int8, "uint8": np.uint8, "byte": np.uint8, "char": np.uint8,
          "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32, "int64": np.int64,
          "uint64": np.uint64, "float32": np.float32, "float64": np.float64}


def _base(kind: str, draw: Any, ros1: bool) -> Any:
    if kind == "string":
        return draw(st.text(st.characters(codec="utf-8", exclude_characters="\x00"), max_size=6))
    if kind == "bool":
        return draw(st.booleans())
    if kind.startswith("float"):
        width = 32 if kind == "float32" else 64
        return draw(st.floats(width=width, allow_nan=False))
    if kind == "char" or (kind == "byte" and not ros1):
        # char: signed in one decoder, unsigned in another (a deprecated alias); a ROS 2 byte (an octet) is packed
        # signed by rosbags' CDR serializer of a plain field (128 raises struct.error): a value every side agrees on
        return draw(st.integers(0, 127))
    info = np.iinfo(np.int8 if ros1 and kind == "byte" else _NUMPY[kind])   # ROS 1's byte is signed
    return draw(st.integers(int(info.min), int(info.max)))


def _value(store: Any, desc: Any, draw: Any, ros1: bool) -> Any:
    from rosbags.typesys.base import Nodetype
    kind, arg = desc
    if kind == Nodetype.BASE:
        return _base(arg[0], draw, ros1)
    if kind == Nodetype.NAME:
        return _example(store, arg, draw, ros1)
    (sub_kind, sub_arg), count = arg
    n = count if kind == Nodetype.ARRAY else draw(st.integers(0, min(count, 2) if count else 2))
    if sub_kind == Nodetype.BASE and sub_arg[0] != "string":
        dtype = np.int8 if ros1 and sub_arg[0] == "byte" else _NUMPY[sub_arg[0]]
        return np.array([_base(sub_arg[0], draw, ros1) for _ in range(n)], dtype=dtype)
    return [_value(store, (sub_kind, sub_arg), draw, ros1) for _ in range(n)]


@settings(max_examples=150, deadline=None)
@given(st.data(), st.booleans())
def test_any_common_type_decodes_by_the_schema_we_write(data, ros1):
    """Our schema text of any type rosbags knows (ROS 1 Noetic, ROS 2 Humble) decodes that type's messages, with
    any values, in the mcap library's ROS decoders."""
    from mcap.records import Schema
    store = _common_store(ros1)
    msgtype = data.draw(st.sampled_from(sorted(store.fielddefs)))
    message = _example(store, msgtype, data.draw, ros1)
    kind = R.ros_schema(msgtype, "", "NONE", store, ros1)
    raw = store.serialize_ros1(message, msgtype) if ros1 else store.serialize_cdr(message, msgtype)
    schema = Schema(id=1, name=kind.schema_name, encoding=kind.schema_encoding, data=kind.schema.encode())
    factory = Ros1Decoders() if ros1 else Ros2Decoders()
    decode = factory.decoder_for(kind.message_encoding, schema)
    assert decode is not None
    same(message, decode(bytes(raw)), msgtype)


# ---------------------------------------------------------------- Rerun reads them

def test_rerun_mcap_convert_reads_every_ros_topic(tmp_path, venv_bin):
    """`rerun mcap convert` takes the archive: ROS 2 topics decoded by their ros2msg schema (transforms, log lines,
    positions, custom types by reflection); ROS 1 ones it keeps as raw MCAP messages (it has no ros1msg decoder)."""
    import subprocess

    from rerun.chunk import RrdReader
    store = _ros2_store()
    write_ros2(tmp_path / "dive", store, bag_items(store, ros1=False), "mcap")
    record(load_manifest(manifest(tmp_path, "dive/")), tmp_path / "a.mcap", workers=1)
    subprocess.run([str(venv_bin / "rerun"), "mcap", "convert", str(tmp_path / "a.mcap"), "-o",
                    str(tmp_path / "a.rrd")], check=True, capture_output=True)
    kinds: dict[str, set[str]] = {}
    for chunk in RrdReader(tmp_path / "a.rrd").stream().to_chunks():
        names = chunk.to_record_batch().schema.names
        kinds.setdefault(str(chunk.entity_path), set()).update(n.split(":")[0] for n in names if ":" in n)
    assert "Transform3D" in kinds["/auv/ros/tf"] and "TextLog" in kinds["/auv/ros/rosout"]
    assert "GeoPoints" in kinds["/auv/ros/gps/fix"] and "my_auv_msgs.msg.Thrusters" in kinds["/auv/ros/thrusters"]


# ---------------------------------------------------------------- compressed ROS 2 bags, bounded

def _compressed_bag(folder: Path, mode: str) -> tuple[Any, list[tuple[str, str, int, Any]]]:
    from rosbags.rosbag2 import Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
    store = _ros2_store()
    items = [x for x in bag_items(store, ros1=False) if x[0] != "/thrusters"]
    w = Writer(folder, version=8)
    w.set_compression(CompressionMode[mode.upper()], CompressionFormat.ZSTD)
    w.open()
    conns: dict[str, Any] = {}
    for topic, msgtype, t, msg in sorted(items, key=lambda x: x[2]):
        if topic not in conns:
            conns[topic] = w.add_connection(topic, msgtype, typestore=store)
        w.write(conns[topic], t, store.serialize_cdr(msg, msgtype))
    w.close()
    return store, items


BOMB = 65 << 20   # zeros past the 64 MiB cap, a few KB compressed


def test_a_bag_compressed_per_message_is_inflated_within_the_cap(tmp_path):
    import zstandard
    _, items = _compressed_bag(tmp_path / "dive", "message")
    stats = record(load_manifest(manifest(tmp_path, "dive/")), tmp_path / "a.mcap", workers=1).files[0]
    ros, _ = archived(tmp_path / "a.mcap")   # the messages as the bag's writer gave them, inflated
    assert sum(len(v) for v in ros.values()) == len(items) == stats.parsed and stats.skipped == 0
    assert [d.data for _, _, d in ros["/auv/ros/status"]] == [f"ok {k}" for k in range(4)]
    # one message a zstd bomb: that message refused with its reason, in bounded memory, the others archived
    with sqlite3.connect(next((tmp_path / "dive").glob("*.db3"))) as con:
        con.execute("UPDATE messages SET data = ? WHERE id = 1", (zstandard.ZstdCompressor().compress(bytes(BOMB)),))
    stats = record(load_manifest(manifest(tmp_path, "dive/")), tmp_path / "b.mcap", workers=1).files[0]
    assert stats.skipped == 1 and stats.parsed == len(items) - 1
    with ArchiveReader(tmp_path / "b.mcap") as reader:
        (line,) = [m.message.message for m in reader.messages(["/diagnostics"])]
    assert "inflates past the 64 MiB limit" in line


def test_a_bag_compressed_per_file_is_checked_before_rosbags_inflates_it(tmp_path):
    import zstandard

    from recorders.manifest import ManifestError
    _, items = _compressed_bag(tmp_path / "dive", "file")
    stats = record(load_manifest(manifest(tmp_path, "dive/")), tmp_path / "a.mcap", workers=1).files[0]
    assert stats.parsed == len(items) and stats.skipped == 0
    (compressed,) = (tmp_path / "dive").glob("*.zstd")
    compressed.write_bytes(zstandard.ZstdCompressor().compress(bytes(BOMB)))
    with pytest.raises(ManifestError, match=r"\(compression mode file\) inflates past the 64 MiB limit") as err:
        record(load_manifest(manifest(tmp_path, "dive/")), tmp_path / "b.mcap", workers=1)
    assert "\n" not in str(err.value)


# ---------------------------------------------------------------- Imu read from its bytes, judged by rosbags'

_component = st.one_of(st.floats(-2.0, 2.0), st.sampled_from([0.0, -1.0, math.nan, math.inf, 1e200, -1e300]))


@settings(max_examples=200, deadline=None)
@given(st.booleans(), st.lists(st.tuples(
    st.tuples(_component, _component, _component, _component),            # orientation
    st.sampled_from([-1.0, 0.0, 0.01, math.nan]), st.floats(0.0, 1.0),    # orientation covariance [0], [4]
    st.tuples(_component, _component, _component), st.sampled_from([-1.0, 0.0, math.nan]),   # rates, cov [0]
    st.tuples(_component, _component, _component), st.sampled_from([-1.0, 0.5]),             # accel, cov [0]
    st.sampled_from(["imu_link", "imu_frd", "", "base_link_ned"]), st.integers(0, 3)), min_size=1, max_size=6))
def test_imu_read_from_its_bytes_gives_what_rosbags_decoding_gives(ros1, rows):
    """`_ImuBatch` over the serialized bytes (`formats.ros_imu`) gives the very states and refusals the one-by-one
    `_imu` gives from rosbags' decoded messages."""
    from formats import ros_imu
    from formats.records import Reject, Where
    from recorders import rosbag as RB
    from recorders.base import LogContext
    store = _common_store(ros1)
    T = store.types
    V3, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    ctx = LogContext("auv")
    batch = RB._ImuBatch(ctx)
    expected = []
    for k, (q, c0, c4, av, av0, la, la0, frame, stamp_s) in enumerate(rows):
        t = T0 + k
        stamp = T0 + stamp_s * NS if stamp_s else 0
        header = (ros_header(store, stamp, frame) if ros1 else T["std_msgs/msg/Header"](
            stamp=T["builtin_interfaces/msg/Time"](sec=stamp // NS, nanosec=stamp % NS), frame_id=frame))
        cov = np.zeros(9)
        cov[0], cov[4], cov[8] = c0, c4, 0.02
        msg = T["sensor_msgs/msg/Imu"](
            header=header, orientation=Q(x=q[0], y=q[1], z=q[2], w=q[3]), orientation_covariance=cov,
            angular_velocity=V3(x=av[0], y=av[1], z=av[2]), angular_velocity_covariance=np.full(9, av0),
            linear_acceleration=V3(x=la[0], y=la[1], z=la[2]), linear_acceleration_covariance=np.full(9, la0))
        data = bytes(store.serialize_ros1(msg, ros_imu.MSGTYPE) if ros1 else store.serialize_cdr(msg, ros_imu.MSGTYPE))
        decoded = store.deserialize_ros1(data, ros_imu.MSGTYPE) if ros1 else store.deserialize_cdr(data,
                                                                                                   ros_imu.MSGTYPE)
        head = ros_imu.header(data, ros1)
        assert head is not None and head == (stamp, frame.encode())
        where = Where(k, None, t, k + 1)
        expected += list(RB._imu(ctx, decoded, RB._stamp_ns(decoded, t), t, where))
        batch.add(head[0] if head[0] > 0 else t, t, where, head[1], data)
        assert ros_imu.header(data[:-1], ros1) is None and ros_imu.header(data + b"\0", ros1) is None
    got = list(batch.flush(f"/{ctx.vehicle}/ins"))   # (a Batch only for a recording that takes batches)
    assert len(got) == len(expected)
    for a, b in zip(got, expected):
        assert type(a) is type(b) and a.where == b.where
        if isinstance(a, Reject):
            assert a.reason == b.reason
            continue
        assert (a.topic, a.log_time_ns, a.publish_time_ns) == (b.topic, b.log_time_ns, b.publish_time_ns)
        for f in S.InsState.DESCRIPTOR.fields:
            x, y = getattr(a.message, f.name), getattr(b.message, f.name)
            if f.name in ("timestamp",):
                assert x == y
            elif isinstance(x, float):
                assert a.message.HasField(f.name) == b.message.HasField(f.name) if f.has_presence else True
                assert (math.isnan(x) and math.isnan(y)) or x == pytest.approx(y, rel=1e-12, abs=1e-9), f.name
            else:
                assert x == y, f.name
