"""Archive I/O throughput: our writer and reader against the bare mcap writer, same run.

Writes N small archive messages over 4 topics (default 1e6), then reads them
back decoded. The bare writer adds the same messages pre-encoded as bytes;
ours writes them as messages (serializing each) and, like for like, as the
same bytes through write_serialized.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import median_time, print_table
from mcap.reader import make_reader
from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

from formats import schemas as S
from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import ArchiveWriter

T0 = 1_476_259_200_000_000_000


def message_pool(size: int = 1000) -> list[tuple[str, object]]:
    """A cycle of small messages over 4 topics."""
    pool = []
    for i in range(size):
        t = T0 + i * 10**8
        ts = S.timestamp(t)
        pool.append(("/follower/gps", S.location_fix(t, "follower", 45.7 + i * 1e-6, 126.6, 0.0)))
        pool.append(("/follower/gps/status", S.GnssStatus(timestamp=ts, fix_quality=1, satellites=9, hdop=0.9)))
        pool.append(("/follower/modem/range", S.AcousticRange(timestamp=ts, source="leader1", destination="follower",
                                                              travel_time_s=0.4, range_m=600.0, kind="ping")))
        pool.append(("/follower/ins", S.InsState(timestamp=ts, latitude=45.7, longitude=126.6, heading_deg=90.0)))
    return pool


def write_ours(path: Path, n: int, pool) -> None:
    with ArchiveWriter(path) as w:
        for i in range(n):
            topic, msg = pool[i % len(pool)]
            w.write(topic, msg, T0 + i * 1000)


def write_bare(path: Path, n: int, encoded) -> None:
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start()
        ids = {}
        for topic, cls, _ in encoded[:8]:
            if topic not in ids:
                sid = w.register_schema(cls.DESCRIPTOR.full_name, SchemaEncoding.Protobuf,
                                        build_file_descriptor_set(cls).SerializeToString())
                ids[topic] = w.register_channel(topic, MessageEncoding.Protobuf, sid)
        for i in range(n):
            topic, _, data = encoded[i % len(encoded)]
            t = T0 + i * 1000
            w.add_message(ids[topic], t, data, t)
        w.finish()


def write_ours_bytes(path: Path, n: int, encoded) -> None:
    with ArchiveWriter(path) as w:
        for topic, cls, _ in encoded[:8]:
            w.channel(topic, cls)
        for i in range(n):
            topic, _, data = encoded[i % len(encoded)]
            t = T0 + i * 1000
            w.write_serialized(topic, data, t, t)


def read_ours(path: Path) -> int:
    with ArchiveReader(path) as r:
        return sum(1 for _ in r.messages())


def read_bare(path: Path) -> int:
    with open(path, "rb") as f:
        return sum(1 for _ in make_reader(f).iter_messages())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("-n", type=int, default=1_000_000, help="messages (default 1e6)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    pool = message_pool()
    encoded = [(t, type(m), m.SerializeToString()) for t, m in pool]
    with tempfile.TemporaryDirectory() as d:
        ours, bare = Path(d) / "ours.mcap", Path(d) / "bare.mcap"
        t_bare_w = median_time(lambda: write_bare(bare, args.n, encoded), args.repeats)
        t_ours_w = median_time(lambda: write_ours(ours, args.n, pool), args.repeats)
        t_ours_b = median_time(lambda: write_ours_bytes(Path(d) / "bytes.mcap", args.n, encoded), args.repeats)
        t_ours_r = median_time(lambda: read_ours(ours), args.repeats)
        t_bare_r = median_time(lambda: read_bare(bare), args.repeats)
        assert read_ours(ours) == args.n
        size = os.path.getsize(ours)
    n = args.n
    print_table(
        f"MCAP archive I/O, {n:,} messages over 4 topics (median of {args.repeats}; file {size / 1e6:.1f} MB)",
        ["what", "seconds", "msgs/s", "ratio to bare"],
        [
            ["bare mcap writer, pre-encoded bytes", t_bare_w, n / t_bare_w, 1.0],
            ["ours: ArchiveWriter.write(message)", t_ours_w, n / t_ours_w, t_bare_w / t_ours_w],
            ["ours: ArchiveWriter.write_serialized(bytes)", t_ours_b, n / t_ours_b, t_bare_w / t_ours_b],
            ["bare mcap reader, undecoded", t_bare_r, n / t_bare_r, 1.0],
            ["ours: ArchiveReader.messages() decoded", t_ours_r, n / t_ours_r, t_bare_r / t_ours_r],
        ],
    )
    print(f"  writer goal: >= 50 % of bare -> {'met' if t_bare_w / t_ours_w >= 0.5 else 'NOT met'} "
          f"({100 * t_bare_w / t_ours_w:.0f} %)")


if __name__ == "__main__":
    main()
