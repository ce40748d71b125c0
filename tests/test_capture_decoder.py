"""The live stream decoder gives what `record`'s converter gives on the whole log, however the bytes arrive."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.lines import strip_prefix
from formats.records import Where
from recorders.base import Ignored, LogContext, Output
from recorders.capture.base import SourceError
from recorders.capture.decoder import StreamDecoder, stamp_prefix
from recorders.capture.sources import make_source
from recorders.manifest import ManifestError, load_manifest, parse_manifest
from recorders.record import log_context, record
from recorders.registry import binary_formats, block_converters, converters, is_binary

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "samples" / "lake_trial" / "trial.toml"
MANIFEST = load_manifest(SAMPLE)
TABLE = converters()
# one log per decoder kind: NMEA epochs, PHINS bursts, binary PD0, NovAtel, Micro-Modem, EvoLogics USBL groups
LOGS = {log.path: log for log in MANIFEST.logs()
        if log.path in ("leader1/gps.log", "leader1/ins.log", "leader1/dvl.pd0", "leader2/gps.log",
                        "follower/modem.log", "buoy1/usbl.log")}
PREFIX_BYTES = 24_000


def _key(item):
    if type(item) is Output:
        return (item.topic, item.log_time_ns, item.publish_time_ns, item.message.SerializeToString(),
                item.where.offset)
    return ("reject", item.where.offset, item.where.line, item.reason)


def _fed(log, data: bytes, cuts: list[int], decode_every: int, stamp: bool) -> list:
    d = StreamDecoder(TABLE[(log.sensor, log.format)], log_context(MANIFEST, log), log.sensor, log.format)
    d.stamp = d.stamp and stamp
    out, pos = [], 0
    for k, n in enumerate(cuts):
        d.feed(data[pos:pos + n], 1_800_000_000 * 10**9 + pos)
        pos += n
        if k % decode_every == 0:
            out += d.decode()
    d.feed(data[pos:], 1_800_000_000 * 10**9 + pos)
    return out + d.decode(final=True)


@settings(max_examples=8, deadline=None)
@given(path=st.sampled_from(sorted(LOGS)), seed=st.integers(0, 2**31), step=st.integers(1, 4),
       largest=st.sampled_from([7, 200, 3000]))
def test_windowed_decode_equals_whole_log(path, seed, step, largest):
    log = LOGS[path]
    data = (MANIFEST.root / log.path).read_bytes()[:PREFIX_BYTES]
    rng = random.Random(seed)
    cuts = []
    while sum(cuts) < len(data):
        cuts.append(rng.randint(1, largest))
    want = [_key(i) for i in TABLE[(log.sensor, log.format)](data, log_context(MANIFEST, log))]
    assert [_key(i) for i in _fed(log, data, cuts, step, stamp=False)] == want


def test_stamped_lines_keep_device_times_and_get_receive_times():
    """Lines without a host prefix get the receive time; a format with its own clock keeps its log times."""
    log = LOGS["leader1/ins.log"]  # PHINS with TIME__, no host prefix
    data = (MANIFEST.root / log.path).read_bytes()[:PREFIX_BYTES]
    plain = list(TABLE[(log.sensor, log.format)](data, log_context(MANIFEST, log)))
    stamped = _fed(log, data, [500] * (len(data) // 500), 1, stamp=True)
    outs = [i for i in stamped if type(i) is Output]
    timed = [(o.topic, o.log_time_ns, o.message.SerializeToString()) for o in plain if type(o) is Output]
    assert [(o.topic, o.log_time_ns, o.message.SerializeToString()) for o in outs[:len(timed)]] == timed
    assert all(o.publish_time_ns >= 1_800_000_000 * 10**9 for o in outs)  # the receive time, not the device's
    # the cut-off last burst has no TIME__: a reject from the file, the receive time live
    no_time = [i for i in plain if type(i) is not Output and i.reason.startswith("no time")]
    assert len(outs) - len(timed) == len(no_time) == 1
    assert outs[-1].log_time_ns >= 1_800_000_000 * 10**9


@pytest.mark.parametrize("style", ["auto", "iso8601", "unix"])
def test_stamp_prefix_reads_back(style):
    t = 1_476_237_600_123_456_789
    rest, host = strip_prefix(stamp_prefix(t, style).decode() + "$GPGGA,1", style)
    assert (rest, host) == ("$GPGGA,1", t)


def test_manifest_source_instead_of_path(tmp_path):
    text = """[trial]\nname = "t"\n[[vehicles]]\nname = "a"\nrole = "leader"\n[[vehicles.logs]]\n""" \
           """sensor = "gps"\nformat = "nmea"\nsource = "udp://127.0.0.1:5000"\n"""
    (tmp_path / "m.toml").write_text(text)
    log = load_manifest(tmp_path / "m.toml").logs()[0]
    assert (log.source, log.path) == ("udp://127.0.0.1:5000", "a/gps.nmea")
    with pytest.raises(ManifestError, match="live source"):
        record(load_manifest(tmp_path / "m.toml"), tmp_path / "x.mcap")
    with pytest.raises(ManifestError, match="'source' must be text"):
        parse_manifest(text.replace('"udp://127.0.0.1:5000"', "5"), tmp_path / "m.toml")


@pytest.mark.parametrize("url, message", [
    ("ftp://x:1", "unknown source kind"), ("udp://127.0.0.1", "HOST:PORT"), ("tcp://:80", "HOST:PORT"),
    ("serial:///dev/ttyUSB0?baud=fast", "baud must be an integer"), ("tail:", "tail:PATH"),
])
def test_bad_source_addresses_say_why(url, message):
    with pytest.raises(SourceError, match=message):
        make_source(url)


def _ignore_lines(data: bytes, ctx):
    """A converter that reads every line whole and archives none (an unmapped topic, say)."""
    pos = 0
    for number, line in enumerate(data.splitlines(keepends=True), 1):
        yield Ignored(Where(pos, number), "unmapped")
        pos += len(line)


def test_ignored_items_are_counted_over_the_whole_stream():
    """Ignored is frozen like Reject: a later window rebases a copy instead of assigning to it."""
    log = LOGS["leader1/gps.log"]
    d = StreamDecoder(_ignore_lines, log_context(MANIFEST, log), log.sensor, log.format)
    d.stamp = False
    data = b"".join(b"line %05d\n" % k for k in range(2000))  # 22 kB: well past HOLD_BYTES, so the window moves
    out = []
    for at in range(0, len(data), 1100):
        d.feed(data[at:at + 1100], 1_800_000_000 * 10**9 + at)
        out += d.decode()
    out += d.decode(final=True)
    assert [(i.where.offset, i.where.line) for i in out] == [(11 * k, k + 1) for k in range(2000)]
    assert all(type(i) is Ignored and i.reason == "unmapped" for i in out)


def test_the_decoder_reads_binariness_from_the_registry() -> None:
    """Binary formats are the registry's: taken as bytes, never cut into lines nor stamped; text ones are."""
    blocks = block_converters()
    assert binary_formats() == {("dvl", "pd0"), ("dvl", "pd4"), ("dvl", "pd5"), ("gps", "novatel"),
                                ("ins", "novatel"), ("", "rosbag"), ("", "mavlink")}
    for (sensor, fmt), convert in TABLE.items():
        d = StreamDecoder(convert, LogContext("v"), sensor, fmt)
        assert d.text == (not is_binary(sensor, fmt)) and d.stamp == d.text, (sensor, fmt)
        # a line-based format's converter also takes its log in blocks (recorders.base); a binary one never does
        assert ((sensor, fmt) in blocks) == d.text, (sensor, fmt)


@pytest.mark.parametrize("path", ["leader1/gps.log", "leader1/ins.log", "leader1/dvl.pd0", "leader2/gps.log"])
@pytest.mark.parametrize("stamp", [False, True])
def test_each_byte_is_converted_about_once(path, stamp):
    # fed in datagrams and decoded every ~8 KB, as `bench/bench_capture.py` at 400x decodes these logs: the
    # windows overlap only by a warm-up record and the held epoch (a stamped stream counts its stamps)
    log = LOGS[path]
    data = (MANIFEST.root / log.path).read_bytes()[:200_000]
    d = StreamDecoder(TABLE[(log.sensor, log.format)], log_context(MANIFEST, log), log.sensor, log.format)
    d.stamp = d.stamp and stamp
    out = []
    for pos in range(0, len(data), 1400):
        d.feed(data[pos:pos + 1400], 1_800_000_000 * 10**9 + pos * 10**6)
        if (pos // 1400) % 6 == 5:
            out += d.decode(budget=128 << 10)
    out += d.decode(final=True)
    stream = d._base + len(d._buf)
    assert stream == len(data) or stamp
    assert d.converted <= 1.2 * stream
    if not stamp:
        assert [_key(i) for i in out] == [_key(i) for i in TABLE[(log.sensor, log.format)](data, d.ctx)]


def test_an_epoch_longer_than_the_budget_doubles_the_window_not_converts_it_again():
    # 64 GGA of one time (about 5 KB) in a budget of 500 bytes: windows of 0.5, 1, 2, 4, 8 KB, none repeated whole
    log = LOGS["leader1/gps.log"]
    line = (MANIFEST.root / log.path).read_bytes().split(b"\n", 1)[0] + b"\n"
    data = line * 64 + (MANIFEST.root / log.path).read_bytes()[len(line):30_000]
    data = data[:data.rfind(b"\n") + 1]
    d = StreamDecoder(TABLE[(log.sensor, log.format)], log_context(MANIFEST, log), log.sensor, log.format)
    d.stamp = False
    d.feed(data, 1)
    out: list = []
    while not out:
        out += d.decode(budget=500)
    # settled after windows of 0.5 + 1 + 2 + 4 + 8 KB; converting the whole stream again would be 35 KB
    assert d.converted <= 4 * 64 * len(line) < len(data)
    while d.pending:
        out += d.decode(budget=500)
    out += d.decode(final=True)
    assert [_key(i) for i in out] == [_key(i) for i in TABLE[(log.sensor, log.format)](data, d.ctx)]
