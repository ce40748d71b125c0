"""Fuzz targets of the importers: whole damaged files through the real `record`, one temp folder per entry.

Each target starts from small valid files built as the tests build them (tests.hostile, tests.trial_shapes,
tests.test_ecosystem_inputs) and damages the whole file: ROS 1 bags (flips, cuts, absurd record and field
lengths, hostile header values, decompression bombs), ROS 2 `.db3` databases (valid sqlite with hostile rows:
NULL, negative, huge and mistyped timestamps, data that is no blob or a cut CDR blob, unknown topics and
types, damaged definitions and metadata), MOOS alogs (damaged lines, huge values, control characters, lines
split in two), MAVLink tlogs (flips, cuts, bad CRCs, absurd lengths and times) and ArduPilot `.BIN` files
(damaged FMT records, absurd lengths). A case is written into the entry's folder next to its manifest and
recorded with `recorders.record.record`: it must give an archive (its damage a counted skip) or one line of
ManifestError, FormatError or UserError; any other exception, a case over HANG_S, or a file left behind
in the folder is a failure.
"""

from __future__ import annotations

import bz2
import contextlib
import functools
import os
import random
import resource
import shutil
import signal
import sqlite3
import struct
import tempfile
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from formats.records import FormatError
from recorders.manifest import ManifestError, load_manifest
from recorders.record import record
from replay.errors import UserError

HANG_S = 5.0   # a case using more CPU than this, or not ending in twice this wall time, is a hang
T0 = 1_476_259_200 * 10**9
HOSTILE_NUMBERS = ("nan", "inf", "-inf", "1e400", "-1e400", "9" * 400, "1e-400", "0", "-0", "1e30", "+", ".",
                   "0x1F", "٣", "")
_U32 = struct.Struct("<I")


class Hang(BaseException):
    """A case ran past its bound (a BaseException: the code under test must not swallow it)."""


@contextlib.contextmanager
def bounded(seconds: float) -> Iterator[None]:
    """Raise Hang in the block after `seconds` (in the main thread; elsewhere only measured by the caller)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(signum: int, frame: object) -> None:
        raise Hang(f"over {seconds:.0f} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def cpu_seconds() -> float:
    """CPU time of this process (every thread) and of its waited-for children: a case's own work, which a
    machine shared with other jobs does not inflate as it inflates wall time."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def peak_rss_mb() -> float:
    """This process's own peak RSS (VmHWM, MB): ru_maxrss would keep a forking parent's high-water mark."""
    with open("/proc/self/status") as f:
        kb = next(int(line.split()[1]) for line in f if line.startswith("VmHWM"))
    return kb / 1024


# ---- byte damage shared by the binary targets -----------------------------------------------------------------
_ABSURD_U32 = (0xFFFFFFFF, 0x7FFFFFFF, 0x80000000, 1 << 30, 1 << 24, 0, 1)


def byte_damage(data: bytes, rng: random.Random, keep: int = 0) -> bytes:
    """A few flips, insertions, deletions, repeats and cuts after the first `keep` bytes."""
    out = bytearray(data)
    for _ in range(rng.randrange(1, 5)):
        n = len(out)
        if n <= keep:
            break
        op = rng.random()
        at = rng.randrange(keep, n)
        if op < 0.4:
            out[at] ^= 1 << rng.randrange(8) if rng.random() < 0.7 else rng.randrange(1, 256)
        elif op < 0.55:
            out[at:at] = rng.randbytes(rng.randrange(1, 32))
        elif op < 0.7:
            del out[at:at + rng.randrange(1, 64)]
        elif op < 0.8:
            out[at:at] = out[at:at + rng.randrange(1, 300)]
        elif op < 0.9:
            out[at:at + 4] = _U32.pack(rng.choice(_ABSURD_U32))
        else:
            del out[at:]
    return bytes(out)


# ---- ROS 1 bags ---------------------------------------------------------------------------------------------
def _gga(i: int) -> bytes:
    from formats.nmea.framing import nmea_checksum
    body = f"GPGGA,08{i // 60:02d}{i % 60:02d}.00,4542.{i:04d},N,12636.0000,E,1,08,0.9,10.0,M,0.0,M,,"
    return f"${body}*{nmea_checksum(body):02X}".encode()


def _fixes(start: int, n: int) -> list[tuple[int, bytes]]:
    from tests.hostile import ros_string
    return [(T0 + (start + i) * 10**9, ros_string(_gga(start + i))) for i in range(n)]


def _rich_bag() -> bytes:
    """A rosbags-written bag of NavSatFix, Imu and Odometry (their definitions carried in the bag)."""
    from tests.trial_shapes import enu_quaternion, imu, navsatfix, odometry, ros1_typestore, write_ros1
    ts = ros1_typestore()
    items = []
    for k in range(3):
        t = T0 + k * 10**9
        items += [navsatfix(ts, t, 45.7 + k * 1e-5, 126.6, status=0), imu(ts, t + 1000, enu_quaternion(ts, 30.0)),
                  odometry(ts, t + 2000, 10.0 * k, 5.0, -2.0, enu_quaternion(ts, 30.0), 1.5)]
    with tempfile.TemporaryDirectory(prefix="fuzz-bag-") as tmp:
        write_ros1(Path(tmp) / "a.bag", ts, items)
        return (Path(tmp) / "a.bag").read_bytes()


@functools.lru_cache(maxsize=1)
def ros1_seeds() -> tuple[list[bytes], list[bytes]]:
    """(valid bags, bombs): String bags of each compression, a bag of typed messages; chunks that inflate
    far past what they declare, or declare far past the readers' cap."""
    from tests.hostile import ros1_bag
    chunks = [_fixes(0, 4), _fixes(4, 4)]
    valid = [ros1_bag(chunks, compression=c) for c in ("bz2", "lz4", "none")] + [_rich_bag()]
    bomb = bz2.compress(bytes(8 << 20), 9) * 16   # 128 MiB of zeros in ~700 bytes
    bombs = [ros1_bag(chunks, chunk_data={1: bomb}), ros1_bag(chunks, chunk_data={0: bomb}, declared={0: 3 << 30}),
             ros1_bag(chunks, chunk_data={1: bomb}, declared={1: 200})]
    return valid, bombs


def ros1_fields(data: bytes) -> tuple[list[int], list[tuple[int, int]]]:
    """(offsets of every length field, (offset, size) of every header field's value) of a bag's top-level records."""
    lengths: list[int] = []
    values: list[tuple[int, int]] = []
    pos = 13   # after "#ROSBAG V2.0\n"
    while pos + 4 <= len(data):
        (hlen,) = _U32.unpack_from(data, pos)
        lengths.append(pos)
        p, end = pos + 4, pos + 4 + hlen
        if end + 4 > len(data):
            break
        while p + 4 <= end:
            (flen,) = _U32.unpack_from(data, p)
            lengths.append(p)
            eq = data.find(b"=", p + 4, p + 4 + flen)
            if eq > 0:
                values.append((eq + 1, p + 4 + flen - eq - 1))
            p += 4 + flen
        lengths.append(end)
        pos = end + 4 + _U32.unpack_from(data, end)[0]
    return lengths, values


def ros1_case(rng: random.Random) -> bytes:
    """A damaged ROS 1 bag: a bomb, or a valid bag with record lengths, header values or bytes damaged."""
    valid, bombs = ros1_seeds()
    if rng.random() < 0.02:
        return rng.choice(bombs)
    data = bytearray(rng.choice(valid))
    for _ in range(rng.randrange(1, 4)):
        lengths, values = ros1_fields(bytes(data))
        lengths = [at for at in lengths if at + 4 <= len(data)]
        values = [(at, size) for at, size in values if at + size <= len(data)]
        op = rng.random()
        if op < 0.3 and lengths:
            at = rng.choice(lengths)
            data[at:at + 4] = _U32.pack(rng.choice(_ABSURD_U32 + (len(data), (_U32.unpack_from(data, at)[0] + 1) % 2**32)))
        elif op < 0.6 and values:
            at, size = rng.choice(values)
            fill = rng.choice([b"\xff" * size, bytes(size), rng.randbytes(size), b"\x7f" + b"\xff" * (size - 1)])
            data[at:at + size] = fill[:size]
        else:
            data = bytearray(byte_damage(bytes(data), rng, keep=13 if rng.random() < 0.9 else 0))
    return bytes(data)


# ---- ROS 2 .db3 ---------------------------------------------------------------------------------------------
_RELAX = {  # every table of rosbags' sqlite3 storage without its NOT NULL and types: rows as another tool may leave
    "messages": "id INTEGER PRIMARY KEY, topic_id, timestamp, data",
    "topics": "id INTEGER PRIMARY KEY, name, type, serialization_format, offered_qos_profiles, type_description_hash",
    "message_definitions": "id INTEGER PRIMARY KEY, topic_type, encoding, encoded_message_definition, "
                           "type_description_hash",
    "metadata": "id INTEGER PRIMARY KEY, metadata_version, metadata",
    "schema": "schema_version, ros_distro",
}


@functools.lru_cache(maxsize=1)
def db3_seeds() -> tuple[bytes, bytes]:
    """(as rosbags writes it, the same with every table relaxed): /nmea Strings and /gps/fix NavSatFixes."""
    import numpy as np
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    String, Fix = T["std_msgs/msg/String"], T["sensor_msgs/msg/NavSatFix"]
    with tempfile.TemporaryDirectory(prefix="fuzz-db3-") as tmp:
        with Writer(Path(tmp) / "bag", version=8, storage_plugin=StoragePlugin.SQLITE3) as w:
            nmea = w.add_connection("/nmea", String.__msgtype__, typestore=store)
            fix = w.add_connection("/gps/fix", "sensor_msgs/msg/NavSatFix", typestore=store)
            for i in range(6):
                w.write(nmea, T0 + i * 10**9, store.serialize_cdr(String(data=_gga(i).decode()), String.__msgtype__))
                t = T0 + i * 10**9 + 500
                header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=t // 10**9,
                                                  nanosec=t % 10**9), frame_id="gps")
                msg = Fix(header=header, status=T["sensor_msgs/msg/NavSatStatus"](status=0, service=1),
                          latitude=45.7 + i * 1e-5, longitude=126.6, altitude=0.0,
                          position_covariance=np.eye(3).flatten(), position_covariance_type=2)
                w.write(fix, t, store.serialize_cdr(msg, Fix.__msgtype__))
        db = next((Path(tmp) / "bag").glob("*.db3"))
        plain = db.read_bytes()
        with contextlib.closing(sqlite3.connect(db)) as con, con:
            for table, columns in _RELAX.items():
                con.executescript(f"ALTER TABLE {table} RENAME TO old_{table}; CREATE TABLE {table}({columns});"
                                  f"INSERT INTO {table} SELECT * FROM old_{table}; DROP TABLE old_{table};")
        return plain, db.read_bytes()


_TIMES = ("NULL", "-1", "-9223372036854775808", "9223372036854775807", "18446744073709551615", "1e300", "-0.0",
          "1.5", "'soon'", "x'00ff'", "0", "'1476259200000000000'", "9.2e18")
_DATA = ("NULL", "42", "'text'", "x''", "substr(data, 1, abs(random()) % max(length(data), 1))", "randomblob(40)",
         "x'000100000000ffff'", "x'00010000ffffff7f41'", "zeroblob(300000)", "data || randomblob(5)", "3.5")
_TOPIC_IDS = ("999", "NULL", "-1", "'x'", "1.5", "0")
_TOPIC_VALUES = {
    "type": ("'no_such/msg/Type'", "''", "NULL", "'std_msgs/msg/String' || char(0)", "'sensor_msgs/msg/Imu'",
             "'../../etc'", "42"),
    "serialization_format": ("'ros1'", "''", "NULL", "'cdr' || char(10)", "7"),
    "name": ("''", "NULL", "'/x' || char(0) || 'y'", "'/nmea'", "'/gps/fix'", "x'ff00'", "printf('%.4000c', 'n')"),
    "offered_qos_profiles": ("'- ['", "NULL", "'{a: [1, 2'", "'- history: 99999999999999999999'", "x'00'"),
}
_DEFINITION_VALUES = {
    "encoded_message_definition": ("'int32 x\nfoo bar baz'", "''", "NULL", "'string data\n' || char(0)",
                                   "'uint8[99999999999] a'", "'module a { struct b { long c; }; };'",
                                   "'sensor_msgs/NavSatFix loop\n'"),
    "encoding": ("'ros2idl'", "'unknown'", "NULL", "''"),
    "topic_type": ("NULL", "'std_msgs/msg/Header'", "'a/b/c/d'"),
}


def db3_statements(rng: random.Random) -> list[str]:
    """A few hostile statements on a relaxed .db3: rows, topics, definitions, metadata and tables spoiled."""
    out = []
    for _ in range(rng.randrange(1, 5)):
        op = rng.random()
        row = rng.choice([f"id = {rng.randrange(1, 14)}", "id % 2 = 0", "1"])
        if op < 0.25:
            out.append(f"UPDATE messages SET timestamp = {rng.choice(_TIMES)} WHERE {row}")
        elif op < 0.45:
            out.append(f"UPDATE messages SET data = {rng.choice(_DATA)} WHERE {row}")
        elif op < 0.55:
            out.append(f"UPDATE messages SET topic_id = {rng.choice(_TOPIC_IDS)} WHERE {row}")
        elif op < 0.62:
            out.append(f"INSERT INTO messages(topic_id, timestamp, data) VALUES ({rng.choice(_TOPIC_IDS)}, "
                       f"{rng.choice(_TIMES)}, {rng.choice(_DATA).replace('data', 'x' + repr('00'))})")
        elif op < 0.75:
            column = rng.choice(list(_TOPIC_VALUES))
            out.append(f"UPDATE topics SET {column} = {rng.choice(_TOPIC_VALUES[column])} "
                       f"WHERE id = {rng.randrange(1, 3)}")
        elif op < 0.8:
            out.append("INSERT INTO topics VALUES (NULL, '/extra', 'no_such/msg/T', 'cdr', '', '')")
        elif op < 0.88:
            column = rng.choice(list(_DEFINITION_VALUES))
            out.append(f"UPDATE message_definitions SET {column} = {rng.choice(_DEFINITION_VALUES[column])} "
                       f"WHERE id = {rng.randrange(1, 3)}")
        elif op < 0.93:
            out.append(rng.choice(["UPDATE metadata SET metadata = '{[: bad yaml'", "UPDATE metadata SET metadata = NULL",
                                   "UPDATE metadata SET metadata_version = 99", "DELETE FROM metadata",
                                   "UPDATE metadata SET metadata = printf('%.200000c', 'a')"]))
        elif op < 0.97:
            out.append(rng.choice(["UPDATE schema SET schema_version = 99", "UPDATE schema SET schema_version = NULL",
                                   "UPDATE schema SET schema_version = 'x'", "DELETE FROM schema",
                                   "DROP TABLE schema"]))
        else:
            out.append(rng.choice(["DROP TABLE topics", "DROP TABLE messages", "DROP TABLE message_definitions",
                                   "DELETE FROM messages", "DELETE FROM topics", "DROP INDEX IF EXISTS timestamp_idx",
                                   "DROP TABLE metadata"]))
    return out


def db3_case(rng: random.Random, path: Path) -> None:
    """A hostile .db3 at `path`: the relaxed seed with statements run on it, or (a few) its bytes damaged."""
    plain, relaxed = db3_seeds()
    kind = rng.random()
    if kind < 0.1:   # rosbags' own NOT NULL tables, their bytes damaged (no longer a sound database)
        path.write_bytes(byte_damage(plain, rng, keep=16))
        return
    path.write_bytes(relaxed)
    with contextlib.closing(sqlite3.connect(path)) as con, con:
        for sql in db3_statements(rng):
            with contextlib.suppress(sqlite3.Error):   # a statement on a table an earlier one dropped
                con.execute(sql)
    if kind > 0.95:
        path.write_bytes(byte_damage(path.read_bytes(), rng, keep=100))


# ---- MOOS alogs ---------------------------------------------------------------------------------------------
_CONTROL = ("\x00", "\x1b[2J", "\r", "\x0b", "\x0c", "\x85", "\u2028", "\x7f", "\t\t", "\ufeff", "\udcff")


def alog_case(rng: random.Random) -> bytes:
    """The alog seed with lines cut, values made huge or hostile, control characters, lines split or joined."""
    from tests.test_ecosystem_inputs import ALOG
    lines = ALOG.splitlines(keepends=True)
    for _ in range(rng.randrange(1, 6)):
        i = rng.randrange(len(lines))
        line = lines[i].rstrip("\n")
        op = rng.random()
        fields = line.split(None, 3)
        if op < 0.15:
            lines[i] = line[:rng.randrange(len(line) + 1)] + "\n"
        elif op < 0.35 and len(fields) == 4:   # the value (or the time) hostile, huge or long
            value = rng.choice([*HOSTILE_NUMBERS, "x" * 70_000, "1" * 5000, "vname=a,range=" + "9" * 300,
                                ",".join(f"k{j}={j}" for j in range(2000)), "=,=,=", "range=nan,time=inf"])
            at = 3 if rng.random() < 0.7 else 0
            fields[at] = value
            lines[i] = " ".join(fields) + "\n"
        elif op < 0.55:
            at = rng.randrange(len(line) + 1)
            lines[i] = line[:at] + rng.choice(_CONTROL) * rng.randrange(1, 4) + line[at:] + "\n"
        elif op < 0.7:   # one line split in two (a value over two lines), or two lines joined
            at = rng.randrange(len(line) + 1)
            lines[i] = line[:at] + "\n" + line[at:] + "\n" if rng.random() < 0.6 else line + " "
        elif op < 0.8:
            lines.insert(i, lines[i] if rng.random() < 0.5 else lines[rng.randrange(len(lines))])
        elif op < 0.9:   # the header's start time hostile
            lines[1] = f"%% LOGSTART {rng.choice(HOSTILE_NUMBERS)}\n"
        else:
            del lines[i]
    out = "".join(lines).encode("utf-8", "surrogateescape")
    return byte_damage(out, rng) if rng.random() < 0.2 else out


# ---- MAVLink tlogs ------------------------------------------------------------------------------------------
def tlog_packets() -> list[tuple[int, bytes]]:
    """(time in us, MAVLink 2 packet) of the ecosystem tests' tlog."""
    from tests.test_ecosystem_inputs import write_tlog
    with tempfile.TemporaryDirectory(prefix="fuzz-tlog-") as tmp:
        write_tlog(Path(tmp) / "t.tlog")
        data = (Path(tmp) / "t.tlog").read_bytes()
    out, pos = [], 0
    while pos < len(data):
        n = 12 + data[pos + 9] + (13 if data[pos + 10] & 1 else 0)  # after the time: magic 0xFD, length, ...
        out.append((struct.unpack_from(">Q", data, pos)[0], data[pos + 8:pos + 8 + n]))
        pos += 8 + n
    return out


_packets = functools.lru_cache(maxsize=1)(tlog_packets)


def tlog_case(rng: random.Random) -> bytes:
    """The tlog's packets with flips, cuts, bad CRCs, absurd lengths and times, stray magic bytes."""
    packets = [[us, bytearray(p)] for us, p in _packets()]
    for _ in range(rng.randrange(1, 4)):
        k = rng.randrange(len(packets))
        us, pkt = packets[k]
        op = rng.random()
        if op < 0.2 and len(pkt) > 2:
            pkt[-1 - rng.randrange(2)] ^= 1 << rng.randrange(8)   # bad CRC
        elif op < 0.35 and len(pkt) > 2:
            pkt[1] = rng.choice([0, 1, 255, (pkt[1] + 1) % 256, max(pkt[1] - 1, 0)])   # absurd payload length
        elif op < 0.5:
            packets[k][0] = rng.choice([0, 2**64 - 1, 2**63, us - 10**12, us * 1000 % 2**64])
        elif op < 0.6 and pkt:
            pkt[0] = rng.choice([0xFE, 0x00, 0xFD, 0x55])
        elif op < 0.7:
            packets.insert(k, [us, bytearray(b"\xfd" + rng.randbytes(rng.randrange(0, 40)))])
        elif op < 0.8:
            packets.insert(k, [us, pkt[:]])
        elif op < 0.9 and len(pkt) > 2:
            pkt[2] |= 1   # "signed", without a signature
        elif pkt:
            del pkt[rng.randrange(len(pkt)):]
    out = b"".join(struct.pack(">Q", us % 2**64) + bytes(p) for us, p in packets)
    return byte_damage(out, rng) if rng.random() < 0.4 else out


# ---- ArduPilot dataflash .BIN -------------------------------------------------------------------------------
_FMT_CHARS = "abBhHiIfdnNZcCeELMqQX?"


@functools.lru_cache(maxsize=1)
def bin_seed() -> bytes:
    """An ArduSub dive without GPS (tests.trial_shapes.write_nogps_bin, two seconds)."""
    from tests.trial_shapes import write_nogps_bin
    with tempfile.TemporaryDirectory(prefix="fuzz-bin-") as tmp:
        write_nogps_bin(Path(tmp) / "a.BIN", seconds=2)
        return (Path(tmp) / "a.BIN").read_bytes()


def bin_case(rng: random.Random) -> bytes:
    """The .BIN with FMT records damaged (lengths, formats, names, type ids) and absurd lengths or bytes."""
    data = bytearray(bin_seed())
    fmts = [i for i in range(len(data) - 2) if data[i:i + 3] == b"\xa3\x95\x80"]
    for _ in range(rng.randrange(1, 4)):
        at = rng.choice(fmts)
        op = rng.random()
        if op < 0.25:   # the record length it declares
            data[at + 4] = rng.choice([0, 1, 2, 3, 4, 255, data[at + 4] + 1, max(data[at + 4] - 1, 0)])
        elif op < 0.5:  # its format string
            fmt = "".join(rng.choice(_FMT_CHARS) for _ in range(rng.randrange(0, 17)))
            data[at + 9:at + 25] = fmt.encode().ljust(16, b"\0")
        elif op < 0.6:  # its name
            data[at + 5:at + 9] = rng.choice([b"FMT\0", b"\0\0\0\0", b"\xff\xfe\x00A", b"ATT\0", b"GPS\0", b"MSG\0"])
        elif op < 0.7:  # the type it defines: FMT itself, another's, or a new one
            data[at + 3] = rng.choice([128, 131, 140, 0, 255, rng.randrange(256)])
        elif op < 0.8:  # its columns: too few, too many, empty, not text
            cols = rng.choice([b"", b"a", b",".join(b"c%d" % j for j in range(40)), b"\xff\xfe", b"TimeUS,,,,"])
            data[at + 25:at + 89] = cols[:64].ljust(64, b"\0")
        elif op < 0.9:  # a stray record header with a type of any kind
            pos = rng.randrange(len(data))
            data[pos:pos] = b"\xa3\x95" + bytes([rng.randrange(256)]) + rng.randbytes(rng.randrange(0, 20))
        else:           # a record cut short
            end = at + rng.randrange(1, 89)
            del data[end:end + rng.randrange(1, 89)]
    out = bytes(data)
    return byte_damage(out, rng) if rng.random() < 0.4 else out


# ---- the entries --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Target:
    """One importer entry: the file a case is written to, the manifest's log lines, the case builder."""

    filename: str
    log: str
    build: Callable[[random.Random, Path], None]


def _bytes(make: Callable[[random.Random], bytes]) -> Callable[[random.Random, Path], None]:
    return lambda rng, path: path.write_bytes(make(rng))


_TOPICS = '[vehicles.logs.topics]\n"/nmea" = "gps:nmea"\n"/gps/fix" = "gps"\n"/imu" = "ins"\n"/odom" = "ins"\n'
TARGETS: dict[str, Target] = {
    "record/ros1": Target("a.bag", 'format = "rosbag"\norigin = [45.7, 126.6]\n' + _TOPICS, _bytes(ros1_case)),
    "record/ros2-db3": Target("a.db3", 'format = "rosbag"\n' + _TOPICS, db3_case),
    "record/alog": Target("a.alog", 'format = "alog"\norigin = [45.7, 126.6]\n', _bytes(alog_case)),
    "record/tlog": Target("a.tlog", 'format = "mavlink"\n', _bytes(tlog_case)),
    "record/bin": Target("a.BIN", 'format = "mavlink"\ntime_base = "boot"\nstart = "2024-05-01T10:00:00Z"\n',
                         _bytes(bin_case)),
}
IMPORTERS = tuple(TARGETS)


def manifest_text(target: Target) -> str:
    """The manifest of one log of `target`, relative to its folder."""
    return ('[trial]\nname = "fuzz"\ndate = "2016-10-12"\n[[vehicles]]\nname = "a"\nrole = "leader"\n'
            f'[[vehicles.logs]]\npath = "{target.filename}"\n{target.log}')


def importer_cases(name: str, n: int, base_seed: int = 0, folder: Path | None = None) -> dict:
    """Run n damaged files of one importer through `record`; counts of outcomes, failures and the peak RSS.

    clean: archived without a skip; skips: archived with counted skips; refused: one line of
    ManifestError, FormatError or UserError; exceptions: anything else, a message of more than one line,
    or a file left in the folder; hangs: cases over HANG_S (bounded by an alarm). Cases are reproducible
    from (name, base_seed, case number).
    """
    target = TARGETS[name]
    own = folder is None
    folder = folder or Path(tempfile.mkdtemp(prefix="fuzz-record-",
                                             dir="/dev/shm" if os.path.isdir("/dev/shm") else None))
    manifest, case_path, output = folder / "trial.toml", folder / target.filename, folder / "out.mcap"
    manifest.write_text(manifest_text(target))
    expected = {manifest.name, case_path.name, output.name}
    counts: dict = {"cases": 0, "clean": 0, "skips": 0, "refused": 0, "exceptions": 0, "hangs": 0}
    examples: list[str] = []
    slowest = 0.0

    def fail(kind: str, case: int, text: str) -> None:
        counts[kind] += 1
        if len(examples) < 3:
            keep = folder / f"{name.replace('/', '-')}-{base_seed}-{case}{case_path.suffix}"
            shutil.copyfile(case_path, keep)
            expected.add(keep.name)
            examples.append(f"case {case} ({keep}): {text}")

    for case in range(n):
        rng = random.Random(f"{name}/{base_seed}/{case}")
        target.build(rng, case_path)
        counts["cases"] += 1
        started, cpu = time.monotonic(), cpu_seconds()
        try:
            with bounded(HANG_S * 2):
                summary = record(load_manifest(manifest), output, workers=1)
            counts["skips" if any(f.skipped for f in summary.files) else "clean"] += 1
        except Hang:
            fail("hangs", case, f"no end after {time.monotonic() - started:.1f} s")
            continue
        except (ManifestError, FormatError, UserError) as exc:
            if "\n" in str(exc) or not str(exc).strip():
                fail("exceptions", case, f"{type(exc).__name__} not one line: {str(exc)[:300]!r}")
            else:
                counts["refused"] += 1
        except Exception:  # noqa: BLE001 - the count this fuzz exists for
            fail("exceptions", case, traceback.format_exc(limit=-3).strip())
        seconds = cpu_seconds() - cpu
        slowest = max(slowest, seconds)
        if seconds > HANG_S:
            fail("hangs", case, f"took {seconds:.1f} s of CPU ({time.monotonic() - started:.1f} s wall)")
        left = set(os.listdir(folder)) - expected
        if left:
            fail("exceptions", case, f"left behind: {sorted(left)}")
            for extra in left:
                with contextlib.suppress(OSError):
                    (folder / extra).unlink()
    if own and not examples:
        shutil.rmtree(folder, ignore_errors=True)
    counts["slowest_s"] = round(slowest, 2)
    counts["peak_mb"] = round(peak_rss_mb())
    counts["examples"] = examples
    return counts
