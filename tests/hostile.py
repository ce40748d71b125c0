"""Hostile archives built in the test: zstd bombs, crafted chunk sizes, garbage messages, flipped bytes.

Shared by tests/test_hostile_archives.py and the fuzz run (tests/fuzz/fuzz_archives.py).
"""

from __future__ import annotations

import functools
import os
import random
import struct
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import zstandard

from formats.mcap_chunks import ordered_messages
from formats.mcap_reader import ArchiveReader
from formats.mcap_records import read_summary
from formats.mcap_writer import ArchiveWriter
from formats.schemas import MESSAGE_CLASSES

GIB = 1 << 30
ROOT = Path(__file__).resolve().parent.parent
# the child reports its own peak (VmHWM): ru_maxrss of a child keeps the forking parent's high-water mark
_CHILD = """
import runpy, sys
try:
    runpy.run_module("replay.cli", run_name="__main__", alter_sys=True)
finally:
    hwm = next(line for line in open("/proc/self/status") if line.startswith("VmHWM"))
    sys.stderr.write("\\n#VmHWM " + hwm.split()[1] + "\\n")
"""


def run_child(*argv: str) -> tuple[int, str, int]:
    """`auvreplay ARGV` in a child process: (exit code, stderr, its peak RSS in KB)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", _CHILD, *argv], env=env, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True, cwd=ROOT, timeout=600)
    err, _, peak = done.stderr.rpartition("#VmHWM ")
    return done.returncode, err.strip() + "\n", int(peak)


@functools.lru_cache(maxsize=4)
def zstd_bomb(size: int = 4 * GIB, content_size: bool = False) -> bytes:
    """One zstd frame of `size` zero bytes (~134 KB for 4 GiB), with or without its size in the header."""
    c = zstandard.ZstdCompressor(level=1, write_content_size=content_size).compressobj(
        size=size if content_size else -1)
    zero = bytes(1 << 24)
    parts = [c.compress(zero) for _ in range(size // len(zero))]
    parts.append(c.flush())
    return b"".join(parts)


class _FirstChunk:
    """A compressor whose first chunk is `payload` (the chunk still declares its true size and CRC)."""

    def __init__(self, payload: bytes):
        self.payload: bytes | None = payload
        self.real = zstandard.ZstdCompressor(level=3)

    def compress(self, data: bytes) -> bytes:
        if self.payload is not None:
            out, self.payload = self.payload, None
            return out
        return self.real.compress(data)


def rewrite(src: Path, dst: Path, message: Callable[[str, bytes, random.Random], bytes | None] | None = None,
            first_chunk: bytes | None = None, seed: int = 0, chunk_size: int = 1 << 20) -> Path:
    """A copy of an archive (metadata, attachments) with each message's bytes through `message`.

    `message(topic, data, rng)` returns new bytes, or None to drop the message;
    `first_chunk` replaces the compressed bytes of the first chunk.
    """
    rng = random.Random(seed)
    with ArchiveReader(src) as r:
        summary, _ = read_summary(r._file, r._size, True)
        assert summary is not None
        topics = {ch.topic: MESSAGE_CLASSES[summary.schemas[ch.schema_id].name] for ch in summary.channels.values()}
        with ArchiveWriter(dst, chunk_size=chunk_size) as w:
            if first_chunk is not None:
                w._zstd = _FirstChunk(first_chunk)
            for t, cls in topics.items():
                w.channel(t, cls)
            names = {cid: ch.topic for cid, ch in summary.channels.items()}
            for log_time, publish_time, cid, raw in ordered_messages(r._file, summary.chunk_indexes, None, True):
                data = raw if message is None else message(names[cid], raw, rng)
                if data is not None:
                    w.write_serialized(names[cid], data, log_time, publish_time)
            for name in dict.fromkeys(r.summary().metadata_names):  # trial, recording; run of a results archive
                meta = r.metadata(name)
                if meta is not None:
                    w.add_metadata(name, meta)
            for a in r.attachments():
                w.add_attachment(a.name, a.data, a.media_type, a.log_time, a.create_time)
    return dst


def chunk_offsets(path: Path) -> list[int]:
    """File offsets of the archive's chunk records, from its summary."""
    with ArchiveReader(path) as r:
        return sorted(ci.chunk_start_offset for ci in r._index.chunk_indexes)


def set_declared_size(path: Path, offset: int, size: int) -> None:
    """Overwrite the uncompressed-size field of the chunk record at `offset` (it has no CRC)."""
    data = bytearray(path.read_bytes())
    struct.pack_into("<Q", data, offset + 9 + 16, size)
    path.write_bytes(bytes(data))


def record_offsets(path: Path, opcode: int) -> list[tuple[int, int]]:
    """(offset, length) of every top-level record of an opcode, by walking the file's framing."""
    data = path.read_bytes()
    pos, out = 8, []
    while pos + 9 <= len(data) - 8:
        op, n = struct.unpack_from("<BQ", data, pos)
        if op == opcode:
            out.append((pos, 9 + n))
        pos += 9 + n
    return out


def damage_lines(data: bytes, seed: int) -> bytes:
    """`data` with lines cut, checksums broken, garbage, host-prefixed and repeated lines thrown in."""
    rng = random.Random(seed)
    lines = data.splitlines(keepends=True)
    for _ in range(max(len(lines) // 40, 5)):
        i = rng.randrange(len(lines))
        kind = rng.randrange(5)
        if kind == 0:
            lines[i] = lines[i][: rng.randrange(len(lines[i]))] + b"\n"
        elif kind == 1:
            lines[i] = lines[i].replace(b"*", b"*0", 1)
        elif kind == 2:
            lines.insert(i, rng.randbytes(rng.randrange(1, 60)).replace(b"\n", b"") + b"\r\n")
        elif kind == 3:
            lines[i] = b"2016-10-12T08:00:%02d.250Z " % rng.randrange(60) + lines[i]
        else:
            lines.insert(i, lines[i])
    return b"".join(lines)


# ---------------------------------------------------------------- ROS 1 bags, written field by field

STRING_MD5 = "992ce8a1687cec8c8bd883ec73ca41d1"   # std_msgs/String


def _ros_header(**fields: bytes) -> bytes:
    body = b"".join(struct.pack("<I", len(k) + 1 + len(v)) + k.encode() + b"=" + v for k, v in fields.items())
    return struct.pack("<I", len(body)) + body


def _ros_record(data: bytes, **fields: bytes) -> bytes:
    return _ros_header(**fields) + struct.pack("<I", len(data)) + data


def _ros_time(t_ns: int) -> bytes:
    return struct.pack("<II", *divmod(t_ns, 10**9))


def ros_string(text: bytes) -> bytes:
    """A std_msgs/String message, ROS 1 serialized."""
    return struct.pack("<I", len(text)) + text


def ros1_bag(chunks: list[list[tuple[int, bytes]]], topic: str = "/nmea", compression: str = "bz2",
             chunk_data: dict[int, bytes] | None = None, declared: dict[int, int] | None = None) -> bytes:
    """A ROS 1 (v2.0) bag of std_msgs/String messages on one topic: `chunks` lists each chunk's (time ns, message).

    `chunk_data` replaces a chunk's compressed bytes (a bomb), `declared` the uncompressed size its header
    gives; the index (message times and offsets) stays that of the real messages.
    """
    import bz2 as _bz2

    import lz4.frame

    conn = struct.pack("<I", 0)
    connection = _ros_record(
        _ros_header(topic=topic.encode(), type=b"std_msgs/String", md5sum=STRING_MD5.encode(),
                    message_definition=b"string data\n")[4:],
        op=b"\x07", conn=conn, topic=topic.encode())
    out = bytearray(b"#ROSBAG V2.0\n")
    head_at = len(out)
    out += bytes(4096)   # the bag header, written at the end
    infos = []
    for k, messages in enumerate(chunks):
        inner = bytearray(connection)
        index = []
        for t, data in messages:
            index.append((t, len(inner)))
            inner += _ros_record(data, op=b"\x02", conn=conn, time=_ros_time(t))
        packed = {"bz2": _bz2.compress, "lz4": lz4.frame.compress, "none": bytes}[compression](bytes(inner))
        packed = (chunk_data or {}).get(k, packed)
        size = (declared or {}).get(k, len(inner))
        pos = len(out)
        out += _ros_record(packed, op=b"\x05", compression=compression.encode(), size=struct.pack("<I", size))
        entries = b"".join(_ros_time(t) + struct.pack("<I", off) for t, off in index)
        out += _ros_record(entries, op=b"\x04", ver=struct.pack("<I", 1), conn=conn,
                           count=struct.pack("<I", len(index)))
        times = [t for t, _ in messages]
        infos.append(_ros_record(conn + struct.pack("<I", len(index)), op=b"\x06", ver=struct.pack("<I", 1),
                                 chunk_pos=struct.pack("<Q", pos), start_time=_ros_time(min(times)),
                                 end_time=_ros_time(max(times)), count=struct.pack("<I", 1)))
    index_pos = len(out)
    out += connection
    for info in infos:
        out += info
    header = _ros_header(op=b"\x03", index_pos=struct.pack("<Q", index_pos), conn_count=struct.pack("<I", 1),
                         chunk_count=struct.pack("<I", len(chunks)))
    padding = 4096 - len(header) - 4
    out[head_at:head_at + 4096] = header + struct.pack("<I", padding) + b" " * padding
    return bytes(out)
