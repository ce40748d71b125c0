"""Our MCAP chunk writer, judged by other readers: mcap's Seeking/NonSeeking readers (CRCs on),
our reader, a byte-level walk of the layout, and Rerun's `mcap convert` (the Rust mcap crate)."""

from __future__ import annotations

import struct
import subprocess
import zlib
from pathlib import Path

import numpy as np
import pytest
import zstandard
from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import NonSeekingReader, SeekingReader
from mcap.records import (
    Attachment,
    Channel,
    Chunk,
    DataEnd,
    Footer,
    Message,
    MessageIndex,
    Metadata,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.stream_reader import StreamReader
from mcap.writer import Writer

from formats import schemas as S
from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import MAGIC, ArchiveWriter
from formats.units import NS, archivable_ns

T0 = 1_476_259_200_000_000_000  # 2016-10-12T08:00:00Z


def fix(i: int) -> object:
    return S.location_fix(T0 + i, "a", 45.0 + i * 1e-6, 126.0, float(i), (1.0, 0, 0, 0, 1.0, 0, 0, 0, 4.0), 2)


def status(i: int) -> object:
    return S.GnssStatus(timestamp=S.timestamp(T0 + i), frame_id="b", satellites=i % 30, hdop=0.5 + i % 7)


def write_mixed(path: Path, n: int, chunk_size: int = 4096) -> list[tuple[str, int, bytes]]:
    """n messages over two topics, with a log time going backwards now and then; returns what was written."""
    written = []
    with ArchiveWriter(path, chunk_size=chunk_size) as w:
        for i in range(n):
            t = T0 + i * 1000 - (5000 if i % 97 == 5 else 0)
            topic, msg = ("/a/gps", fix(i)) if i % 3 else ("/b/gps/status", status(i))
            w.write(topic, msg, t, t + 7)
            written.append((topic, t, msg.SerializeToString()))
    return written


def stream_records(path: Path) -> list[object]:
    """Every record in file order with chunks kept whole, CRCs (chunk, data section) validated."""
    with open(path, "rb") as f:
        return list(StreamReader(f, emit_chunks=True, validate_crcs=True).records)


def check_footer_and_summary(path: Path) -> None:
    """The footer's summary CRC and every summary offset, recomputed from the bytes."""
    data = path.read_bytes()
    assert data[:8] == MAGIC and data[-8:] == MAGIC
    footer_at = len(data) - 8 - 29
    opcode, length, summary_start, offset_start, crc = struct.unpack_from("<BQQQI", data, footer_at)
    assert (opcode, length) == (0x02, 20)
    assert crc == zlib.crc32(data[summary_start : footer_at + 25])
    pos = offset_start
    while pos < footer_at:
        op, ln, group_op, start, glen = struct.unpack_from("<BQBQQ", data, pos)
        assert op == 0x0E
        q, end = start, start + glen
        while q < end:  # every record of the group has the group's opcode
            assert data[q] == group_op
            q += 9 + struct.unpack_from("<Q", data, q + 1)[0]
        assert q == end
        pos += 9 + ln


def test_empty_archive_is_valid_for_every_reader(tmp_path):
    path = tmp_path / "empty.mcap"
    ArchiveWriter(path).close()
    check_footer_and_summary(path)
    with open(path, "rb") as f:
        summary = SeekingReader(f, validate_crcs=True).get_summary()
        assert summary.statistics.message_count == 0 and summary.chunk_indexes == []
    with open(path, "rb") as f:
        assert list(NonSeekingReader(f, validate_crcs=True).iter_messages()) == []
    with ArchiveReader(path) as r:
        assert list(r.messages()) == [] and not r.problems and r.summary().topics == {}


def test_channel_without_messages_is_in_the_data_section_and_summary(tmp_path):
    path = tmp_path / "chan.mcap"
    with ArchiveWriter(path) as w:
        assert w.channel("/a/gps", type(fix(0))) == 1
    kinds = [type(r) for r in stream_records(path)]
    assert kinds.index(Schema) < kinds.index(Channel) < kinds.index(DataEnd)
    assert Chunk not in kinds
    with ArchiveReader(path) as r:
        assert r.summary().topics == {"/a/gps": {"count": 0, "schema": "foxglove.LocationFix"}}


def test_one_message_reads_back_with_mcap_and_ours(tmp_path):
    path = tmp_path / "one.mcap"
    msg = fix(3)
    with ArchiveWriter(path) as w:
        w.write("/a/gps", msg, T0 + 3, T0 + 9)
    check_footer_and_summary(path)
    with open(path, "rb") as f:
        ((schema, channel, m),) = list(SeekingReader(f, validate_crcs=True).iter_messages())
    assert (schema.name, schema.encoding, channel.topic, channel.message_encoding) == (
        "foxglove.LocationFix", "protobuf", "/a/gps", "protobuf")
    assert (m.log_time, m.publish_time, m.sequence, m.data) == (T0 + 3, T0 + 9, 0, msg.SerializeToString())
    with ArchiveReader(path) as r:
        (got,) = list(r.messages())
    assert got.message == msg and got.publish_time_ns == T0 + 9


def test_many_chunks_same_messages_for_seeking_nonseeking_and_ours(tmp_path):
    path = tmp_path / "many.mcap"
    written = write_mixed(path, 3000)
    check_footer_and_summary(path)
    expected = sorted(written, key=lambda x: x[1])
    with open(path, "rb") as f:
        reader = SeekingReader(f, validate_crcs=True)
        summary = reader.get_summary()
        seeking = [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages(log_time_order=True)]
    assert len(summary.chunk_indexes) > 20
    assert sorted(seeking) == sorted(written)  # equal times may come in either order
    assert [t for _, t, _ in seeking] == [t for _, t, _ in expected]
    with open(path, "rb") as f:
        plain = [(c.topic, m.log_time, m.data)
                 for _, c, m in NonSeekingReader(f, validate_crcs=True).iter_messages(log_time_order=False)]
    assert plain == written  # file order is write order
    with ArchiveReader(path) as r:
        ours = [(m.topic, m.log_time_ns, m.message.SerializeToString()) for m in r.messages()]
        s = r.summary()
    assert sorted(ours) == sorted(written) and [t for _, t, _ in ours] == sorted(t for _, t, _ in written)
    assert s.topics == {"/a/gps": {"count": 2000, "schema": "foxglove.LocationFix"},
                        "/b/gps/status": {"count": 1000, "schema": "auvreplay.GnssStatus"}}
    assert (s.start_ns, s.end_ns, s.message_count) == (min(t for _, t, _ in written), max(t for _, t, _ in written), 3000)


def test_sequences_count_per_channel(tmp_path):
    path = tmp_path / "seq.mcap"
    write_mixed(path, 300)
    with open(path, "rb") as f:
        seqs: dict[str, list[int]] = {}
        for _, c, m in NonSeekingReader(f).iter_messages(log_time_order=False):
            seqs.setdefault(c.topic, []).append(m.sequence)
    assert seqs == {"/a/gps": list(range(200)), "/b/gps/status": list(range(100))}


def test_chunk_and_message_indexes_point_at_the_right_bytes(tmp_path):
    path = tmp_path / "idx.mcap"
    written = write_mixed(path, 1500, chunk_size=2048)
    records = stream_records(path)
    data = path.read_bytes()
    with open(path, "rb") as f:
        summary = SeekingReader(f).get_summary()
    chunks = [r for r in records if isinstance(r, Chunk)]
    assert len(chunks) == len(summary.chunk_indexes)
    total = 0
    for chunk, ci in zip(chunks, summary.chunk_indexes):
        raw = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
        assert chunk.compression == ci.compression == "zstd" and zlib.crc32(raw) == chunk.uncompressed_crc
        assert data[ci.chunk_start_offset] == 0x06
        assert ci.chunk_length == 9 + struct.unpack_from("<Q", data, ci.chunk_start_offset + 1)[0]
        assert ci.message_index_length == sum(9 + struct.unpack_from("<Q", data, o + 1)[0]
                                              for o in ci.message_index_offsets.values())
        times = []
        for cid, offset in ci.message_index_offsets.items():
            (count_bytes,) = struct.unpack_from("<I", data, offset + 11)
            assert data[offset] == 0x07 and struct.unpack_from("<H", data, offset + 9)[0] == cid
            pairs = np.frombuffer(data, "<u8", count_bytes // 8, offset + 15).reshape(-1, 2)
            assert np.all(np.diff(pairs[:, 0].astype(np.int64)) >= 0)  # sorted by log time
            for t, off in pairs:
                op, _, ch, _, log_time = struct.unpack_from("<BQHIQ", raw, int(off))
                assert (op, ch, log_time) == (0x05, cid, t)
                times.append(int(t))
        assert (ci.message_start_time, ci.message_end_time) == (min(times), max(times))
        assert (chunk.message_start_time, chunk.message_end_time) == (min(times), max(times))
        total += len(times)
    assert total == len(written)
    stats = summary.statistics
    assert (stats.message_count, stats.chunk_count, stats.channel_count, stats.schema_count) == (1500, len(chunks), 2, 2)
    assert stats.channel_message_counts == {1: 500, 2: 1000}  # /b is registered first (i = 0)


def test_attachments_and_metadata_read_by_mcap_with_crcs(tmp_path):
    path = tmp_path / "att.mcap"
    blob = np.random.default_rng(4).bytes(300_000)
    with ArchiveWriter(path, chunk_size=1024) as w:
        w.add_attachment("follower/dvl.pd0", blob, "application/octet-stream", T0, T0 - 5)
        for i in range(100):
            w.write("/a/gps", fix(i), T0 + i)
        w.add_attachment("empty.log", b"", "text/plain")
        w.add_metadata("trial", {"name": "lake", "vehicles": ["leader1"]})
        w.add_metadata("recording", {"files": 2})
    check_footer_and_summary(path)
    records = stream_records(path)
    atts = [r for r in records if isinstance(r, Attachment)]
    assert [(a.name, a.media_type, a.log_time, a.create_time, len(a.data)) for a in atts] == [
        ("follower/dvl.pd0", "application/octet-stream", T0, T0 - 5, 300_000), ("empty.log", "text/plain", 0, 0, 0)]
    assert atts[0].data == blob
    assert [(m.name, m.metadata) for m in records if isinstance(m, Metadata)] == [
        ("trial", {"name": "lake", "vehicles": '["leader1"]'}), ("recording", {"files": "2"})]
    with open(path, "rb") as f:
        reader = SeekingReader(f, validate_crcs=True)
        summary = reader.get_summary()
        assert [a.data for a in reader.iter_attachments()] == [blob, b""]  # attachment CRCs checked here
        assert [m.name for m in reader.iter_metadata()] == ["trial", "recording"]
    assert [(a.name, a.data_size) for a in summary.attachment_indexes] == [("follower/dvl.pd0", 300_000), ("empty.log", 0)]
    with ArchiveReader(path) as r:
        assert r.metadata_json("trial")["vehicles"] == ["leader1"]
        assert len(list(r.messages())) == 100


def test_summary_groups_in_order_with_offsets(tmp_path):
    path = tmp_path / "sum.mcap"
    with ArchiveWriter(path, chunk_size=512) as w:
        w.add_attachment("a.log", b"abc")
        for i in range(60):
            w.write("/a/gps", fix(i), T0 + i)
        w.add_metadata("trial", {"name": "x"})
    records = stream_records(path)
    after = records[[type(r) for r in records].index(DataEnd) + 1:]
    kinds = [type(r).__name__ for r in after]
    order = ["Schema", "Channel", "Statistics", "ChunkIndex", "AttachmentIndex", "MetadataIndex", "SummaryOffset", "Footer"]
    assert sorted(set(kinds), key=order.index) == order
    assert [order.index(k) for k in kinds] == sorted(order.index(k) for k in kinds)
    offsets = {r.group_opcode for r in after if isinstance(r, SummaryOffset)}
    assert offsets == {0x03, 0x04, 0x0B, 0x08, 0x0A, 0x0D}
    assert isinstance(after[-1], Footer) and isinstance(after[2], Statistics)
    assert not any(isinstance(r, (Message, MessageIndex)) for r in after)


def test_write_serialized_by_topic_or_id_matches_write(tmp_path):
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    with ArchiveWriter(a) as w:
        for i in range(50):
            w.write("/a/gps", fix(i), T0 + i, T0 + 2 * i)
    with ArchiveWriter(b) as w:
        cid = w.channel("/a/gps", type(fix(0)))
        for i in range(50):
            w.write_serialized("/a/gps" if i % 2 else cid, fix(i).SerializeToString(), T0 + i, T0 + 2 * i)
        with pytest.raises(KeyError, match="not a registered channel"):
            w.write_serialized("/nope", b"", T0)
    with open(a, "rb") as fa, open(b, "rb") as fb:
        ma = [(c.topic, m.sequence, m.log_time, m.publish_time, m.data) for _, c, m in SeekingReader(fa).iter_messages()]
        mb = [(c.topic, m.sequence, m.log_time, m.publish_time, m.data) for _, c, m in SeekingReader(fb).iter_messages()]
    assert ma == mb and len(ma) == 50
    assert a.read_bytes() == b.read_bytes()  # the same bytes, message for message


def test_write_serialized_batch_writes_the_same_file_as_one_by_one(tmp_path):
    """A batch gives the very bytes its messages written one at a time give, chunks closed at the same places."""
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    payloads = [fix(i).SerializeToString() for i in range(300)]
    times = [T0 + 10 * i for i in range(300)]
    with ArchiveWriter(a, chunk_size=2048) as w:
        w.channel("/a/gps", type(fix(0)))
        for data, t in zip(payloads, times):
            w.write_serialized("/a/gps", data, t, t + 1)
    with ArchiveWriter(b, chunk_size=2048) as w:
        w.channel("/a/gps", type(fix(0)))
        w.write_serialized_batch("/a/gps", payloads[:7], times[:7], [t + 1 for t in times[:7]])
        w.write_serialized_batch("/a/gps", payloads[7:], times[7:], [t + 1 for t in times[7:]])
        w.write_serialized_batch("/a/gps", [], [])
        with pytest.raises(KeyError, match="not a registered channel"):
            w.write_serialized_batch("/nope", [b""], [T0])
    assert a.read_bytes() == b.read_bytes()


def test_same_messages_as_the_mcap_library_writer(tmp_path):
    ours, theirs = tmp_path / "ours.mcap", tmp_path / "theirs.mcap"
    written = write_mixed(ours, 800)
    with open(theirs, "wb") as f:
        w = Writer(f, chunk_size=4096)
        w.start()
        ids = {}
        for topic, cls in (("/b/gps/status", type(status(0))), ("/a/gps", type(fix(0)))):
            from mcap_protobuf.schema import register_schema

            ids[topic] = w.register_channel(topic, "protobuf", register_schema(w, cls))
        for topic, t, data in written:
            w.add_message(ids[topic], t, data, t + 7)
        w.finish()
    with ArchiveReader(ours) as r1, ArchiveReader(theirs) as r2:
        a = [(m.topic, m.log_time_ns, m.publish_time_ns, m.message.SerializeToString()) for m in r1.messages()]
        b = [(m.topic, m.log_time_ns, m.publish_time_ns, m.message.SerializeToString()) for m in r2.messages()]
        assert r1.summary().topics == r2.summary().topics
    assert sorted(a) == sorted(b) and len(a) == 800


def test_interrupted_write_leaves_nothing_and_closed_writer_refuses(tmp_path):
    path = tmp_path / "out.mcap"
    with pytest.raises(RuntimeError):
        with ArchiveWriter(path, chunk_size=256) as w:
            for i in range(100):
                w.write("/a/gps", fix(i), T0 + i)
            raise RuntimeError("crash")
    assert list(tmp_path.iterdir()) == []
    w = ArchiveWriter(path)
    w.write("/a/gps", fix(0), T0)
    w.close()
    with pytest.raises(ValueError, match="closed"):
        w.write("/a/gps", fix(1), T0 + 1)
    with pytest.raises(KeyError):
        w.write_serialized("/a/gps", b"", T0 + 1)
    assert w.close() == path  # a second close does nothing


def test_cut_file_recovers_complete_chunks_with_our_reader(tmp_path):
    path = tmp_path / "cut.mcap"
    written = write_mixed(path, 2000)
    data = path.read_bytes()
    (tmp_path / "half.mcap").write_bytes(data[: len(data) // 2])
    with ArchiveReader(tmp_path / "half.mcap") as r:
        got = list(r.messages())
        assert r.recovered
    assert 500 < len(got) < 2000
    assert {(m.topic, m.log_time_ns) for m in got} <= {(t, ts) for t, ts, _ in written}


def test_rerun_mcap_convert_reads_many_chunks_attachments_and_metadata(tmp_path, venv_bin):
    rerun_cli = venv_bin / "rerun"
    if not rerun_cli.exists():
        pytest.fail("the rerun CLI that rerun-sdk installs is missing")
    from rerun.chunk import RrdReader

    path, rrd = tmp_path / "x.mcap", tmp_path / "x.rrd"
    with ArchiveWriter(path, chunk_size=700) as w:
        w.add_attachment("a.log", b"$GPGGA\r\n", "text/plain")
        for i in range(120):
            w.write("/a/gps", S.location_fix(T0 + i * 10**9, "a", 45.0 + i * 1e-5, 126.0, 0.0), T0 + i * 10**9)
        w.add_metadata("trial", {"name": "x"})
    subprocess.run([str(rerun_cli), "mcap", "convert", str(path), "-o", str(rrd)], check=True, capture_output=True)
    points = []
    for chunk in RrdReader(rrd).stream().to_chunks():
        if chunk.entity_path == "/a/gps":
            batch = chunk.to_record_batch()
            for name in batch.schema.names:
                if name.endswith("GeoPoints:positions"):
                    points.extend(p for cell in batch.column(name).to_pylist() for p in cell)
    assert len(points) == 120
    np.testing.assert_allclose(sorted(p[0] for p in points), 45.0 + np.arange(120) * 1e-5, atol=1e-9)


def test_rerun_mcap_convert_accepts_an_empty_archive(tmp_path, venv_bin):
    path, rrd = tmp_path / "e.mcap", tmp_path / "e.rrd"
    ArchiveWriter(path).close()
    done = subprocess.run([str(venv_bin / "rerun"), "mcap", "convert", str(path), "-o", str(rrd)], capture_output=True)
    assert done.returncode == 0, done.stderr.decode(errors="replace")[-500:]


@settings(max_examples=20, deadline=None)
@given(
    items=st.lists(st.tuples(st.sampled_from(["/a/gps", "/b/gps/status"]), st.integers(0, 2**63 - 1)), max_size=60),
    chunk_size=st.sampled_from([64, 300, 1 << 20]),
)
def test_any_write_order_reads_back_in_time_order(tmp_path_factory, items, chunk_size):
    path = tmp_path_factory.mktemp("h") / "h.mcap"
    with ArchiveWriter(path, chunk_size=chunk_size) as w:
        for k, (topic, t) in enumerate(items):
            w.write(topic, fix(k) if topic == "/a/gps" else status(k), t)
    check_footer_and_summary(path)
    stream_records(path)  # CRCs
    with open(path, "rb") as f:
        reader = SeekingReader(f, validate_crcs=True)
        got = [(c.topic, m.log_time) for _, c, m in reader.iter_messages(log_time_order=True)]
        stats = reader.get_summary().statistics
    assert sorted(got) == sorted(items) and [t for _, t in got] == sorted(t for _, t in items)
    assert stats.message_count == len(items)
    if items:
        assert (stats.message_start_time, stats.message_end_time) == (min(t for _, t in items), max(t for _, t in items))


def location_fix_reference(t_ns, frame_id, lat, lon, alt, cov, kind):
    """The obvious construction, field by field: the judge of schemas.location_fix's wire-bytes shortcut."""
    out = LocationFix()
    if archivable_ns(t_ns):  # outside 1970-2200 the field stays absent
        out.timestamp.seconds, out.timestamp.nanos = divmod(t_ns, NS)
    out.frame_id, out.latitude, out.longitude, out.altitude = frame_id, lat, lon, alt
    out.position_covariance.extend([float("nan")] * 9 if cov is None else cov)
    out.position_covariance_type = 0 if cov is None else kind
    return out


@settings(max_examples=200, deadline=None)
@given(
    t=st.integers(-(2**62), 2**62), name=st.text(max_size=12), lat=st.floats(), lon=st.floats(), alt=st.floats(),
    cov=st.none() | st.lists(st.floats(), min_size=9, max_size=9).map(tuple) | st.lists(st.floats(), max_size=12),
    kind=st.integers(0, 3),
)
def test_location_fix_equals_the_field_by_field_construction(t, name, lat, lon, alt, cov, kind):
    got = S.location_fix(t, name, lat, lon, alt, cov, kind)
    assert got.SerializeToString() == location_fix_reference(t, name, lat, lon, alt, cov, kind).SerializeToString()
    assert got.HasField("timestamp") == archivable_ns(t) and got.frame_id == name
    assert S.to_ns(got.timestamp) == (t if archivable_ns(t) else 0)
