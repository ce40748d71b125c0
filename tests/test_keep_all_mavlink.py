"""Every MAVLink message and dataflash record is kept as a message that the `mcap` library decodes by its schema.

Logs are built here (pymavlink's encoder, ArduPilot's dataflash layout), recorded, and read back with the `mcap`
library itself (CRCs checked): the messages archived plus the CRC rejects plus the records refused equal the
log's own record count as pymavlink reads it.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from formats import json_messages as J
from formats import schemas as S
from formats.mcap_reader import ArchiveReader
from recorders.manifest import load_manifest
from recorders.record import record
from tests.trial_shapes import dataflash_formats, dataflash_record, mavlink, tlog_bytes

US0 = 1476237600_000_000  # 2016-10-12 02:00:00 UTC, microseconds
DAMAGE = b"\x00garbage\x00"


def _packets(m: Any) -> list[tuple[int, Any]]:
    """An ArduSub telemetry minute in miniature: GPS of both kinds, EKF, attitude, text, modes, battery, RC."""
    out = []
    for k in range(5):
        us = US0 + k * 1_000_000
        out += [
            (us, m.heartbeat_encode(12, 3, 81, 19, 4)),
            (us + 1, m.gps_raw_int_encode(us, 3, 457022621 + k, 1265974195, 1000, 90, 200, 462, 9041, 8)),
            (us + 2, m.gps_input_encode(us, 0, 0, 0, 0, 3, 457023000 + k, 1265975000, -5.5, 1.1, 0.9, 0.5, 0.2,
                                        0.25, 0, 0, 0, 7)),
            (us + 3, m.attitude_encode(k * 100, 0.01, -0.02, 0.7, 0, 0, 0)),
            (us + 4, m.global_position_int_encode(k * 100, 457022000, 1265974000, 100000, -5500, 100, -50, 10,
                                                  4500)),
            (us + 5, m.scaled_pressure2_encode(k * 100, 1500.0, 0.5, 1800)),
            (us + 6, m.sys_status_encode(0, 0, 0, 500, 15800, -1, 80, 0, 0, 0, 0, 0, 0)),
            (us + 7, m.rc_channels_raw_encode(k * 100, 0, 1500, 1500, 1500, 1500, 1100, 1900, 1500, 1500, 255)),
        ]
    out.append((US0 + 5_000_000, m.statustext_encode(4, b"Leak detected")))
    out.append((US0 + 5_000_001, m.param_value_encode(b"SURFACE_DEPTH", -10.0, 9, 900, 12)))
    return out


def write_tlog(path: Path, bad_crc: int = 2) -> int:
    """A tlog of `_packets` with the last `bad_crc` packets' CRCs broken and garbage at the end; its bytes' count
    of packets."""
    m = mavlink()
    packets = _packets(m)
    data = bytearray()
    for i, (us, pkt) in enumerate(packets):
        one = bytearray(tlog_bytes(m, [(us, pkt)]))
        if i >= len(packets) - bad_crc:
            one[-1] ^= 0xFF  # the CRC's high byte
        data += one
    path.write_bytes(bytes(data) + DAMAGE)
    return len(packets)


BIN_TYPES = {
    "GPS": (130, "QBIHBcLLeff", "TimeUS,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt,Spd,GCrs"),
    "ATT": (131, "Qccf", "TimeUS,Roll,Pitch,Yaw"),
    "POS": (132, "QLLff", "TimeUS,Lat,Lng,Alt,RelHomeAlt"),
    "MSG": (136, "QZ", "TimeUS,Message"),
    "BAT": (137, "Qff", "TimeUS,Volt,Curr"),
}


def write_bin(path: Path) -> None:
    """A dataflash log: FMT records, GPS with its week and time, attitude, EKF position, battery, a text."""
    out = dataflash_formats(BIN_TYPES)
    boot = 1_000_000
    out += dataflash_record(130, BIN_TYPES["GPS"][1], boot, 3, 266_417_000, 1918, 9, 90, 457022621, 1265974195,
                            10987, 2.3, 90.4)
    for k in range(4):
        t = boot + (k + 1) * 200_000
        out += dataflash_record(131, "Qccf", t, 200, -300, 45.0 + k)
        out += dataflash_record(132, "QLLff", t + 1, 457022000, 1265974000, 100.0, -5.5)
        out += dataflash_record(137, "Qff", t + 2, 15.8, float("nan"))  # a NaN: null in JSON
    out += dataflash_record(136, "QZ", boot + 2_000_000, b"ArduSub V4.1.0")
    path.write_bytes(out)


def pymavlink_count(path: Path) -> tuple[int, int]:
    """(records, CRC failures) as pymavlink reads the log: its messages, but not bytes that frame no packet."""
    from pymavlink import DFReader, mavutil

    if path.read_bytes()[:2] == b"\xa3\x95":
        os.environ["PYMAVLINK_FAST_INDEX"] = "0"
        conn: Any = DFReader.DFReader_binary(str(path), zero_time_base=False)
    else:
        mavutil.set_dialect("ardupilotmega")
        conn = mavutil.mavlogfile(str(path), notimestamps=False)
    records = crc = 0
    while (msg := conn.recv_match()) is not None:
        if msg.get_type() == "BAD_DATA":
            if "CRC" in str(getattr(msg, "reason", "")):
                records, crc = records + 1, crc + 1
            continue
        records += 1
    return records, crc


def trial(tmp: Path, *logs: str) -> Path:
    text = '[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "sub"\nrole = "follower"\n'
    text += "".join(f'[[vehicles.logs]]\nformat = "mavlink"\npath = "{name}"\n' for name in logs)
    (tmp / "trial.toml").write_text(text)
    return tmp / "trial.toml"


def _type_ok(value: Any, schema: dict) -> bool:
    """Whether a JSON value is of its JSON Schema's type (the keywords `object_schema` writes)."""
    kinds = schema.get("type")
    if kinds is None:
        return True
    kinds = kinds if isinstance(kinds, list) else [kinds]
    python = {"null": type(None), "boolean": bool, "string": str, "array": list, "object": dict,
              "number": (int, float), "integer": int}
    if not any(isinstance(value, python[k]) and not (k in ("number", "integer") and isinstance(value, bool))
               for k in kinds):
        return False
    if isinstance(value, list) and "items" in schema:
        return all(_type_ok(v, schema["items"]) for v in value)
    if isinstance(value, dict):
        props = schema.get("properties", {})
        return all(_type_ok(v, props[k]) for k, v in value.items() if k in props)
    return True


def mcap_library_messages(path: Path) -> dict[str, list[tuple[str, Any]]]:
    """Every message by topic as the `mcap` library reads it (CRCs checked): JSON decoded and checked against
    its JSON Schema, protobuf decoded by its schema name."""
    out: dict[str, list[tuple[str, Any]]] = {}
    with path.open("rb") as fh:
        reader = make_reader(fh, validate_crcs=True)
        for schema, channel, msg in reader.iter_messages():
            assert schema is not None
            if channel.message_encoding == "json":
                assert schema.encoding == "jsonschema"
                doc = json.loads(schema.data)
                value = json.loads(msg.data)
                assert _type_ok(value, doc), (channel.topic, value)
                assert set(value) <= set(doc["properties"])
            else:
                assert channel.message_encoding == "protobuf" and schema.encoding == "protobuf"
                value = S.MESSAGE_CLASSES[schema.name].FromString(msg.data)
            out.setdefault(channel.topic, []).append((schema.name, value))
    return out


def test_every_tlog_message_is_archived_or_counted(tmp_path):
    written = write_tlog(tmp_path / "sub.tlog", bad_crc=2)
    out = tmp_path / "a.mcap"
    summary = record(load_manifest(trial(tmp_path, "sub.tlog")), out, workers=1)
    stats = summary.files[0]
    records, crc = pymavlink_count(tmp_path / "sub.tlog")
    assert (records, crc) == (written, 2)
    by = mcap_library_messages(out)
    raw = sum(len(v) for k, v in by.items() if k.startswith("/sub/mavlink/"))
    # archived + CRC rejects + refused with a reason (bytes that frame no packet are no record of pymavlink's;
    # after a broken packet pymavlink's resync takes in the garbage at the end)
    assert stats.bad_checksum == 2 and stats.skipped in (2, 3)
    assert raw + stats.bad_checksum == records and stats.parsed == raw
    assert raw / (records - crc) >= 0.99
    assert {k.rsplit("/", 1)[1] for k in by if k.startswith("/sub/mavlink/")} == {
        "HEARTBEAT", "GPS_RAW_INT", "GPS_INPUT", "ATTITUDE", "GLOBAL_POSITION_INT", "SCALED_PRESSURE2",
        "SYS_STATUS", "RC_CHANNELS_RAW"}  # STATUSTEXT and PARAM_VALUE are the two whose CRC was broken
    (name, heartbeat), *_ = by["/sub/mavlink/HEARTBEAT"]
    assert name == "mavlink.HEARTBEAT" and heartbeat["custom_mode"] == 19 and heartbeat["type"] == 12
    assert by["/sub/mavlink/SCALED_PRESSURE2"][0][1]["press_abs"] == 1500.0
    # mapped ones are archived as ours as well; GPS_INPUT and GPS_RAW_INT are separate sources
    assert len(by["/sub/gps"]) == 5 and len(by["/sub/gps/input"]) == 5
    assert [v.latitude for _, v in by["/sub/gps/input"]] == pytest.approx([45.7023 + k * 1e-7 for k in range(5)])
    assert len(by["/sub/ins"]) == 5
    # the diagnostics name the bad CRCs' byte offsets
    with ArchiveReader(out) as reader:
        lines = [m.message.message for m in reader.messages(["/diagnostics"])]
    assert sum("bad crc at byte " in line and "invalid MAVLink CRC" in line for line in lines) == 2


def test_statustext_is_the_vehicles_log(tmp_path):
    write_tlog(tmp_path / "sub.tlog", bad_crc=0)
    out = tmp_path / "a.mcap"
    stats = record(load_manifest(trial(tmp_path, "sub.tlog")), out, workers=1).files[0]
    by = mcap_library_messages(out)
    (_, log), = by["/sub/log"]
    assert log.message == "Leak detected" and log.level == S.Log.WARNING and log.name == "sub"
    assert by["/sub/mavlink/PARAM_VALUE"][0][1]["param_id"] == "SURFACE_DEPTH"
    records, crc = pymavlink_count(tmp_path / "sub.tlog")
    assert crc == 0 and stats.parsed == records and stats.skipped == 1 and stats.bad_checksum == 0


def test_every_dataflash_record_is_archived(tmp_path):
    write_bin(tmp_path / "00000001.BIN")
    out = tmp_path / "a.mcap"
    stats = record(load_manifest(trial(tmp_path, "00000001.BIN")), out, workers=1).files[0]
    records, crc = pymavlink_count(tmp_path / "00000001.BIN")
    by = mcap_library_messages(out)
    raw = sum(len(v) for k, v in by.items() if k.startswith("/sub/mavlink/"))
    assert crc == 0 and raw == records == stats.parsed and stats.skipped == 0
    assert len(by["/sub/mavlink/FMT"]) == 1 + len(BIN_TYPES)
    bat = [v for _, v in by["/sub/mavlink/BAT"]]
    assert [b["Curr"] for b in bat] == [None] * 4 and bat[0]["Volt"] == pytest.approx(15.8)
    assert [v["Yaw"] for _, v in by["/sub/mavlink/ATT"]] == [45.0, 46.0, 47.0, 48.0]
    assert by["/sub/log"][0][1].message == "ArduSub V4.1.0"
    assert by["/sub/mavlink/GPS"][0][0] == "dataflash.GPS"


def test_parallel_recording_writes_the_same_archive(tmp_path):
    write_tlog(tmp_path / "sub.tlog")
    write_bin(tmp_path / "00000001.BIN")
    m = load_manifest(trial(tmp_path, "sub.tlog", "00000001.BIN"))
    record(m, tmp_path / "one.mcap", workers=1)
    record(m, tmp_path / "two.mcap", workers=2)
    assert (tmp_path / "one.mcap").read_bytes() == (tmp_path / "two.mcap").read_bytes()
    with ArchiveReader(tmp_path / "two.mcap") as reader:
        topics = {m.topic for m in reader.messages()}
        assert reader.warning() is None  # JSON channels are read, not skipped as damage
    assert "/sub/mavlink/HEARTBEAT" in topics and "/sub/mavlink/FMT" in topics


_json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-2**63, 2**64) | st.floats() | st.text(max_size=8)
    | st.binary(max_size=8),
    lambda inner: st.lists(inner, max_size=4), max_leaves=8)


@settings(max_examples=200)
@given(st.dictionaries(st.text(min_size=1, max_size=6), _json_values, max_size=6))
def test_any_record_is_json_of_its_schema(fields):
    value = J.plain(fields)
    schema = J.object_schema("t.T", value)
    decoded = J.message("t.T", J.schema_text(schema), fields).value
    assert decoded == value and _type_ok(decoded, json.loads(J.schema_text(schema)))
    for k, v in fields.items():
        if isinstance(v, float) and not math.isfinite(v):
            assert decoded[k] is None
        if isinstance(v, bytes):
            assert decoded[k] == list(v)
