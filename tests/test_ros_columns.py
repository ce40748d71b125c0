"""Issue 25: a bag's Imu messages read from their bytes go to the recording as columns (`recorders.base.Batch`,
from `recorders.rosbag._ImuBatch`), encoded by `formats.proto_encode`. The message-by-message path judges them: the same bytes message for message, and the
same archive, byte for byte, with the same statistics and refusals."""

from __future__ import annotations

import math
import struct
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import recorders.record as recording
from formats import ros_standard
from formats.proto_encode import encode_columns, split
from formats.records import Where
from recorders import rosbag as RB
from recorders.base import Batch, LogContext, Output
from recorders.manifest import load_manifest
from recorders.record import record
from tests.ros_bag_writer import write_bag
from tests.test_ros_standard import _message, _serialize, _store

NS = 10**9
T0 = 1476237600 * NS
NUMBERS = st.one_of(st.sampled_from([0.0, -0.0, 1.0, -1.0, math.nan, 1e12, -1e-300]),
                    st.floats(-1e6, 1e6, allow_nan=False))


def _bytes_of(items: list[Any]) -> list[tuple]:
    """Items as comparable values: an Output's topic, times, record and message bytes; a Reject as it is."""
    return [(i.topic, i.log_time_ns, i.publish_time_ns, i.where, i.message.SerializeToString())
            if type(i) is Output else i for i in items]


def _encoded(batch: Batch) -> list[tuple[str, bytes]]:
    """A Batch's messages as the recording writes them from its columns: (topic, bytes) in write order."""
    per_part = [iter(split(*encode_columns(p.message_class, len(p.log_times_ns), p.columns))) for p in batch.parts]
    return [(batch.parts[j].topic, next(per_part[j])) for j in np.asarray(batch.order).tolist()]


IMU_ROW = st.tuples(
    st.sampled_from([b"imu_link", b"imu_frd", b"base_link_ned"]),
    st.lists(NUMBERS, min_size=4, max_size=4),                          # orientation
    st.sampled_from([-1.0, 0.0, 1e-4, 1e12, math.nan]),                 # orientation_covariance[0]
    st.lists(NUMBERS, min_size=8, max_size=8),                          # the rest of it
    st.lists(NUMBERS, min_size=3, max_size=3), st.sampled_from([-1.0, 0.0, 0.5]),   # angular velocity, cov[0]
    st.lists(NUMBERS, min_size=3, max_size=3), st.sampled_from([-1.0, 0.0, 0.5]))   # linear acceleration, cov[0]


@settings(max_examples=80, deadline=None)
@given(rows=st.lists(IMU_ROW, min_size=1, max_size=8), before_1980=st.booleans())
def test_an_imu_batchs_columns_are_its_messages_one_by_one(rows, before_1980):
    """A batch of Imu messages: one Batch whose columns encode to the messages `_imu_state` builds, or (a row
    refused here, a time outside 1980-2100) the very items the one-by-one path gives."""
    fast, slow = RB._ImuBatch(LogContext("auv", batches=True)), RB._ImuBatch(LogContext("auv"))
    for k, (frame, q, c0, cov, av, av0, la, la0) in enumerate(rows):
        doubles = [*q, c0, *cov, *av, av0, *[0.0] * 8, *la, la0, *[0.0] * 8]
        data = bytes(16) + struct.pack("<37d", *doubles)
        t = (100 * NS if before_1980 and k == len(rows) - 1 else T0) + k
        for batch in (fast, slow):
            batch.add(t, t + 5, Where(40 * k, None, t, k + 1), frame, data)
    items, reference = list(fast.flush("/auv/ins/imu")), list(slow.flush("/auv/ins/imu"))
    assert all(type(i) is not Batch for i in reference)
    if len(items) == 1 and type(items[0]) is Batch:
        batch = items[0]
        assert not before_1980 and all(type(i) is Output for i in reference)
        assert _encoded(batch) == [("/auv/ins/imu", o.message.SerializeToString()) for o in reference]
        # its items, for the recording to take one by one, are those messages on the source's topic
        assert _bytes_of(list(batch.outputs())) == [("/auv/ins/imu", *rest) for _, *rest in _bytes_of(reference)]
        assert np.asarray(batch.keys).tolist() == [o.where.offset for o in reference]
    else:
        assert _bytes_of(items) == _bytes_of(reference)


def _bag(folder: Path, ros1: bool, seconds: int) -> Path:
    """A clean bag with what goes one by one among its messages: an Imu without orientation, or whose rates are
    not given, or whose sigma the value checks refuse; a NavSatFix without a fix, or with a negative variance; an
    Odometry with nothing in it; two Odometry topics, an Imu in a NED frame."""
    store = _store(ros1)
    T = store.types
    V3, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    streams = (("/imu/data", "sensor_msgs/msg/Imu", 40), ("/imu/ned", "sensor_msgs/msg/Imu", 7),
               ("/odometry/filtered", ros_standard.ODOMETRY, 10), ("/odometry/gps", ros_standard.ODOMETRY, 3),
               ("/gps/fix", ros_standard.NAVSATFIX, 5))
    items = []
    for topic, msgtype, rate in streams:
        for k in range(seconds * rate):
            t = T0 + k * NS // rate + 137
            stamp = (t // NS, t % NS)
            if msgtype == "sensor_msgs/msg/Imu":
                cov = np.full(9, 1e-4)
                cov[0] = -1.0 if k == 300 else 1e12 if k == 500 else 1e-4   # no orientation; a sigma refused
                msg = T[msgtype](header=T["std_msgs/msg/Header"](
                    **({"seq": 0} if ros1 else {}), stamp=T["builtin_interfaces/msg/Time"](sec=stamp[0],
                                                                                           nanosec=stamp[1]),
                    frame_id="imu_ned" if topic == "/imu/ned" else "imu_link"),
                    orientation=Q(x=0.0, y=0.0, z=math.sin(k / 100), w=math.cos(k / 100)), orientation_covariance=cov,
                    angular_velocity=V3(x=0.01, y=-0.02, z=k * 1e-3),
                    angular_velocity_covariance=np.full(9, -1.0 if k % 200 < 50 else 0.0),
                    linear_acceleration=V3(x=0.1, y=0.0, z=9.81),
                    linear_acceleration_covariance=np.full(9, -1.0 if 100 <= k % 400 < 150 else 0.0))
            elif msgtype == ros_standard.NAVSATFIX:
                numbers = [45.7 + 1e-6 * k, 126.6, -1.5, -1.0 if k == 33 else 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0,
                           2.0]
                msg = _message(store, ros1, msgtype, numbers, (stamp[0], stamp[1] - stamp[1] % 4 + (k % 4 != 3)),
                               ("gps", ""), n=2)
            else:
                numbers = [0.5 * k, 1.0, -2.0, 0.0, 0.0, math.sin(k / 50), math.cos(k / 50), 0.1, 0.0, 0.2]
                if k == 77:
                    numbers = [math.nan]
                msg = _message(store, ros1, msgtype, numbers, stamp, ("odom", "base_link"))
            items.append((t, topic, msgtype, _serialize(store, ros1, msg, msgtype)))
    items.sort()
    return write_bag(folder, ros1, store, streams, items)


@pytest.mark.parametrize("ros1", [True, False])
def test_a_bag_recorded_through_columns_is_the_bag_recorded_one_by_one(tmp_path, monkeypatch, ros1):
    """The same bag recorded with the recording's batches and without: byte-identical archives, the same
    statistics; the Imu messages went through Batches."""
    bag = _bag(tmp_path, ros1, 30)
    (tmp_path / "trial.toml").write_text(
        '[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "auv"\nrole = "follower"\n'
        f'[[vehicles.logs]]\nformat = "rosbag"\npath = "{bag.name}{"/" if bag.is_dir() else ""}"\n'
        'origin = [45.7, 126.6]\n')
    manifest = load_manifest(tmp_path / "trial.toml")
    taken: dict[str, int] = {}
    real = recording.LogRecorder._add_batch

    def counting(self: Any, batch: Batch) -> None:
        for part in batch.parts:
            taken[part.topic] = taken.get(part.topic, 0) + len(part.log_times_ns)
        real(self, batch)

    with monkeypatch.context() as m:
        m.setattr(recording.LogRecorder, "_add_batch", counting)
        fast = record(manifest, tmp_path / "fast.mcap", workers=1).files
    real_context = recording.log_context
    with monkeypatch.context() as m:
        m.setattr(recording, "log_context", lambda *a, **k: real_context(*a, **{**k, "batches": False}))
        slow = record(manifest, tmp_path / "slow.mcap", workers=1).files
    assert [asdict(f) for f in fast] == [asdict(f) for f in slow]
    assert (tmp_path / "fast.mcap").read_bytes() == (tmp_path / "slow.mcap").read_bytes()
    assert fast[0].skipped >= 5   # the Imu and Odometry refused, the fix and Imu the value checks refused
    # (an Imu batch with a message refused goes one by one: 512 of /imu/data's 1200)
    assert taken["/auv/ins/imu_data"] > 600 and taken["/auv/ins/imu_ned"] > 100


def test_a_where_made_through_its_slots_is_the_dataclass():
    """`_where` sets every field `Where` has (a field added there would be left unset here)."""
    import dataclasses
    assert [f.name for f in dataclasses.fields(Where)] == ["offset", "line", "host_time_ns", "message"]
    made, built = RB._where(12, T0, 3), Where(12, None, T0, 3)
    assert made == built and hash(made) == hash(built) and repr(made) == repr(built)
    with pytest.raises(dataclasses.FrozenInstanceError):
        made.offset = 1  # type: ignore[misc]
