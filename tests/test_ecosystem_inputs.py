"""Trials from ROS 1/ROS 2 bags, MOOS alogs and MAVLink tlogs, and rotated logs: built here, recorded, compared.

Bags are written with rosbags' own writers, tlogs with pymavlink's encoder, alogs as text. "The same archive
messages as the equivalent vendor log" compares decoded messages and log times topic by topic.
"""

from __future__ import annotations

import functools
import json
import math
import struct
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from formats.mcap_reader import ArchiveReader
from recorders.manifest import ManifestError, load_manifest
from recorders.record import record

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"
T0 = 1476237600 * 10**9  # 2016-10-12 02:00:00 UTC, the sample trial's start
NMEA_LINES = [
    "$GPGGA,020000.00,4542.135726,N,12635.845169,E,1,08,0.9,117.87,M,-8.00,M,,*75",
    "$GPGST,020000.00,1.800,,,,1.273,1.273,3.000*71",
    "$GPRMC,020000.00,A,4542.135726,N,12635.845169,E,4.62,90.41,121016,,,A*62",
    "$GPGGA,020001.00,4542.135715,N,12635.846791,E,1,08,1.0,117.99,M,-8.00,M,,*71",
    "$GPGST,020001.00,1.800,,,,1.273,1.273,3.000*70",
]
# Local north metres become degrees with the meridian radius at the origin, R_M = R_e (1 - 2f + 3f sin²L) (the
# radii every layer shares, formats.geodesy): 6,368,228 m at 45.7°. Until 2026-12-02 the recorders used a sphere
# of radius R_e here, 0.16 % longer, which put 200 m north 0.31 m short of where the simulator and the stack put it.
MERIDIAN_RADIUS_45_7 = 6378137.0 * (1 - 2 / 298.257 + 3 / 298.257 * math.sin(math.radians(45.7)) ** 2)


def manifest(tmp: Path, logs: str, date: bool = True) -> Path:
    text = ('[trial]\nname = "t"\n' + ('date = "2016-10-12"\n' if date else "") +
            '[[vehicles]]\nname = "buddy"\nrole = "follower"\nmodem_address = 2\n'
            '[[vehicles]]\nname = "auv"\nrole = "leader"\nmodem_address = 1\n' + logs)
    (tmp / "trial.toml").write_text(text)
    return tmp / "trial.toml"


def log(fmt: str, path: str, sensor: str = "", extra: str = "") -> str:
    return ('[[vehicles.logs]]\n' + (f'sensor = "{sensor}"\n' if sensor else "") +
            f'format = "{fmt}"\npath = {path if path.startswith("[") else repr(path)}\n{extra}\n')


def messages(tmp: Path, m: Path, name: str = "a.mcap") -> tuple[dict[str, list], dict]:
    out = tmp / name
    summary = record(load_manifest(m), out, workers=1)
    by: dict[str, list] = {}
    with ArchiveReader(out) as r:
        for msg in r.messages():
            by.setdefault(msg.topic, []).append((msg.log_time_ns, msg.message.SerializeToString()))
        recording = r.metadata_json("recording")
        attachments = sorted(a.name for a in r.attachments())
    return by, {"summary": summary, "recording": recording, "attachments": attachments}


# ---------------------------------------------------------------- ROS bags

def _typestores():
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS1_NOETIC), get_typestore(Stores.ROS2_HUMBLE)


DVL_MSG = """std_msgs/Header header
float64 time
geometry_msgs/Vector3 velocity
float64 fom
float64 altitude
bool velocity_valid
int64 status
string form
"""


def _bag_messages(ts, *, stamp_offset_ns: int = 0):
    """(topic, msgtype, bag time, message) covering every mapped type; times from T0."""
    from rosbags.typesys import get_types_from_msg
    ts.register(get_types_from_msg(DVL_MSG, "waterlinked_a50_ros_driver/msg/DVL"))
    T = ts.types
    Time = T["builtin_interfaces/msg/Time"]

    def header(t_ns, frame):
        kw = {"stamp": Time(sec=t_ns // 10**9, nanosec=t_ns % 10**9), "frame_id": frame}
        if "seq" in T["std_msgs/msg/Header"].__dataclass_fields__:
            kw["seq"] = 0
        return T["std_msgs/msg/Header"](**kw)

    import numpy as np
    V3, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    out = []
    for i, line in enumerate(NMEA_LINES):
        t = T0 + (i // 3) * 10**9 + 50_000_000
        out.append(("/nmea", "nmea_msgs/msg/Sentence", t + 1000,
                    T["nmea_msgs/msg/Sentence"](header=header(t, "gps"), sentence=line)))
        out.append(("/gps/raw", "std_msgs/msg/String", t + 1000, T["std_msgs/msg/String"](data=line)))
    status = T["sensor_msgs/msg/NavSatStatus"]
    for i, st_ in enumerate((0, -1, 2)):
        t = T0 + i * 10**9
        cov = np.array([1.62, 0, 0, 0, 1.62, 0, 0, 0, 9.0]) if i != 2 else np.full(9, np.nan)
        out.append(("/gps/fix", "sensor_msgs/msg/NavSatFix", t + 10_000_000, T["sensor_msgs/msg/NavSatFix"](
            header=header(t + stamp_offset_ns, "gps_link"), status=status(status=st_, service=1),
            latitude=45.7022621, longitude=126.5974195, altitude=109.87, position_covariance=cov,
            position_covariance_type=2)))
    # a quarter turn about z in ENU: yaw 90 deg = heading 0 (north)
    s = math.sqrt(0.5)
    quat = Q(x=0.0, y=0.0, z=s, w=s)
    out.append(("/imu", "sensor_msgs/msg/Imu", T0 + 2 * 10**9, T["sensor_msgs/msg/Imu"](
        header=header(T0 + 2 * 10**9, "imu_link"), orientation=quat, orientation_covariance=np.zeros(9),
        angular_velocity=V3(x=0.0, y=0.0, z=0.0), angular_velocity_covariance=np.zeros(9),
        linear_acceleration=V3(x=0.0, y=0.0, z=0.0), linear_acceleration_covariance=np.zeros(9))))
    PoseC, TwistC = T["geometry_msgs/msg/PoseWithCovariance"], T["geometry_msgs/msg/TwistWithCovariance"]
    Pose, Twist, Point = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/Twist"], T["geometry_msgs/msg/Point"]
    out.append(("/odom", "nav_msgs/msg/Odometry", T0 + 3 * 10**9, T["nav_msgs/msg/Odometry"](
        header=header(T0 + 3 * 10**9, "odom"), child_frame_id="base_link",
        pose=PoseC(pose=Pose(position=Point(x=100.0, y=200.0, z=-5.0), orientation=quat), covariance=np.zeros(36)),
        twist=TwistC(twist=Twist(linear=V3(x=1.5, y=0.0, z=0.0), angular=V3(x=0.0, y=0.0, z=0.0)),
                     covariance=np.zeros(36)))))
    out.append(("/dvl/twist", "geometry_msgs/msg/TwistWithCovarianceStamped", T0 + 4 * 10**9,
                T["geometry_msgs/msg/TwistWithCovarianceStamped"](
                    header=header(T0 + 4 * 10**9, "dvl_link"),
                    twist=TwistC(twist=Twist(linear=V3(x=1.0, y=0.5, z=-0.1), angular=V3(x=0.0, y=0.0, z=0.0)),
                                 covariance=np.zeros(36)))))
    out.append(("/ublox/fix_velocity", "geometry_msgs/msg/TwistWithCovarianceStamped", T0 + 4 * 10**9,
                T["geometry_msgs/msg/TwistWithCovarianceStamped"](
                    header=header(T0 + 4 * 10**9, "gps"),
                    twist=TwistC(twist=Twist(linear=V3(x=0.3, y=1.2, z=0.1), angular=V3(x=0.0, y=0.0, z=0.0)),
                                 covariance=np.eye(6).flatten() * 0.01))))
    out.append(("/dvl/data", "waterlinked_a50_ros_driver/msg/DVL", T0 + 5 * 10**9,
                T["waterlinked_a50_ros_driver/msg/DVL"](
                    header=header(T0 + 5 * 10**9, "dvl"), time=1.0, velocity=V3(x=0.8, y=0.1, z=0.0), fom=0.002,
                    altitude=12.5, velocity_valid=True, status=0, form="json_v2")))
    out.append(("/camera/info", "std_msgs/msg/String", T0 + 6 * 10**9, T["std_msgs/msg/String"](data="hello")))
    out.append(("/diag_count", "std_msgs/msg/Int32", T0 + 6 * 10**9, T["std_msgs/msg/Int32"](data=4)))
    return out


NMEA_SENTENCE_MSG = "std_msgs/Header header\nstring sentence\n"


def write_ros1(path: Path, part: tuple[int, int] = (0, 2**63)) -> None:
    """A ROS 1 bag of `_bag_messages` (those with bag times in [part[0], part[1]) ns)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import get_types_from_msg
    ts, _ = _typestores()
    if "nmea_msgs/msg/Sentence" not in ts.types:
        ts.register(get_types_from_msg(NMEA_SENTENCE_MSG, "nmea_msgs/msg/Sentence"))
    items = [x for x in _bag_messages(ts) if part[0] <= x[2] < part[1]]
    with Writer(path) as w:
        conns = {}
        for topic, msgtype, t, msg in sorted(items, key=lambda x: x[2]):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=ts)
            w.write(conns[topic], t, ts.serialize_ros1(msg, msgtype))


def write_ros2(folder: Path, storage: str) -> Path:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_types_from_msg
    _, ts = _typestores()
    ts.register(get_types_from_msg(NMEA_SENTENCE_MSG, "nmea_msgs/msg/Sentence"))
    items = _bag_messages(ts)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(folder, version=9, storage_plugin=plugin) as w:
        conns = {}
        for topic, msgtype, t, msg in sorted(items, key=lambda x: x[2]):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=ts)
            w.write(conns[topic], t, ts.serialize_cdr(msg, msgtype))
    return next(folder.glob("*.mcap" if storage == "mcap" else "*.db3"))


@pytest.fixture(scope="module")
def bags(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("bags")
    write_ros1(root / "trial.bag")
    return {"ros1": root / "trial.bag", "mcap": write_ros2(root / "r2mcap", "mcap"),
            "sqlite3": write_ros2(root / "r2db", "sqlite3"), "root": root}


def _vendor_gps(tmp: Path) -> dict[str, list]:
    """The NMEA lines as a vendor log with the bags' header stamps as host prefix."""
    lines = [f"{(T0 + (i // 3) * 10**9 + 50_000_000) / 1e9:.3f} {line}" for i, line in enumerate(NMEA_LINES)]
    (tmp / "gps.log").write_text("\n".join(lines) + "\n")
    by, _ = messages(tmp, manifest(tmp, log("nmea", "gps.log", "gps")), "vendor.mcap")
    return by


@pytest.mark.parametrize("kind", ["ros1", "mcap", "sqlite3"])
def test_bag_maps_every_type_like_the_vendor_logs(bags, tmp_path, kind):
    rel = bags[kind].relative_to(bags["root"])
    m = manifest(bags["root"], log("rosbag", str(rel), extra='origin = [45.7, 126.6]'))
    by, info = messages(tmp_path, m)
    vendor = _vendor_gps(tmp_path)
    # the raw sentences, as nmea_msgs/Sentence and as std_msgs/String, give the vendor log's messages, each ROS
    # topic a source of its own below the NavSatFix's /auv/gps (which claims it first, being typed)
    vendor_fixes = vendor["/auv/gps"]
    assert len(vendor_fixes) == 2
    assert by["/auv/gps/nmea"] == vendor_fixes and by["/auv/gps/gps_raw"] == vendor_fixes
    assert by["/auv/gps/nmea/status"] == by["/auv/gps/gps_raw/status"] == vendor["/auv/gps/status"]
    # NavSatFix: status 0 -> a fix with its covariance; -1 -> status only; NaN covariance -> UNKNOWN
    from formats import schemas as S
    navsat = [S.LocationFix.FromString(b) for t, b in by["/auv/gps"]]
    assert len(navsat) == 2
    assert navsat[0].position_covariance_type == 2 and navsat[0].position_covariance[0] == pytest.approx(1.62)
    assert navsat[1].position_covariance_type == 0 and math.isnan(navsat[1].position_covariance[0])
    assert navsat[0].latitude == pytest.approx(45.7022621) and navsat[0].altitude == pytest.approx(109.87)
    # Imu and Odometry: two sources, the Odometry (a position) on /auv/ins, the Imu below it
    ((t_imu, imu),), ((t_odom, odom),) = by["/auv/ins/imu"], by["/auv/ins"]
    assert (t_imu, t_odom) == (T0 + 2 * 10**9, T0 + 3 * 10**9)
    imu, odom = S.InsState.FromString(imu), S.InsState.FromString(odom)
    assert imu.heading_deg == pytest.approx(0.0, abs=1e-9) and imu.roll_deg == pytest.approx(0.0, abs=1e-9)
    assert math.isnan(imu.latitude)
    # odom: x east 100 m, y north 200 m of the origin, z -5 (ENU) -> depth 5; 1.5 m/s forward heading north
    assert odom.depth_m == pytest.approx(5.0)
    assert odom.latitude == pytest.approx(45.7 + math.degrees(200 / MERIDIAN_RADIUS_45_7), abs=1e-11)
    assert odom.velocity_north_mps == pytest.approx(1.5) and odom.velocity_east_mps == pytest.approx(0.0, abs=1e-9)
    # two DVL topics, two sources: /dvl/data (first by name) on /auv/dvl, /dvl/twist below it
    ((t_a50, a50),), ((t_twist, twist),) = by["/auv/dvl"], by["/auv/dvl/dvl_twist"]
    assert (t_twist, t_a50) == (T0 + 4 * 10**9, T0 + 5 * 10**9)
    twist, a50 = S.DvlVelocity.FromString(twist), S.DvlVelocity.FromString(a50)
    assert (twist.frame, twist.velocity_x_mps, twist.velocity_y_mps, twist.velocity_z_mps) == \
        (S.DvlVelocity.BODY_FRD, 1.0, -0.5, pytest.approx(0.1))
    assert a50.frame == S.DvlVelocity.INSTRUMENT and a50.altitude_m == 12.5 and a50.valid
    (gnss_t, gnss), = by["/auv/gps/velocity"]  # the receiver's ENU twist, north/east/up
    gnss = S.GnssVelocity.FromString(gnss)
    assert (gnss.velocity_north_mps, gnss.velocity_east_mps, gnss.velocity_up_mps) == (1.2, 0.3, pytest.approx(0.1))
    assert gnss.speed_std_mps == pytest.approx(math.sqrt(0.02))
    stats = info["recording"]["files"][0]
    assert stats["format"] == "rosbag" and stats["sensor"] == ""
    # every message archived as itself: 10 raw + 3 NavSatFix + Imu + Odometry + GNSS twist + 2 DVL + 2 unmapped
    total = 20
    assert stats["parsed"] == total and stats["skipped"] == 0
    assert sum(len(v) for k, v in by.items() if k.startswith("/auv/ros/")) == total
    assert len(by["/auv/ros/diag_count"]) == len(by["/auv/ros/camera/info"]) == 1
    # a ROS 2 storage file stands for its bag folder: every file of it is kept
    assert info["attachments"] == ([str(rel)] if kind == "ros1" else [f"{rel.parent}/metadata.yaml", str(rel)])
    # header stamps are log time, bag time publish time
    with ArchiveReader(tmp_path / "a.mcap") as r:
        fix = next(x for x in r.messages(["/auv/gps"]) if x.log_time_ns == T0)
        assert fix.publish_time_ns == T0 + 10_000_000


def test_topic_mapping_and_vehicles(bags, tmp_path):
    rel = bags["ros1"].relative_to(bags["root"])
    extra = 'topics = { "/gps/fix" = { sensor = "gps", vehicle = "buddy" }, "/dvl/twist" = "dvl" }'
    by, info = messages(tmp_path, manifest(bags["root"], log("rosbag", str(rel), extra=extra)))
    # the rest archived as themselves alone; every message as itself on the log's vehicle
    assert {k for k in by if not k.startswith("/auv/ros/")} == {"/buddy/gps", "/buddy/gps/status", "/auv/dvl"}
    assert info["recording"]["files"][0]["ignored"] == 0 and info["recording"]["files"][0]["parsed"] == 20


def test_split_ros1_bags_are_one_log(bags, tmp_path):
    write_ros1(tmp_path / "dive_1.bag", (0, T0 + 3 * 10**9))
    write_ros1(tmp_path / "dive_0.bag", (T0 + 3 * 10**9, 2**63))  # later messages, earlier name
    (tmp_path / "trial.bag").write_bytes(bags["ros1"].read_bytes())
    whole, _ = messages(tmp_path, manifest(tmp_path, log("rosbag", "trial.bag")), "whole.mcap")
    split, info = messages(tmp_path, manifest(tmp_path, log("rosbag", "dive_*.bag", extra='order = "time"')))
    assert {k: sorted(v) for k, v in split.items() if k != "/diagnostics"} == \
        {k: sorted(v) for k, v in whole.items() if k != "/diagnostics"}
    parts = info["recording"]["files"][0]["parts"]
    assert [p["path"] for p in parts] == ["dive_1.bag", "dive_0.bag"] and parts[1]["gap_s"] > 0


def test_rotated_alogs_each_with_its_logstart(tmp_path):
    lines = ALOG.splitlines(keepends=True)
    first, second = lines[:11], lines[11:]
    later = [f"{float(x.split()[0]) - 2.0:.3f}{x[len(x.split()[0]):]}" if x[0].isdigit() else x for x in second]
    (tmp_path / "auv.alog").write_text(ALOG)
    (tmp_path / "r_0.alog").write_text("".join(first))
    (tmp_path / "r_1.alog").write_text(f"%% LOGSTART           {T0 / 1e9 + 2:.3f}\n" + "".join(later))
    whole, _ = messages(tmp_path, manifest(tmp_path, log("alog", "auv.alog")), "whole.mcap")
    split, _ = messages(tmp_path, manifest(tmp_path, log("alog", "r_*.alog")))
    assert {k: v for k, v in split.items() if k != "/diagnostics"} == \
        {k: v for k, v in whole.items() if k != "/diagnostics"}


def test_whole_ros2_bag_folder(bags, tmp_path):
    by, info = messages(tmp_path, manifest(bags["root"], log("rosbag", "r2db/*")))
    single, _ = messages(tmp_path, manifest(bags["root"], log("rosbag", "r2db/r2db.db3")), "single.mcap")
    assert info["attachments"] == ["r2db/metadata.yaml", "r2db/r2db.db3"]
    assert {k: v for k, v in by.items() if k != "/diagnostics"} == \
        {k: v for k, v in single.items() if k != "/diagnostics"}


def test_bag_without_date_takes_the_bags_day(bags, tmp_path):
    rel = bags["mcap"].relative_to(bags["root"])
    by, _ = messages(tmp_path, manifest(bags["root"], log("rosbag", str(rel), extra='topics = { "/nmea" = "gps" }'),
                                        date=False))
    assert [t for t, _ in by["/auv/gps"]] == [T0, T0 + 10**9]


FLOATS = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -1.0, 1e300, 45.7]))
FRAMES = st.sampled_from(["", "/odom", "odom", "map_ned", "world", "base_link", "base_link_frd", "/dvl_link",
                          "gps", "utm", "ned"])
DS_DVL_MSG = """std_msgs/Header header
float64 dvl_time
geometry_msgs/Vector3 velocity
float64[9] velocity_covar
float64 altitude
float64 sound_speed
uint8 coordinate_mode
"""


@functools.cache
def _fuzz_typestore():
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    ts = get_typestore(Stores.ROS2_HUMBLE)
    ts.register(get_types_from_msg(DS_DVL_MSG, "ds_sensor_msgs/msg/Dvl"))
    return ts


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_any_message_content_is_counted_never_a_traceback(tmp_path, data):
    """Other labs' quirks: status -1 or out of range, NaN/inf/huge values, frame name variants, zero or far stamps,
    beam-coordinate DVLs; every message is archived, rejected or ignored, and the recording never fails."""
    import numpy as np
    from rosbags.rosbag2 import StoragePlugin, Writer
    ts = _fuzz_typestore()
    T = ts.types
    V3, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]

    def header():
        sec = data.draw(st.sampled_from([0, 1, 1476237600, 2**31 - 1]))
        return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=0),
                                        frame_id=data.draw(FRAMES))

    def v3():
        return V3(x=data.draw(FLOATS), y=data.draw(FLOATS), z=data.draw(FLOATS))

    def arr(n):
        return np.array([data.draw(FLOATS) for _ in range(n)], dtype=np.float64)

    kinds = {
        "sensor_msgs/msg/NavSatFix": lambda: T["sensor_msgs/msg/NavSatFix"](
            header=header(), status=T["sensor_msgs/msg/NavSatStatus"](status=data.draw(st.integers(-128, 127)),
                                                                      service=1),
            latitude=data.draw(FLOATS), longitude=data.draw(FLOATS), altitude=data.draw(FLOATS),
            position_covariance=arr(9), position_covariance_type=data.draw(st.integers(0, 255))),
        "sensor_msgs/msg/Imu": lambda: T["sensor_msgs/msg/Imu"](
            header=header(), orientation=Q(x=data.draw(FLOATS), y=data.draw(FLOATS), z=data.draw(FLOATS),
                                           w=data.draw(FLOATS)),
            orientation_covariance=arr(9), angular_velocity=v3(), angular_velocity_covariance=arr(9),
            linear_acceleration=v3(), linear_acceleration_covariance=arr(9)),
        "nav_msgs/msg/Odometry": lambda: T["nav_msgs/msg/Odometry"](
            header=header(), child_frame_id=data.draw(FRAMES),
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=data.draw(FLOATS), y=data.draw(FLOATS), z=data.draw(FLOATS)),
                orientation=Q(x=data.draw(FLOATS), y=0.0, z=data.draw(FLOATS), w=data.draw(FLOATS))),
                covariance=arr(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=T["geometry_msgs/msg/Twist"](
                linear=v3(), angular=v3()), covariance=arr(36))),
        "geometry_msgs/msg/TwistStamped": lambda: T["geometry_msgs/msg/TwistStamped"](
            header=header(), twist=T["geometry_msgs/msg/Twist"](linear=v3(), angular=v3())),
        "ds_sensor_msgs/msg/Dvl": lambda: T["ds_sensor_msgs/msg/Dvl"](
            header=header(), dvl_time=0.0, velocity=v3(), velocity_covar=arr(9), altitude=data.draw(FLOATS),
            sound_speed=data.draw(FLOATS), coordinate_mode=data.draw(st.integers(0, 255))),
    }
    chosen = data.draw(st.lists(st.sampled_from(sorted(kinds)), min_size=1, max_size=6))
    folder = tmp_path / f"bag{len(list(tmp_path.iterdir()))}"
    with Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {}
        for i, msgtype in enumerate(chosen):
            if msgtype not in conns:
                conns[msgtype] = w.add_connection("/t" + str(len(conns)), msgtype, typestore=ts)
            w.write(conns[msgtype], T0 + i * 10**9, ts.serialize_cdr(kinds[msgtype](), msgtype))
    bag = next(folder.glob("*.mcap"))
    _, info = messages(tmp_path, manifest(tmp_path, log("rosbag", str(bag.relative_to(tmp_path)))), "f.mcap")
    stats = info["recording"]["files"][0]
    # every message is archived, rejected or ignored; one may be two of them (a NavSatFix's fix archived and
    # its status refused), and each refusal is one skip with its diagnostic line
    assert stats["parsed"] <= len(chosen) <= stats["parsed"] + stats["skipped"] + stats["ignored"]
    assert stats["parsed"] + stats["skipped"] + stats["ignored"] <= 2 * len(chosen)


SAMPLE_LOGS = [  # vehicle, sensor, format, sample log, bag topic
    ("leader1", "gps", "nmea", "leader1/gps.log", "/leader1/nmea"),
    ("leader1", "ins", "phins", "leader1/ins.log", "/leader1/phins"),
    ("follower", "modem", "micromodem", "follower/modem.log", "/follower/modem/raw"),
    ("buoy1", "usbl", "evologics", "buoy1/usbl.log", "/buoy1/usbl/raw"),
]
SAMPLE_VEHICLES = ('[[vehicles]]\nname = "leader1"\nrole = "leader"\nmodem_address = 1\n'
                   '[[vehicles]]\nname = "follower"\nrole = "follower"\nmodem_address = 3\n'
                   '[[vehicles]]\nname = "buoy1"\nrole = "buoy"\nmodem_address = 11\n')


def _sample_manifest(header: str, logs_of: dict[str, str]) -> str:
    text = header
    for vehicle, role, address in (("leader1", "leader", 1), ("follower", "follower", 3), ("buoy1", "buoy", 11)):
        text += f'[[vehicles]]\nname = "{vehicle}"\nrole = "{role}"\nmodem_address = {address}\n'
        text += logs_of.get(vehicle, "")
    return text


def test_sentences_in_a_bag_give_the_vendor_logs_messages(tmp_path):
    """NMEA, PHINS, Micro-Modem and EvoLogics lines of the sample trial as std_msgs/String topics of one bag
    (bag time = the line's host time, else a second apart) record as their vendor logs do."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    from formats.lines import strip_prefix
    _, ts = _typestores()
    String = ts.types["std_msgs/msg/String"]
    header = '[trial]\nname = "t"\ndate = "2016-10-12"\nsound_speed_mps = 1450.0\n'
    vendor_logs: dict[str, str] = {}
    items = []
    with Writer(tmp_path / "bag", version=9, storage_plugin=StoragePlugin.MCAP) as w:
        for vehicle, sensor, fmt, name, topic in SAMPLE_LOGS:
            lines = (SAMPLE / name).read_text().splitlines()[:240]
            flat = name.replace("/", "_")
            (tmp_path / flat).write_text("\n".join(lines) + "\n")
            extra = 'carrier_hz = 75000.0\n' if fmt == "evologics" else ""
            vendor_logs[vehicle] = vendor_logs.get(vehicle, "") + (
                f'[[vehicles.logs]]\nsensor = "{sensor}"\nformat = "{fmt}"\npath = "{flat}"\n{extra}')
            conn = w.add_connection(topic, "std_msgs/msg/String", typestore=ts)
            for i, line in enumerate(lines):
                text, host = strip_prefix(line, "auto")
                items.append((host if host is not None else T0 + i * 10**9, conn, text))
        for t, conn, text in sorted(items, key=lambda x: x[0]):
            w.write(conn, t, ts.serialize_cdr(String(data=text), "std_msgs/msg/String"))
    (tmp_path / "vendor.toml").write_text(_sample_manifest(header, vendor_logs))
    vendor, _ = messages(tmp_path, tmp_path / "vendor.toml", "vendor.mcap")
    topics = "".join(f'"{topic}" = {{ sensor = "{sensor}", vehicle = "{v}", format = "{fmt}" }}\n'
                     for v, sensor, fmt, _, topic in SAMPLE_LOGS)
    bag_file = next((tmp_path / "bag").glob("*.mcap")).relative_to(tmp_path)
    bag_log = (f'[[vehicles.logs]]\nformat = "rosbag"\npath = "{bag_file}"\n[vehicles.logs.topics]\n{topics}'
               '[vehicles.logs.usbl]\ncarrier_hz = 75000.0\n')
    (tmp_path / "bag.toml").write_text(_sample_manifest(header, {"buoy1": bag_log}))
    bag, info = messages(tmp_path, tmp_path / "bag.toml", "bag.mcap")
    families = {"/leader1/gps", "/leader1/gps/status", "/leader1/ins", "/follower/modem/range", "/buoy1/usbl"}
    assert families <= set(vendor)
    for topic in families:
        assert sorted(bag[topic]) == sorted(vendor[topic]), topic
    assert info["recording"]["files"][0]["skipped"] == 0


# ---------------------------------------------------------------- MOOS alog

ALOG = f"""%% LOGFILE:   /home/moos/auv.alog
%% LOGSTART           {T0 / 1e9:.3f}
%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%
0.050   NMEA_GPS        iGPS          {NMEA_LINES[0]}
0.050   NMEA_GPS        iGPS          {NMEA_LINES[1]}
0.050   NMEA_GPS        iGPS          {NMEA_LINES[2]}
1.050   NMEA_GPS        iGPS          {NMEA_LINES[3]}
1.050   NMEA_GPS        iGPS          {NMEA_LINES[4]}
2.000   NAV_X           pNodeReporter 100
2.000   NAV_Y           pNodeReporter 200
2.000   NAV_DEPTH       pNodeReporter 5.5
2.000   NAV_HEADING     pNodeReporter 90
2.000   NAV_SPEED       pNodeReporter 1.2
3.000   GPS_LAT         iGPS          45.71
3.000   GPS_LON         iGPS          126.61
3.000   GPS_SAT         iGPS          9
3.000   GPS_SPEED       iGPS          1.5
3.000   GPS_HEADING     iGPS          180
4.000   CRS_RANGE_REPORT uFldContactRangeSensor vname=auv,range=87.2,target=buddy,time={T0 / 1e9 + 4:.3f}
4.500   DEPLOY          pHelmIvP      true
junk
5.000   NAV_DEPTH       pNodeReporter not-a-number
"""


def test_alog_maps_variables_and_raw_nmea(tmp_path):
    from formats import schemas as S
    (tmp_path / "auv.alog").write_text(ALOG)
    by, info = messages(tmp_path, manifest(tmp_path, log("alog", "auv.alog", extra='origin = [45.7, 126.6]')))
    vendor = _vendor_gps(tmp_path)
    assert [f for f in by["/auv/gps"] if f[0] < T0 + 2 * 10**9] == vendor["/auv/gps"]
    nav = S.InsState.FromString(next(b for t, b in by["/auv/ins"] if t == T0 + 2 * 10**9))
    assert nav.depth_m == 5.5 and nav.heading_deg == 90.0 and nav.velocity_east_mps == pytest.approx(1.2)
    assert nav.latitude == pytest.approx(45.7 + math.degrees(200 / MERIDIAN_RADIUS_45_7), abs=1e-11)
    gps = S.LocationFix.FromString(next(b for t, b in by["/auv/gps"] if t == T0 + 3 * 10**9))
    assert (gps.latitude, gps.longitude) == (45.71, 126.61)
    # the raw NMEA's RMC/VTG velocity, as the vendor log gives it, then GPS_SPEED/GPS_HEADING's
    assert [v for v in by["/auv/gps/velocity"] if v[0] < T0 + 2 * 10**9] == vendor["/auv/gps/velocity"] != []
    (vel_t, vel), = [v for v in by["/auv/gps/velocity"] if v[0] >= T0 + 2 * 10**9]
    vel = S.GnssVelocity.FromString(vel)
    assert vel_t == T0 + 3 * 10**9 and vel.velocity_north_mps == pytest.approx(-1.5)
    rng = S.AcousticRange.FromString(by["/auv/modem/range"][0][1])
    assert (rng.source, rng.destination, rng.range_m, rng.source_address) == ("buddy", "auv", 87.2, 2)
    stats = info["recording"]["files"][0]
    # the line with no time is the next line of DEPLOY's value; the depth that is no number is kept as its posting
    assert stats["skipped"] == 0 and stats["ignored_reasons"] == {
        "NAV_DEPTH = 'not-a-number' is not a number": 1,
        "NMEA_GPS: nmea record merged into its epoch's message or with nothing archived": 3}
    (_, deploy), = by["/auv/moos/DEPLOY"]
    assert json.loads(deploy) == {"value": "true\njunk", "source": "pHelmIvP", "aux": "", "community": "auv"}
    assert json.loads(by["/auv/moos/NAV_DEPTH"][1][1])["value"] == "not-a-number"
    # every posting archived as itself: 18 postings (19 lines, one a value's second line)
    assert stats["parsed"] == sum(len(v) for k, v in by.items() if k.startswith("/auv/moos/")) == 18


# ---------------------------------------------------------------- MAVLink tlog

def write_tlog(path: Path, damage: bytes = b"") -> None:
    from pymavlink.dialects.v20 import ardupilotmega as mav
    m = mav.MAVLink(None, srcSystem=1, srcComponent=1)
    us = T0 // 1000
    packets = [
        (0, m.gps_raw_int_encode(us, 3, 457022621, 1265974195, 109870, 90, 200, 462, 9041, 8)),
        (1, m.heartbeat_encode(12, 3, 0, 0, 4)),
        (2, m.attitude_encode(1000, math.radians(2.0), math.radians(-3.0), math.radians(45.0), 0, 0, 0)),
        (3, m.global_position_int_encode(2000, 457022000, 1265974000, 100000, -5500, 100, -50, 10, 4500)),
        (4, m.gps_input_encode(us + 4_000_000, 0, 0, 0, 0, 3, 457023000, 1265975000, -5.5, 1.1, 0.9,
                               0.5, 0.2, 0.25, 0, 0, 0, 7)),  # hdop 1.1, vdop 0.9, vn, ve, vd
        (5, m.vision_speed_estimate_encode(us + 5_000_000, 0.5, 0.25, 0.05, [0.0] * 9, 0)),
        (6, m.vision_position_delta_encode(us + 6_000_000, 200_000, [0.0, 0.0, 0.0], [0.2, 0.02, 0.0], 80.0)),
        (7, m.distance_sensor_encode(1000, 20, 5000, 1234, 0, 1, 25, 0)),
    ]
    out = b""
    for i, (s, pkt) in enumerate(packets):
        out += struct.pack(">Q", us + s * 1_000_000) + pkt.pack(m)
        if i == len(packets) - 1 and damage:
            out += damage
    path.write_bytes(out)


def test_tlog_maps_fixes_ins_and_dvl(tmp_path):
    from formats import schemas as S
    write_tlog(tmp_path / "sub.tlog", damage=b"\x00garbage\x00")
    by, info = messages(tmp_path, manifest(tmp_path, log("mavlink", "sub.tlog")))
    fixes = {t: S.LocationFix.FromString(b) for t, b in by["/auv/gps"]}
    assert sorted(fixes) == [T0]  # GPS_RAW_INT; the EKF is not a second fix source
    assert fixes[T0].latitude == pytest.approx(45.7022621) and fixes[T0].altitude == pytest.approx(109.87)
    # GPS_INPUT is a source of its own beside the autopilot's GPS: its own topics, its own clock
    (ugps_t, ugps_fix), = by["/auv/gps/input"]
    assert ugps_t == T0 + 4 * 10**9 and S.LocationFix.FromString(ugps_fix).latitude == pytest.approx(45.7023)
    ins = {t: S.InsState.FromString(b) for t, b in by["/auv/ins"]}
    ekf = ins[T0 + 3 * 10**9]
    assert ekf.heading_deg == pytest.approx(45.0) and ekf.roll_deg == pytest.approx(2.0)
    assert ekf.depth_m == pytest.approx(5.5) and ekf.velocity_north_mps == pytest.approx(1.0)
    dvl = {t: S.DvlVelocity.FromString(b) for t, b in by["/auv/dvl"]}
    assert dvl[T0 + 5 * 10**9].frame == S.DvlVelocity.EARTH_NED and dvl[T0 + 5 * 10**9].velocity_y_mps == 0.25
    delta = dvl[T0 + 6 * 10**9]
    assert delta.frame == S.DvlVelocity.BODY_FRD and delta.velocity_x_mps == pytest.approx(1.0) and delta.valid
    assert dvl[T0 + 7 * 10**9].altitude_m == pytest.approx(12.34) and not dvl[T0 + 7 * 10**9].valid
    vel = {t: S.GnssVelocity.FromString(b) for t, b in by["/auv/gps/velocity"] + by["/auv/gps/input/velocity"]}
    assert sorted(vel) == [T0, T0 + 4 * 10**9]
    raw, ugps = vel[T0], vel[T0 + 4 * 10**9]
    assert (raw.speed_over_ground_mps, raw.course_over_ground_deg) == (pytest.approx(4.62), pytest.approx(90.41))
    assert raw.velocity_east_mps == pytest.approx(4.62 * math.sin(math.radians(90.41)))
    assert (ugps.velocity_north_mps, ugps.velocity_east_mps, ugps.velocity_up_mps) == \
        (pytest.approx(0.5), pytest.approx(0.2), pytest.approx(-0.25))
    assert ugps.speed_over_ground_mps == pytest.approx(math.hypot(0.5, 0.2))
    stats = info["recording"]["files"][0]
    # every message is archived as itself too; the garbage after the last packet is one reject
    assert stats["skipped"] == 1 and stats["ignored"] == 0 and stats["parsed"] == 8
    assert json.loads(by["/auv/mavlink/HEARTBEAT"][0][1])["type"] == 12


# dataflash: records described by FMT records (ArduPilot's layout), written by hand: pymavlink has no writer
_DF_CHARS = {"B": "B", "Q": "Q", "I": "I", "H": "H", "f": "f", "n": "4s", "N": "16s", "Z": "64s", "c": "h",
             "e": "i", "L": "i"}
DF_TYPES = {  # name: (id, format, columns)
    "GPS": (130, "QBIHBcLLeff", "TimeUS,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt,Spd,GCrs"),
    "ATT": (131, "Qccf", "TimeUS,Roll,Pitch,Yaw"),
    "POS": (132, "QLLff", "TimeUS,Lat,Lng,Alt,RelHomeAlt"),
    "VISV": (133, "Qfff", "TimeUS,VX,VY,VZ"),
    "VISO": (134, "Qfffff", "TimeUS,dt,PosDX,PosDY,PosDZ,conf"),
    "RFND": (135, "QBfBB", "TimeUS,Instance,Dist,Stat,Orient"),
    "MSG": (136, "QZ", "TimeUS,Message"),
}


def _df(tid: int, fmt: str, *values) -> bytes:
    return b"\xa3\x95" + bytes([tid]) + struct.pack("<" + "".join(_DF_CHARS[c] for c in fmt), *values)


def write_dataflash(path: Path, with_gps: bool = True) -> None:
    out = _df(128, "BBnNZ", 128, 89, b"FMT", b"BBnNZ", b"Type,Length,Name,Format,Columns")
    for name, (tid, fmt, cols) in DF_TYPES.items():
        size = 3 + struct.calcsize("<" + "".join(_DF_CHARS[c] for c in fmt))
        out += _df(128, "BBnNZ", tid, size, name.encode(), fmt.encode(), cols.encode())
    # 2016-10-12 02:00:00 UTC is GPS week 1918, 266417 s (17 leap seconds then)
    boot = 1_000_000  # TimeUS of the first GPS record, at T0
    if with_gps:
        out += _df(130, DF_TYPES["GPS"][1], boot, 3, 266_417_000, 1918, 9, 90, 457022621, 1265974195, 10987, 2.3, 90.4)
    out += _df(131, "Qccf", boot + 500_000, 200, -300, 45.0)
    out += _df(132, "QLLff", boot + 1_000_000, 457022000, 1265974000, 100.0, -5.5)
    out += _df(133, "Qfff", boot + 2_000_000, 0.5, 0.25, 0.0)
    out += _df(134, "Qfffff", boot + 3_000_000, 0.2, 0.2, 0.02, 0.0, 80.0)
    out += _df(135, "QBfBB", boot + 4_000_000, 0, 12.5, 4, 25)
    out += _df(136, "QZ", boot + 4_000_000, b"ArduSub V4.1.0")
    path.write_bytes(out)


def test_dataflash_maps_gps_att_pos_and_dvl(tmp_path):
    from formats import schemas as S
    write_dataflash(tmp_path / "00000012.BIN")
    by, info = messages(tmp_path, manifest(tmp_path, log("mavlink", "00000012.BIN")))
    (fix_t, fix), = by["/auv/gps"]
    assert fix_t == T0 and S.LocationFix.FromString(fix).latitude == pytest.approx(45.7022621)
    (ins_t, ins), = by["/auv/ins"]
    state = S.InsState.FromString(ins)
    assert ins_t == T0 + 10**9 and state.depth_m == pytest.approx(5.5) and state.heading_deg == pytest.approx(45.0)
    assert state.roll_deg == pytest.approx(2.0) and state.pitch_deg == pytest.approx(-3.0)
    dvl = {t: S.DvlVelocity.FromString(b) for t, b in by["/auv/dvl"]}
    assert dvl[T0 + 2 * 10**9].frame == S.DvlVelocity.EARTH_NED and dvl[T0 + 2 * 10**9].velocity_x_mps == 0.5
    assert dvl[T0 + 3 * 10**9].velocity_x_mps == pytest.approx(1.0) and dvl[T0 + 3 * 10**9].valid
    assert dvl[T0 + 4 * 10**9].altitude_m == 12.5
    stats = info["recording"]["files"][0]
    # every record is archived as itself (the 8 FMT records too, at boot); MSG is the vehicle's log line
    assert stats["ignored_reasons"] == {} and stats["skipped"] == 0 and stats["parsed"] == 15
    assert len(by["/auv/mavlink/FMT"]) == 8 and json.loads(by["/auv/mavlink/ATT"][0][1])["Yaw"] == 45.0
    (_, text), = by["/auv/log"]
    assert S.Log.FromString(text).message == "ArduSub V4.1.0"


def test_dataflash_without_gps_time_is_refused_not_guessed(tmp_path):
    write_dataflash(tmp_path / "nogps.BIN", with_gps=False)
    with pytest.raises(ManifestError, match='no GPS week and time; .*time_base = "boot" and start = '):
        messages(tmp_path, manifest(tmp_path, log("mavlink", "nogps.BIN")))


# ---------------------------------------------------------------- rotated logs

def test_rotated_gps_log_records_like_the_whole_file(tmp_path):
    data = (SAMPLE / "leader1" / "gps.log").read_bytes()
    lines = data.splitlines(keepends=True)
    a, b = len(lines) // 3, 2 * len(lines) // 3
    pieces = [b"".join(lines[:a]), b"".join(lines[a:b]), b"".join(lines[b:])]
    (tmp_path / "whole").mkdir()
    (tmp_path / "whole" / "gps.log").write_bytes(data)
    for i, piece in enumerate(pieces):
        (tmp_path / f"gps.log.{i}").write_bytes(piece)
    whole, w_info = messages(tmp_path, manifest(tmp_path, log("nmea", "whole/gps.log", "gps")), "w.mcap")
    for path, extra in (('"gps.log.*"', ""), ('["gps.log.2", "gps.log.0", "gps.log.1"]', 'order = "time"')):
        split, s_info = messages(tmp_path, manifest(tmp_path, log("nmea", path.strip('"') if "*" in path else path,
                                                                  "gps", extra)), "s.mcap")
        assert split == whole
        assert s_info["attachments"] == ["gps.log.0", "gps.log.1", "gps.log.2"]
        stats = s_info["recording"]["files"][0]
        assert [p["path"] for p in stats["parts"]] == ["gps.log.0", "gps.log.1", "gps.log.2"]
        assert all(0 < p["gap_s"] <= 1.0 for p in stats["parts"][1:])
        assert stats["parsed"] == w_info["recording"]["files"][0]["parsed"]
    from recorders.attachments import unpack
    result = unpack(tmp_path / "s.mcap", tmp_path / "out")
    assert not result.mismatched and not result.refused
    assert [(tmp_path / "out" / f"gps.log.{i}").read_bytes() for i in range(3)] == pieces


def test_rotated_log_gap_and_overlap_reported(tmp_path):
    lines = (SAMPLE / "leader1" / "gps.log").read_bytes().splitlines(keepends=True)
    (tmp_path / "g.1").write_bytes(b"".join(lines[:300]))
    (tmp_path / "g.2").write_bytes(b"".join(lines[600:900]))       # 100 s missing: 101 s from the last fix to the next
    (tmp_path / "g.3").write_bytes(b"".join(lines[850:1000]))      # overlaps g.2
    by, info = messages(tmp_path, manifest(tmp_path, log("nmea", "g.*", "gps")))
    notes = info["recording"]["files"][0]["notes"]
    assert notes == ["g.2: 101.000 s gap after the file before it", "g.3 overlaps the file before it by 16.000 s"]
    assert "/diagnostics" not in by  # rejected records only: none here


def test_manifest_examples_parse():
    from recorders.manifest import parse_manifest
    from recorders.registry import manifest_examples
    for fmt, example in manifest_examples().items():
        text = '[[vehicles]]\nname = "auv1"\nrole = "leader"\n' + example.replace("follower", "auv1")
        (spec,) = parse_manifest(text, Path("t.toml")).logs()
        assert (spec.sensor, spec.format) == ("", fmt)


def test_formats_command_lists_containers_with_examples(capsys):
    import json

    from replay.cli import main
    assert main(["formats"]) == 0
    text = capsys.readouterr().out
    for fmt in ("rosbag", "alog", "mavlink"):
        assert f"any     {fmt}" in text and f'format = "{fmt}"' in text
    assert main(["formats", "--json"]) == 0
    assert set(json.loads(capsys.readouterr().out)["any"]) == {"rosbag", "alog", "mavlink"}


def test_bad_paths_are_manifest_errors(tmp_path):
    with pytest.raises(ManifestError, match="no file matches"):
        load_manifest(manifest(tmp_path, log("nmea", "nothing.*", "gps")))
    with pytest.raises(ManifestError, match="order"):
        load_manifest(manifest(tmp_path, log("nmea", "x.log", "gps", 'order = "size"')))
    with pytest.raises(ManifestError, match="sensor"):
        load_manifest(manifest(tmp_path, log("nmea", "x.log")))
    with pytest.raises(ManifestError, match="several sensors"):
        load_manifest(manifest(tmp_path, log("rosbag", "x.bag", "gps")))


# ---------------------------------------------------------------- damaged input: no traceback

def _record_quietly(tmp: Path, fmt: str, name: str, data: bytes) -> None:
    (tmp / name).write_bytes(data)
    try:
        record(load_manifest(manifest(tmp, log(fmt, name))), tmp / "d.mcap", workers=1)
    except ManifestError as exc:  # a file that cannot be opened at all: one line naming it
        assert "\n" not in str(exc) and name in str(exc)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_damaged_bags_never_crash(bags, tmp_path, data):
    kind = data.draw(st.sampled_from(["ros1", "mcap", "sqlite3"]))
    raw = bytearray(bags[kind].read_bytes())
    cut = data.draw(st.integers(64, len(raw)))
    for _ in range(data.draw(st.integers(0, 6))):
        i = data.draw(st.integers(0, cut - 1))
        raw[i] = data.draw(st.integers(0, 255))
    _record_quietly(tmp_path, "rosbag", "x" + bags[kind].suffix, bytes(raw[:cut]))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_damaged_alogs_and_tlogs_never_crash(tmp_path, data):
    write_tlog(tmp_path / "ok.tlog")
    write_dataflash(tmp_path / "ok.BIN")
    sources = {"alog": ALOG.encode(), "mavlink": (tmp_path / "ok.tlog").read_bytes(),
               "dataflash": (tmp_path / "ok.BIN").read_bytes()}
    fmt = data.draw(st.sampled_from(sorted(sources)))
    raw = bytearray(sources[fmt])
    for _ in range(data.draw(st.integers(0, 10))):
        raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
    raw = raw[:data.draw(st.integers(1, len(raw)))]
    name = {"alog": "x.alog", "mavlink": "x.tlog", "dataflash": "x.BIN"}[fmt]
    _record_quietly(tmp_path, "mavlink" if fmt == "dataflash" else fmt, name, bytes(raw))
