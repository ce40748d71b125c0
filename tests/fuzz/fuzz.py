"""Fuzzing every decoder entry point and every kind of archive damage; prints counts, exits 1 on an exception.

    python tests/fuzz/fuzz.py --cases 100000          # make fuzz: every converter, every damage kind
    python tests/fuzz/fuzz.py --cases 2000 --only gps/nmea truncation

Decoder cases start from a real log of the format (the sample trial's, or a
documented example), cut to a random window, then damaged a few ways: byte
flips, insertions, deletions, repeats, and number fields replaced by hostile
number text (`nan`, `1e400`, 400 digits...) with the line's NMEA checksum
made right again, so hostile values reach the field parsers. The payload
targets (/rosbag+payloads, /mavlink+payloads) keep the container valid and
damage the messages inside it, where a damaged bag or tlog would mostly be
refused whole at the open; their cases are damaged payloads. A converter
may yield Rejects or refuse the whole file with a FormatError; anything
else it raises is a failure. Archive cases damage a small archive (several
chunks, metadata, attachments): cuts, byte flips, and crafted records
(absurd lengths, chunk sizes, compressions, frames); the reader must never
raise. The importer entries (record/..., tests/fuzz/importers.py) record whole
damaged files through `record`; the live entries (capture/..., tests/fuzz/live.py)
send hostile streams through the capture decoder and the real sources. Every
entry counts its cases, exceptions, hangs (cases over 5 s of CPU, or not
ending in 10 s: wall time on a shared machine measures the neighbours) and its peak RSS
(each entry runs in a fresh process). Cases are reproducible from (entry,
seed, case number).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import multiprocessing
import os
import random
import re
import shutil
import struct
import sys
import tempfile
import time
import traceback
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from datetime import date
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import zstandard

from formats import schemas as S
from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import ArchiveWriter
from formats.records import FormatError, Reject
from formats.regex_lines import EXAMPLE_PATTERN, EXAMPLE_SCALE
from formats.waterlinked import crc8
from recorders.base import LogContext
from recorders.manifest import load_manifest
from recorders.registry import converters
from tests.fuzz.importers import IMPORTERS, importer_cases, peak_rss_mb
from tests.fuzz.importers import tlog_packets as tlog_packets
from tests.fuzz.live import COST, LIVE, live_cases
from tests.test_ecosystem_inputs import (
    ALOG,
    NMEA_SENTENCE_MSG,
    _bag_messages,
    _typestores,
    write_ros1,
    write_tlog,
)

SAMPLE = ROOT / "samples" / "lake_trial"
BOOK = {1: "leader1", 2: "leader2", 3: "follower", 11: "buoy1", 12: "buoy2", 13: "buoy3", 14: "buoy4"}
HOSTILE_NUMBERS = ("nan", "NaN", "inf", "-inf", "Infinity", "1e400", "-1e400", "9" * 400, "-" + "9" * 400,
                   "1e-400", "0", "-0", "1e30", "-1e30", "+", "-", ".", "1e", "0x1F", "1_0", "٣", "")
WINDOW = 1500  # bytes of a seed per case: whole records, fast cases

# ---- seeds ------------------------------------------------------------------------------------------------
PD6 = (":SA, -2.31, +1.92, 75.20\r\n:TS,04081111563644,35.0,+21.0, 0.0,1524.0, 0\r\n"
       ":RA, 0.00, 71.31, 71.32, 71.32, 71.31\r\n:WI,-32768,-32768,-32768,-32768,V\r\n"
       ":BI, +24, -6, -20, -4,A\r\n:BS, -13, +21, -20,A\r\n:BE, +17, +18, -20,A\r\n"
       ":BD, -0.02, -0.03, +0.02, 7.13, 0.21\r\n")
NORTEK = ("$PNORBT,3,112813,072228.2345,0.1234,0.1234,1.11111,122.2,36.66,2.22222,F7*7A\r\n"
          "$PNORBT,BEAM=3,DATE=112813,TIME=072228.2345,DT1=0.1234,DT2=0.1234,BV=1.11111,FM=122.2,DIST=36.66,"
          "WV=2.22222,STAT=F7*75\r\n"
          "$PNORBT0,1,040721,131335.3341,23.961,-48.122,-32.76800,10.00000,0.00,0x00000000*48\r\n"
          "$PNORBT4,1.234,-1.234,1.234,23.4,12.34567,12.3*3D\r\n"
          "$PNORBT7,1452244916.7508,1.234,-1.234,0.1234,0.1234,0.1234,12.34,23.45,23.45,23.45,23.45*39\r\n")
WATERLINKED = ("wrz,0.120,-0.400,2.000,y,1.30,1.855,1e-07;0;1.4;0;1.2;0;0.2;0;1e+09,7,14,123.00,1*50\r\n"
               "wru,0,0.070,1.10,-40,-95*9c\r\nwru,1,-0.500,1.25,-62,-104*f0\r\n"
               "wrp,49056.809,0.41,0.15,1.23,0.4,53.9,13.0,19.3,0*de\r\n"
               '{"time":49056.809,"vx":0.12,"vy":-0.4,"vz":2.0,"fom":1.855,"altitude":1.3,"velocity_valid":true,'
               '"status":0,"time_of_validity":1476259200000000,"time_of_transmission":1476259200100000,'
               '"transducers":[{"id":0,"velocity":0.07,"distance":1.1,"rssi":-40,"nsd":-95,"beam_valid":true}]}\r\n')
PASHR = "$PASHR,085335.000,224.19,T,-01.26,+00.83,+00.00,0.101,0.113,0.267,1,0*06\r\n"
REGEX = "12:00:05.200 Range 1 to 2 : 500.1 m (Round-trip 666.8 ms)\r\n"


def _pd4(pd5: bool = False) -> bytes:
    n = 88 if pd5 else 45
    b = bytearray(n)
    b[0], b[1] = 0x7D, 1 if pd5 else 0
    b[2:4] = struct.pack("<H", n)
    b[4] = 0b11_1_0_0_011
    b[5:13] = struct.pack("<4h", 1234, -567, 8, -32768)
    b[13:21] = struct.pack("<4H", 2500, 2510, 0, 2490)
    b[35:39] = bytes([13, 45, 7, 89])
    b[41:43] = struct.pack("<H", 1490)
    b[43:45] = struct.pack("<h", -150)
    return bytes(b) + struct.pack("<H", sum(b) & 0xFFFF)


def _csv(cls: type) -> tuple[bytes, dict]:
    numbers = [f.name for f in cls.DESCRIPTOR.fields if f.type in (1, 2)][:2]  # double, float
    head = ",".join(["t", *numbers])
    rows = "".join(f"{1476259200 + k}.5,{1.5 + k},{-2.25 * k}\r\n" for k in range(20))
    return (head + "\r\n" + rows).encode(), {"columns": {"time": "t", **{n: n for n in numbers}}}


def seeds() -> dict[str, tuple[bytes, dict]]:
    """(sensor/format) -> (seed bytes, log options) for every converter."""
    out: dict[str, tuple[bytes, dict]] = {}
    manifest = load_manifest(SAMPLE / "trial.toml")
    for log in manifest.logs():
        key = f"{log.sensor}/{log.format}"
        if key not in out:
            out[key] = ((SAMPLE / log.path).read_bytes()[:200_000], dict(log.options))
    gps = (SAMPLE / "leader1" / "gps.log").read_bytes()[:50_000]
    out.setdefault("ins/nmea", (gps + b"$HEHDT,90.5,T*26\r\n$PHTRO,1.20,M,0.50,T*4C\r\n" * 5, {}))
    out.setdefault("dvl/pd6", (PD6.encode() * 4, {}))
    out.setdefault("dvl/nortek", (NORTEK.encode() * 4, {}))
    out.setdefault("dvl/waterlinked", (WATERLINKED.encode() * 4, {}))
    out.setdefault("dvl/pd4", (_pd4() * 8, {}))
    out.setdefault("dvl/pd5", (_pd4(True) * 8, {}))
    out.setdefault("ins/pashr", (PASHR.encode() * 8, {}))
    regex = {"pattern": EXAMPLE_PATTERN, "time_format": "tod", "travel_time_scale": EXAMPLE_SCALE}
    out.setdefault("modem/regex", (REGEX.encode() * 8, regex))
    out.setdefault("usbl/regex", (REGEX.replace("to 2", "to 2 target 3").encode() * 8,
                                  {**regex, "pattern": EXAMPLE_PATTERN.replace("(?P<source>", "(?P<target>")}))
    for family, cls in (("gps", S.LocationFix), ("ins", S.InsState), ("dvl", S.DvlVelocity),
                        ("modem", S.AcousticRange), ("usbl", S.UsblObservation)):
        out.setdefault(f"{family}/csv", _csv(cls))
    out.setdefault("modem/evologics", out["usbl/evologics"])
    out.setdefault("gps/novatel", out.get("ins/novatel", (gps, {})))
    out.setdefault("ins/novatel", out["gps/novatel"])
    # the container formats (no sensor key), built as the ecosystem tests build them
    with tempfile.TemporaryDirectory(prefix="fuzz-seeds-") as tmp:
        write_ros1(Path(tmp) / "trial.bag")
        write_tlog(Path(tmp) / "trial.tlog")
        out.setdefault("/rosbag", ((Path(tmp) / "trial.bag").read_bytes(), {}))
        out.setdefault("/mavlink", ((Path(tmp) / "trial.tlog").read_bytes(), {}))
    out.setdefault("/alog", (ALOG.encode(), {"origin": [45.7, 126.6]}))
    return out


# ---- decoder mutations ------------------------------------------------------------------------------------
_NUMBER = re.compile(rb"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")
_NMEA = re.compile(rb"\$([^$*\r\n]*)\*([0-9A-Fa-f]{2})")
_WL = re.compile(rb"^(w[a-z][a-z0-9]?,[^*\r\n]*)\*([0-9a-f]{2})", re.M)


def _fix_checksums(data: bytes) -> bytes:
    def nmea(m: re.Match) -> bytes:
        x = 0
        for c in m.group(1):
            x ^= c
        return b"$" + m.group(1) + b"*" + b"%02X" % x
    data = _NMEA.sub(nmea, data)
    return _WL.sub(lambda m: m.group(1) + b"*" + b"%02x" % crc8(m.group(1)), data)


def mutate(seed: bytes, rng: random.Random) -> bytes:
    """A damaged window of a seed log (see the module docstring)."""
    start = rng.randrange(max(1, len(seed) - 64))
    data = bytearray(seed[start:start + rng.randrange(1, WINDOW)])
    for _ in range(rng.randrange(1, 5)):
        op = rng.random()
        n = len(data)
        if op < 0.40:
            matches = list(_NUMBER.finditer(bytes(data)))
            if matches:
                m = rng.choice(matches)
                data[m.start():m.end()] = rng.choice(HOSTILE_NUMBERS).encode()
        elif op < 0.60 and n:
            data[rng.randrange(n)] ^= 1 << rng.randrange(8)
        elif op < 0.70:
            at = rng.randrange(n + 1)
            data[at:at] = bytes(rng.getrandbits(8) for _ in range(rng.randrange(1, 16)))
        elif op < 0.80 and n:
            at = rng.randrange(n)
            del data[at:at + rng.randrange(1, 64)]
        elif op < 0.90 and n:
            at = rng.randrange(n)
            data[at:at] = data[at:at + rng.randrange(1, 200)]
        elif n:
            data[rng.randrange(n)] = rng.choice(b",*$\r\n\x00\xff;=")
    out = bytes(data)
    return _fix_checksums(out) if rng.random() < 0.7 else out


def decoder_cases(key: str, seed: bytes, options: dict, n: int, base_seed: int = 0) -> dict[str, int]:
    """Run n mutated cases through one converter; counts of outputs, rejects, refusals, exceptions."""
    return run_cases(key, lambda rng: mutate(seed, rng), options, n, base_seed)


def run_cases(key: str, make: Callable[[random.Random], bytes], options: dict, n: int,
              base_seed: int = 0) -> dict[str, int]:
    """Run n cases `make(rng)` through the converter of `key` (sensor/format, or /container+target)."""
    sensor, fmt = key.split("/")
    fmt = fmt.split("+")[0]
    conv = converters()[(sensor, fmt)]
    ctx = LogContext(vehicle="follower", role="follower", path=f"fuzz/{fmt}", trial_date=date(2016, 10, 12),
                     options=options, address_book=BOOK, sound_speed_mps=1450.0)
    # container formats (no sensor key) are opened by their library from a file: each case is written to one
    suffix = {"rosbag": ".bag", "mavlink": ".tlog"}.get(fmt, f".{fmt}")
    spool = Path(tempfile.mkdtemp(prefix="fuzz-container-")) / f"case{suffix}" if not sensor else None
    if spool is not None:
        ctx = dataclasses.replace(ctx, files=(spool,))
    counts = {"cases": 0, "outputs": 0, "rejects": 0, "refused": 0, "exceptions": 0}
    examples: list[str] = []
    for case in range(n):
        rng = random.Random(f"{key}/{base_seed}/{case}")
        data = make(rng)
        counts["cases"] += 1
        if spool is not None:
            spool.write_bytes(data)
        try:
            for item in conv(data, ctx):
                if isinstance(item, Reject):
                    counts["rejects"] += 1
                else:
                    counts["outputs"] += 1
        except FormatError:
            counts["refused"] += 1
        except Exception:  # noqa: BLE001 - the count this fuzz exists for
            counts["exceptions"] += 1
            if len(examples) < 3:
                examples.append(f"case {case}: {traceback.format_exc(limit=-2).strip()}\n  input {data[:300]!r}")
    if spool is not None:
        shutil.rmtree(spool.parent, ignore_errors=True)
    counts["examples"] = examples  # type: ignore[assignment]
    return counts


# ---- payload targets: a valid container whose message payloads are damaged ------------------------------------
# A mutated container file is mostly refused whole when opened (its index, its connection records), so the
# message decoding behind it is barely reached; these targets keep the container valid and damage the payloads:
# words overwritten with NaN, infinities, huge floats and absurd array or string lengths, bits flipped, bytes cut
# or added.
_HOSTILE_WORDS = (struct.pack("<d", math.nan), struct.pack("<d", math.inf), struct.pack("<d", -math.inf),
                  struct.pack("<d", 1e308), struct.pack("<d", -1e308), struct.pack("<f", math.nan) * 2,
                  struct.pack("<I", 0xFFFFFFFF), struct.pack("<I", 1 << 30), struct.pack("<i", -1),
                  struct.pack("<q", 2**63 - 1), struct.pack("<Q", 2**64 - 1))


def mutate_payload(data: bytes, rng: random.Random, limit: int = 1 << 16) -> bytes:
    """One message payload damaged a few ways (see above), at most `limit` bytes long."""
    out = bytearray(data)
    for _ in range(rng.randrange(1, 4)):
        op = rng.random()
        n = len(out)
        if op < 0.5 and n >= 4:
            word = rng.choice(_HOSTILE_WORDS)
            at = rng.randrange(0, max(1, n - len(word) + 1))
            at -= at % 4 if rng.random() < 0.7 else 0  # mostly where a field would be
            out[at:at + len(word)] = word
        elif op < 0.7 and n:
            out[rng.randrange(n)] ^= 1 << rng.randrange(8)
        elif op < 0.85:
            del out[rng.randrange(n + 1):]
        else:
            at = rng.randrange(n + 1)
            out[at:at] = rng.randbytes(rng.randrange(1, 32))
    return bytes(out[:limit])


def ros1_items() -> tuple[object, list[tuple[str, str, int, bytes]]]:
    """The typestore and (topic, msgtype, bag time, serialized message) of the ecosystem tests' ROS 1 bag."""
    from rosbags.typesys import get_types_from_msg  # the optional rosbags, as recorders.rosbag imports it
    ts, _ = _typestores()
    ts.register(get_types_from_msg(NMEA_SENTENCE_MSG, "nmea_msgs/msg/Sentence"))
    items = sorted(_bag_messages(ts), key=lambda x: x[2])
    return ts, [(topic, msgtype, t, bytes(ts.serialize_ros1(msg, msgtype))) for topic, msgtype, t, msg in items]


def ros1_payload_case(ts: object, items: list[tuple[str, str, int, bytes]], folder: Path, rng: random.Random,
                      damaged: int) -> bytes:
    """A valid ROS 1 bag of `items` over and over (100 s apart) with a third of the payloads damaged, `damaged`
    in all: opening a bag costs rosbags far more than its messages, so one bag carries many cases."""
    from rosbags.rosbag1 import Writer
    path = folder / "payloads.bag"
    path.unlink(missing_ok=True)
    done = rep = 0
    with Writer(path) as w:
        conns: dict[str, object] = {}
        while done < damaged:
            for topic, msgtype, t, data in items:
                if topic not in conns:
                    conns[topic] = w.add_connection(topic, msgtype, typestore=ts)
                if done < damaged and rng.random() < 1 / 3:
                    data, done = mutate_payload(data, rng), done + 1
                w.write(conns[topic], t + rep * 100 * 10**9, data)
            rep += 1
    return path.read_bytes()


def mavlink_payload_case(packets: list[tuple[int, bytes]], rng: random.Random, damaged: int) -> bytes:
    """The tlog's packets over and over (100 s apart) with a third of the payloads damaged, `damaged` in all,
    each damaged packet's CRC made right (its signature dropped)."""
    from pymavlink.dialects.v20 import ardupilotmega as mav  # the optional pymavlink
    from pymavlink.generator.mavcrc import x25crc
    out = bytearray()
    done = rep = 0
    while done < damaged:
        for us, pkt in packets:
            if done < damaged and rng.random() < 1 / 3:
                msgid = int.from_bytes(pkt[7:10], "little")
                payload = mutate_payload(pkt[10:10 + pkt[1]], rng, 255)
                head = bytes([pkt[0], len(payload), pkt[2] & 0xFE]) + pkt[3:10]
                crc = x25crc(head[1:] + payload)
                crc.accumulate(bytes([mav.mavlink_map[msgid].crc_extra]) if msgid in mav.mavlink_map else b"\0")
                pkt, done = head + payload + struct.pack("<H", crc.crc), done + 1
            out += struct.pack(">Q", us + rep * 100_000_000) + pkt
        rep += 1
    return bytes(out)


PAYLOADS_PER_FILE = {"/rosbag+payloads": 250, "/mavlink+payloads": 50}


def payload_cases(name: str, n: int, base_seed: int = 0) -> dict[str, int]:
    """n damaged payloads of one payload target (PAYLOADS_PER_FILE to a file) through its container's converter.

    The counts are those of `run_cases`, with `cases` the payloads damaged and `files` the files they came in.
    """
    per = PAYLOADS_PER_FILE[name]
    files = -(-n // per)
    folder = Path(tempfile.mkdtemp(prefix="fuzz-payloads-"))
    try:
        if name == "/rosbag+payloads":
            ts, items = ros1_items()
            counts = run_cases(name, lambda rng: ros1_payload_case(ts, items, folder, rng, per), {}, files, base_seed)
        else:
            packets = tlog_packets()
            counts = run_cases(name, lambda rng: mavlink_payload_case(packets, rng, per), {}, files, base_seed)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    counts["files"], counts["cases"] = counts["cases"], files * per
    return counts


PAYLOAD_TARGETS = ("/mavlink+payloads", "/rosbag+payloads")


# ---- archive damage ---------------------------------------------------------------------------------------
T0 = 1_476_259_200 * 10**9


def base_archive(path: Path) -> bytes:
    """A small archive: two topics over several chunks, two metadata records, two attachments."""
    with ArchiveWriter(path, chunk_size=1000) as w:
        for k in range(60):
            w.write("/a/gps", S.location_fix(T0 + k * 10**8, "a", 45.0 + k * 1e-5, 126.0, 1.0), T0 + k * 10**8)
            if k % 3 == 0:
                w.write("/a/gps/status", S.GnssStatus(satellites=k % 12, hdop=0.9), T0 + k * 10**8)
        w.add_metadata("trial", {"name": "fuzz", "vehicles": [{"name": "a", "role": "follower"}]})
        w.add_metadata("recording", {"files": [{"path": "a/gps.log", "parsed": 1}]})
        w.add_attachment("a/gps.log", b"$GPGGA\r\n" * 40)
        w.add_attachment("a/ins.log", b"$PIXSE\r\n" * 20)
    return path.read_bytes()


def _crafted(data: bytes, rng: random.Random) -> bytes:
    """Insert or overwrite one crafted record: absurd lengths, chunk sizes, compressions, frames, garbage."""
    kind = rng.randrange(6)
    if kind == 0:    # a record of any opcode declaring an absurd length
        rec = struct.pack("<BQ", rng.randrange(256), rng.choice([2**63, 2**64 - 1, 1 << 34, len(data) * 2]))
    elif kind == 1:  # a chunk declaring a huge or wrong uncompressed size
        body = zstandard.ZstdCompressor(write_content_size=rng.random() < 0.5).compress(bytes(rng.randrange(1, 5000)))
        comp = rng.choice(["zstd", "lz4", "", "gzip", "\xff"]).encode("latin-1")
        head = struct.pack("<QQQI", T0, T0 + 5, rng.choice([0, 1, 1 << 34, 16 << 30, len(body)]), 0)
        payload = head + struct.pack("<I", len(comp)) + comp + struct.pack("<Q", len(body)) + body
        rec = struct.pack("<BQ", 0x06, len(payload)) + payload
    elif kind == 2:  # metadata or attachment of garbage fields
        op = rng.choice([0x0C, 0x09, 0x03, 0x04])
        payload = bytes(rng.getrandbits(8) for _ in range(rng.randrange(0, 80)))
        rec = struct.pack("<BQ", op, len(payload)) + payload
    elif kind == 3:  # a string length field past the record
        payload = struct.pack("<I", rng.choice([2**32 - 1, 1 << 30, 100])) + b"abc"
        rec = struct.pack("<BQ", rng.choice([0x0C, 0x09, 0x03, 0x04, 0x08, 0x0B]), len(payload)) + payload
    elif kind == 4:  # a footer pointing anywhere
        rec = struct.pack("<BQQQI", 0x02, 20, rng.randrange(2**64), rng.randrange(2**64), rng.randrange(2**32))
        return data[:-28] + rec + data[-8:]
    else:            # overwrite 8 bytes at a random place with a large number (a length or an offset)
        at = rng.randrange(8, len(data) - 8)
        return data[:at] + struct.pack("<Q", rng.choice([2**63, 1 << 40, len(data), 0])) + data[at + 8:]
    at = rng.randrange(8, len(data))
    return data[:at] + rec + data[at:]


def damage(kind: str, data: bytes, rng: random.Random) -> bytes:
    """One damaged copy of `data` of the given kind."""
    if kind == "truncation":
        return data[:rng.randrange(8, len(data))]
    if kind == "flips":
        out = bytearray(data)
        for _ in range(rng.randrange(1, 9)):
            at = rng.randrange(8, len(out))
            out[at] ^= 1 << rng.randrange(8) if rng.random() < 0.7 else rng.randrange(1, 256)
        return bytes(out)
    return _crafted(data, rng)


DAMAGE_KINDS = ("truncation", "flips", "crafted")


def read_all(path: Path) -> int:
    """Everything a command reads: summary, messages, metadata, attachments; the count of messages."""
    with ArchiveReader(path) as r:
        r.summary()
        n = sum(1 for _ in r.messages())
        r.metadata_json("trial"), r.metadata_json("recording")
        for _ in r.attachments():
            pass
        r.warning()
    return n


def archive_cases(kind: str, n: int, base_seed: int = 0, folder: Path | None = None) -> dict[str, int]:
    """Run n damaged copies of the base archive through the reader; counts of reads, damage, exceptions."""
    folder = folder or Path(tempfile.mkdtemp(prefix="fuzz-", dir="/dev/shm" if os.path.isdir("/dev/shm") else None))
    data = base_archive(folder / "base.mcap")
    path = folder / "case.mcap"
    counts = {"cases": 0, "clean": 0, "damaged": 0, "refused": 0, "exceptions": 0}
    examples: list[str] = []
    for case in range(n):
        rng = random.Random(f"{kind}/{base_seed}/{case}")
        blob = damage(kind, data, rng)
        path.write_bytes(blob)
        counts["cases"] += 1
        try:
            with ArchiveReader(path) as r:
                r.summary()
                for _ in r.messages():
                    pass
                r.metadata_json("trial"), r.metadata_json("recording")
                for _ in r.attachments():
                    pass
                counts["damaged" if r.warning() else "clean"] += 1
        except FormatError:
            counts["refused"] += 1  # not MCAP at all: the one error the reader raises
        except Exception:  # noqa: BLE001 - the count this fuzz exists for
            counts["exceptions"] += 1
            if len(examples) < 3:
                keep = folder / f"{kind}-{case}.mcap"
                keep.write_bytes(blob)
                examples.append(f"case {case} ({keep}): {traceback.format_exc(limit=-2).strip()}")
    counts["examples"] = examples  # type: ignore[assignment]
    return counts


def run_job(name: str, cases: int, seed: int) -> tuple[str, dict, float]:
    """One entry point (sensor/format) or damage kind (archive/KIND): (name, counts, seconds)."""
    t = time.monotonic()
    if name in IMPORTERS:
        return name, importer_cases(name, cases, seed), time.monotonic() - t
    if name in LIVE:
        return name, live_cases(name, max(1, cases // COST[name]), seed), time.monotonic() - t
    if name.startswith("archive/"):
        counts = archive_cases(name.split("/", 1)[1], cases, seed)
    elif name in PAYLOAD_TARGETS:
        counts = payload_cases(name, cases, seed)
    else:
        data, options = seeds()[name]
        counts = decoder_cases(name, data, options, cases, seed)
    counts["peak_mb"] = round(peak_rss_mb())
    return name, counts, time.monotonic() - t


def main(argv: list[str] | None = None) -> int:
    """Run the cases (one process per core) and print one line of counts per entry point and damage kind."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=100_000, help="cases per entry point and kind")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="processes (default: one per core)")
    parser.add_argument("only", nargs="*", help="entries (sensor/format) or damage kinds; default all")
    args = parser.parse_args(argv)
    names = [k for k in sorted(seeds()) if not args.only or k in args.only]
    names += [k for k in PAYLOAD_TARGETS if not args.only or k in args.only]
    names += [f"archive/{k}" for k in DAMAGE_KINDS if not args.only or k in args.only]
    names += [k for k in (*IMPORTERS, *LIVE) if not args.only or k in args.only]
    print(f"{'entry':<22} " + "  ".join(f"{c:>11}" for c in ("cases", "outputs/ok", "rejects/skip", "refused",
                                                            "exceptions", "hangs", "peak MB", "seconds")), flush=True)
    failures = hangs = total = 0
    # one fresh process per entry: its peak RSS is its own
    pool = ProcessPoolExecutor(max_workers=max(1, args.jobs), mp_context=multiprocessing.get_context("spawn"),
                               max_tasks_per_child=1)
    with pool:
        for name, c, seconds in pool.map(run_job, names, [args.cases] * len(names), [args.seed] * len(names)):
            examples = c.pop("examples")
            cols = [c["cases"], c.get("outputs", c.get("clean", c.get("ok", 0))),
                    c.get("rejects", c.get("damaged", c.get("skips", 0))), c.get("refused", 0), c["exceptions"],
                    c.get("hangs", 0), c.get("peak_mb", 0)]
            print(f"{name:<22} " + "  ".join(f"{v:>11}" for v in cols) + f"  {seconds:>11.1f}", flush=True)
            for e in examples:
                print("    " + e.replace("\n", "\n    "))
            failures += c["exceptions"]
            hangs += c.get("hangs", 0)
            total += c["cases"]
    print(f"{failures} exceptions and {hangs} hangs over {total} cases of {len(names)} entry points, damage kinds, "
          f"importers and live sources")
    return 1 if failures or hangs else 0


def iter_keys() -> Iterator[str]:
    """Every decoder entry point's name (sensor/format)."""
    yield from sorted(seeds())


if __name__ == "__main__":
    sys.exit(main())
