"""Capture against hostile sources: a FIFO with no writer, a full disk, paths outside, floods of clients,
a stalled client, a fast writer, a 100 MB line without a newline.

Everything is built in the test and binds 127.0.0.1 only; every wait is bounded. How long a stop takes
and how fast a file is read are printed (pytest -s), never asserted: the loop's structure is what is
checked (a stop is seen within a turn, a turn reads up to its budget).
"""

from __future__ import annotations

import errno
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.lines import strip_prefix
from formats.mcap_reader import ArchiveReader
from formats.mcap_recover import recover
from formats.nmea.framing import nmea_checksum
from recorders.capture.decoder import MAX_LINE_BYTES, StreamDecoder, stamp_prefix
from recorders.capture.session import POLL_BUDGET, CaptureOptions, CaptureSession, CaptureStopped, part_path
from recorders.manifest import ManifestError, parse_manifest
from recorders.record import log_context
from recorders.registry import converters
from tests.hostile import run_child
from tests.processes import end_group

ROOT = Path(__file__).resolve().parent.parent
WAIT_S = 60.0


def gga(i: int) -> bytes:
    """A valid GGA sentence, one second after the previous (from 08:00:00), with its checksum."""
    h, rest = divmod(8 * 3600 + i, 3600)
    body = f"GPGGA,{h:02d}{rest // 60:02d}{rest % 60:02d}.00,4542.{i % 10000:04d},N,12636.0000,E,1,08,0.9,10.0,M,0.0,M,,"
    return f"${body}*{nmea_checksum(body):02X}\r\n".encode()


def manifest_text(source: str, path: str = "a/gps.log") -> str:
    return (f'[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "a"\nrole = "leader"\n'
            f'[[vehicles.logs]]\nsensor = "gps"\nformat = "nmea"\npath = "{path}"\nsource = "{source}"\n')


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def raw_by_connection(path: Path) -> dict[int, bytes]:
    """The raw bytes of the archive's one stream, by connection number."""
    out: dict[int, list[tuple[int, bytes]]] = {}
    with ArchiveReader(path) as r:
        for m in r.messages([t for t in r.summary().topics if t.startswith("/raw/")]):
            out.setdefault(m.message.connection, []).append((m.message.offset, m.message.data))
    return {c: b"".join(d for _, d in sorted(parts)) for c, parts in out.items()}


def gps_count(path: Path) -> int:
    with ArchiveReader(path) as r:
        return sum(1 for _ in r.messages(["/a/gps"]))


def _cli(*args: str, cwd: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen([sys.executable, "-m", "replay.cli", *args], env=env, text=True, cwd=cwd,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)


def _wait_line(proc: subprocess.Popen, text: str) -> list[str]:
    lines: list[str] = []
    assert proc.stderr is not None
    for line in proc.stderr:   # bounded: the child exits by itself at --duration, or end_group ends it
        lines.append(line)
        if text in line:
            return lines
    raise AssertionError(f"no {text!r} in {''.join(lines)}")


# ---------------------------------------------------------------- never hangs


@pytest.mark.parametrize("stop", ["SIGINT", "SIGTERM", "duration"])
def test_a_fifo_without_writer_never_holds_the_capture(tmp_path, stop):
    fifo = tmp_path / "gps.fifo"
    os.mkfifo(fifo)
    (tmp_path / "live.toml").write_text(manifest_text("tail:gps.fifo"))
    extra = ["--duration", "1"] if stop == "duration" else []
    proc = _cli("capture", "live.toml", "-o", "out.mcap", *extra, cwd=tmp_path)
    try:
        _wait_line(proc, "capturing 1 sources")   # the FIFO is open although no writer ever comes
        asked = time.monotonic()
        if stop != "duration":
            os.kill(proc.pid, getattr(signal, stop))
        code = proc.wait(timeout=WAIT_S)
        print(f"\n{stop}: exit {code} after {time.monotonic() - asked:.2f} s")
    finally:
        end_group(proc)
    assert code == 0
    assert (tmp_path / "out.mcap").is_file() and not part_path(tmp_path / "out.mcap").exists()
    assert gps_count(tmp_path / "out.mcap") == 0


def test_a_fifo_writer_that_comes_late_is_read(tmp_path):
    fifo = tmp_path / "gps.fifo"
    os.mkfifo(fifo)
    manifest = parse_manifest(manifest_text("tail:gps.fifo"), tmp_path / "live.toml")
    session = CaptureSession(manifest, tmp_path / "out.mcap", CaptureOptions(flush_s=0.1))
    data = b"".join(gga(i) for i in range(50))

    def write() -> None:
        time.sleep(0.3)
        with open(fifo, "wb") as f:  # blocks until the capture's read end is open: it is
            f.write(data)

    writer = threading.Thread(target=write)
    writer.start()
    deadline = time.monotonic() + WAIT_S
    session.run(lambda: (not writer.is_alive() and session.statuses()[0].bytes >= len(data))
                or time.monotonic() > deadline)
    writer.join()
    assert raw_by_connection(tmp_path / "out.mcap") == {1: data}
    assert gps_count(tmp_path / "out.mcap") == 50


# ---------------------------------------------------------------- a full disk


def _full_after(session: CaptureSession, budget: int) -> None:
    """The part file's writes fail with ENOSPC once `budget` more bytes went through."""
    stream = session.writer._stream
    real = stream.write
    left = [budget]

    def write(data) -> int:
        if left[0] < len(data):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        left[0] -= len(data)
        return real(data)

    stream.write = write  # type: ignore[method-assign]


@pytest.mark.parametrize("when", ["running", "closing"])
def test_a_full_disk_stops_with_one_line_and_keeps_the_part_file(tmp_path, when):
    log = tmp_path / "gps.log"
    data = b"".join(gga(i) for i in range(3000))
    log.write_bytes(data[: len(data) // 2])
    manifest = parse_manifest(manifest_text("tail:gps.log"), tmp_path / "live.toml")
    session = CaptureSession(manifest, tmp_path / "out.mcap", CaptureOptions(flush_s=0.05))
    turns = [0]

    def should_stop() -> bool:
        turns[0] += 1
        if turns[0] == 40:
            if when == "running":
                _full_after(session, 0)
                with open(log, "ab") as f:   # more data: its write fails
                    f.write(data[len(data) // 2:])
            else:
                _full_after(session, 0)     # the stop itself (decode, summary, rename) meets the full disk
                return True
        return turns[0] > 400

    with pytest.raises(CaptureStopped) as caught:
        session.run(should_stop)
    text = str(caught.value)
    assert "\n" not in text and "No space left on device" in text and "recover" in text
    part = part_path(tmp_path / "out.mcap")
    assert part.is_file() and not (tmp_path / "out.mcap").exists()
    report = recover(part, tmp_path / "fixed.mcap")
    kept = raw_by_connection(tmp_path / "fixed.mcap")
    # every byte archived before the disk filled is there: the first half of the log, whole
    assert kept[1][: len(data) // 2] == data[: len(data) // 2]
    assert report.messages > 0


def test_a_full_disk_at_the_cli_is_one_line_and_exit_1(tmp_path):
    # the child fills its disk through the same writer hook: a small program around the CLI
    (tmp_path / "gps.log").write_bytes(b"".join(gga(i) for i in range(200)))
    (tmp_path / "live.toml").write_text(manifest_text("tail:gps.log"))
    program = (
        "import errno, os, sys\n"
        "from formats import mcap_writer\n"
        "real = mcap_writer.ArchiveWriter.flush\n"
        "def flush(self):\n"
        "    if self.keep_on_error and self._chunk_indexes:\n"
        "        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))\n"
        "    real(self)\n"
        "mcap_writer.ArchiveWriter.flush = flush\n"
        "from replay.cli import main\n"
        "sys.exit(main(sys.argv[1:]))\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", program, "capture", "live.toml", "-o", "out.mcap",
                           "--flush-s", "0.1", "--duration", "5"], cwd=tmp_path, env=env, text=True,
                          capture_output=True, timeout=WAIT_S)
    assert done.returncode == 1
    errors = [line for line in done.stderr.splitlines() if "error" in line]
    assert len(errors) == 1 and "No space left on device" in errors[0] and "Traceback" not in done.stderr
    assert (tmp_path / "out.mcap.part").is_file()
    assert recover(tmp_path / "out.mcap.part", tmp_path / "fixed.mcap").messages > 0


# ---------------------------------------------------------------- containment


@pytest.mark.parametrize("source", ["tail:../outside.log", "tail:/etc/hostname", "tail:sub/../../outside.log"])
def test_a_tail_outside_the_manifest_folder_is_refused_unless_allowed(tmp_path, source):
    folder = tmp_path / "trial"
    (folder / "sub").mkdir(parents=True)
    (tmp_path / "outside.log").write_bytes(gga(0))
    manifest = parse_manifest(manifest_text(source), folder / "live.toml")
    with pytest.raises(ManifestError, match="outside the manifest's folder"):
        CaptureSession(manifest, folder / "out.mcap")
    assert not part_path(folder / "out.mcap").exists()
    session = CaptureSession(manifest, folder / "out.mcap", allow_outside=True)
    session.abandon()
    (folder / "live.toml").write_text(manifest_text(source))
    proc = _cli("capture", "live.toml", "-o", "cli.mcap", "--duration", "1", cwd=folder)
    _, err = proc.communicate(timeout=WAIT_S)
    assert proc.returncode == 1 and "--allow-outside" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_a_relative_tail_is_read_from_the_manifest_folder(tmp_path):
    folder = tmp_path / "trial"
    folder.mkdir()
    data = b"".join(gga(i) for i in range(20))
    (folder / "gps.log").write_bytes(data)
    manifest = parse_manifest(manifest_text("tail:gps.log"), folder / "live.toml")
    session = CaptureSession(manifest, tmp_path / "out.mcap")   # the working folder is elsewhere
    session.run(lambda: session.statuses()[0].bytes >= len(data))
    assert raw_by_connection(tmp_path / "out.mcap") == {1: data}


# ---------------------------------------------------------------- fair and complete


def test_two_hundred_clients_at_once_all_reach_the_archive(tmp_path):
    port = free_port()
    manifest = parse_manifest(manifest_text(f"tcp-listen://127.0.0.1:{port}"), tmp_path / "live.toml")
    session = CaptureSession(manifest, tmp_path / "out.mcap", CaptureOptions(flush_s=0.1))
    session.step(time.monotonic())   # listening
    sent: dict[bytes, bytes] = {}
    socks = []
    for _ in range(200):   # all connected before any sends: 200 clients at once
        socks.append(socket.create_connection(("127.0.0.1", port), timeout=5))
    for i, s in enumerate(socks):
        payload = gga(i) + gga(1000 + i)
        s.sendall(payload)
        sent[payload[:30]] = payload
    for s in socks:
        s.close()
    total = sum(map(len, sent.values()))
    deadline = time.monotonic() + WAIT_S
    session.run(lambda: session.statuses()[0].bytes >= total or time.monotonic() > deadline)
    streams = raw_by_connection(tmp_path / "out.mcap")
    assert len(streams) == 200
    assert {d[:30]: d for d in streams.values()} == sent   # each client's bytes whole, none spliced
    assert gps_count(tmp_path / "out.mcap") == 400


def test_a_stalled_client_does_not_hold_back_another(tmp_path):
    port = free_port()
    manifest = parse_manifest(manifest_text(f"tcp-listen://127.0.0.1:{port}"), tmp_path / "live.toml")
    decoded: list[int] = []
    session = CaptureSession(manifest, tmp_path / "out.mcap", CaptureOptions(flush_s=0.1),
                             listener=lambda log, outputs: decoded.extend(o.log_time_ns for o in outputs))
    session.step(time.monotonic())
    stalled = socket.create_connection(("127.0.0.1", port), timeout=5)
    stalled.sendall(gga(5000)[:20])   # half a line, then nothing while the other one sends
    logger = socket.create_connection(("127.0.0.1", port), timeout=5)
    data = b"".join(gga(i) for i in range(100))
    logger.sendall(data)
    deadline = time.monotonic() + WAIT_S
    while len(decoded) < 98 and time.monotonic() < deadline:   # the last epoch waits for a later one
        session.step(time.monotonic())
    # decoded while the stalled client still holds its connection and its half line
    assert len(decoded) >= 98 and stalled.fileno() >= 0
    stalled.close()
    logger.close()
    session.run(lambda: True)
    streams = raw_by_connection(tmp_path / "out.mcap")
    # connections are numbered as their first bytes come: either may be first
    assert set(streams) == {2, 3} and sorted(streams.values()) == sorted([gga(5000)[:20], data])
    assert gps_count(tmp_path / "out.mcap") == 100


def test_tail_keeps_up_with_a_fast_writer_and_drains_at_the_stop(tmp_path):
    log = tmp_path / "gps.log"
    line_block = b"".join(gga(i) for i in range(2000))
    data = line_block * (30_000_000 // len(line_block) + 1)
    log.write_bytes(b"")
    manifest = parse_manifest(manifest_text("tail:gps.log"), tmp_path / "live.toml")
    session = CaptureSession(manifest, tmp_path / "out.mcap", CaptureOptions(flush_s=0.5))
    session.step(time.monotonic())   # open
    with open(log, "ab") as f:
        f.write(data[: len(data) // 2])
    started = time.monotonic()
    turns = 0
    while session.statuses()[0].bytes < len(data) // 2:
        session.step(time.monotonic())
        turns += 1
    seconds = time.monotonic() - started
    print(f"\ntail: {len(data) // 2 / 1e6:.1f} MB read in {seconds:.2f} s "
          f"({len(data) / 2e6 / seconds:.1f} MB/s), {turns} turns")
    # a turn reads up to its budget: the half is read in as many turns as it has budgets, plus one
    assert turns <= len(data) // 2 // POLL_BUDGET + 1
    with open(log, "ab") as f:   # written just before the stop: read at the stop, not lost
        f.write(data[len(data) // 2:])
    session.run(lambda: True)
    assert raw_by_connection(tmp_path / "out.mcap") == {1: data}


def test_a_line_without_a_newline_is_dropped_in_linear_time_and_counted():
    table = converters()
    manifest = parse_manifest(manifest_text("tail:x"), Path("/tmp/live.toml"))
    log = manifest.logs()[0]
    dec = StreamDecoder(table[("gps", "nmea")], log_context(manifest, log), "gps", "nmea")
    dec.feed(gga(0), 1)
    piece = b"A" * 65536
    for _ in range(3 * MAX_LINE_BYTES // len(piece)):
        dec.feed(piece, 2)
        assert sum(len(p) for p in dec._partials.values()) <= MAX_LINE_BYTES
    dec.feed(b"AAAA\r\n" + gga(1) + gga(2), 3)
    items = dec.decode(final=True)
    rejects = [i for i in items if "without a newline" in getattr(i, "reason", "")]
    assert len(rejects) == 1
    assert len([i for i in items if getattr(i, "topic", "") == "/a/gps"]) == 3


def test_a_100_mb_line_costs_bounded_memory_at_the_cli(tmp_path):
    with open(tmp_path / "gps.log", "wb") as f:
        f.write(gga(0))
        block = b"B" * (1 << 20)
        for _ in range(100):
            f.write(block)
        f.write(b"\r\n" + gga(1) + gga(2))
    (tmp_path / "live.toml").write_text(manifest_text("tail:gps.log"))
    code, err, peak_kb = run_child("capture", str(tmp_path / "live.toml"), "-o", str(tmp_path / "out.mcap"),
                                   "--duration", "0.5")
    print(f"\n100 MB line: peak RSS {peak_kb / 1024:.0f} MB")
    assert code == 0, err
    assert err.count("without a newline") == 1 and "Traceback" not in err
    assert peak_kb < 400 * 1024
    with ArchiveReader(tmp_path / "out.mcap") as r:
        files = r.metadata_json("recording")["files"]
    assert files[0]["size"] == (tmp_path / "gps.log").stat().st_size   # read whole: drained at the stop
    assert files[0]["skipped"] >= 1 and files[0]["messages"] >= 3


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from([b"$GPGGA,1*00", b"", b" ", b"\x1c", b"\xa0x", b"\t$X", b"2016-10-12T08:00:01Z $A",
                                 b"[1476259201.5] $B", b"1476259201.250 $C", b"12 ab", b"\x85", b"\r", b"a\rb"]),
                max_size=12),
       st.sampled_from(["auto", "iso8601", "unix"]))
def test_the_one_pass_stamp_equals_the_line_by_line_one(lines, prefix):
    data = b"".join(line + b"\r\n" for line in lines)
    table = converters()
    manifest = parse_manifest(manifest_text("tail:x").replace('source =', f'prefix = "{prefix}"\nsource ='),
                              Path("/tmp/live.toml"))
    log = manifest.logs()[0]
    fast = StreamDecoder(table[("gps", "nmea")], log_context(manifest, log), "gps", "nmea")
    fast.feed(data, 1_476_259_200_000_000_000)
    expected = bytearray()
    stamp = stamp_prefix(1_476_259_200_000_000_000, prefix)
    for line in data.splitlines(keepends=True):
        text = line.decode("latin-1")
        if text.strip() and strip_prefix(text, prefix)[1] is None:
            expected += stamp
        expected += line
    assert bytes(fast._buf) == bytes(expected)


def test_garbage_after_the_last_record_is_settled_in_bounded_memory():
    # found by tests/fuzz/live.py: the epoch of the last output was held with everything after it, so a stream
    # of garbage lines after one record was kept whole and decoded again at every decode (quadratic)
    from recorders.capture.decoder import MAX_WARMUP
    table = converters()
    manifest = parse_manifest(manifest_text("tail:x"), Path("/tmp/live.toml"))
    log = manifest.logs()[0]
    dec = StreamDecoder(table[("gps", "nmea")], log_context(manifest, log), "gps", "nmea")
    dec.feed(gga(0) + gga(1), 1)
    items = dec.decode()
    garbage = b"$\r\n" * 20_000
    for k in range(8):   # 480 KB of lines that are no record
        dec.feed(garbage, 2 + k)
        while dec.pending:   # as the capture loop decodes: in slices, until nothing is pending
            items += dec.decode(budget=128 << 10)
        assert len(dec._buf) <= 2 * MAX_WARMUP + 4096
    items += dec.decode(final=True)
    assert len([i for i in items if getattr(i, "topic", "") == "/a/gps"]) == 2
    assert sum(1 for i in items if getattr(i, "reason", None)) >= 8 * 20_000


def test_a_backlog_given_up_by_the_live_decode_keeps_its_line_numbers_and_offsets():
    table = converters()
    manifest = parse_manifest(manifest_text("udp://127.0.0.1:1") + 'prefix = "none"\n', Path("/tmp/live.toml"))
    log = manifest.logs()[0]
    dec = StreamDecoder(table[("gps", "nmea")], log_context(manifest, log), "gps", "nmea")
    lines = [gga(i) for i in range(2000)]
    stream = b"".join(lines)
    dec.feed(stream, 1)
    skipped = dec.shed(10_000)
    assert 0 < dec.backlog <= 10_000 + len(lines[0]) and skipped == len(stream) - dec.backlog
    items = dec.decode(final=True)
    outputs = [i for i in items if getattr(i, "topic", "") == "/a/gps"]
    rejects = [i for i in items if getattr(i, "reason", "")]
    first = len(lines) - len(outputs)
    assert len(outputs) == len(lines) - skipped // len(lines[0]) >= 10_000 // len(lines[0])
    assert outputs[0].where.offset == skipped == sum(map(len, lines[:first]))   # offsets of the whole stream
    assert outputs[0].where.line == first + 1
    assert len(rejects) == 1 and rejects[0].reason.startswith(f"{skipped} bytes arrived faster")


def test_a_socket_faster_than_the_decoder_is_archived_whole_in_bounded_memory(tmp_path, monkeypatch):
    import recorders.capture.session as session_module
    monkeypatch.setattr(session_module, "MAX_BACKLOG", 20_000)
    port = free_port()
    manifest = parse_manifest(manifest_text(f"tcp-listen://127.0.0.1:{port}"), tmp_path / "live.toml")
    said: list[str] = []
    session = CaptureSession(manifest, tmp_path / "out.mcap", CaptureOptions(flush_s=0.1, decode_s=3600),
                             report=said.append)
    session.step(time.monotonic())   # listening
    payload = b"".join(gga(i) for i in range(4000))   # 300 KB, never decoded while it arrives
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall(payload)
    deadline = time.monotonic() + WAIT_S
    session.run(lambda: session.statuses()[0].bytes >= len(payload) or time.monotonic() > deadline)
    assert list(raw_by_connection(tmp_path / "out.mcap").values()) == [payload]   # every byte archived
    assert 0 < gps_count(tmp_path / "out.mcap") < 4000   # the decode gave up the oldest, not the newest
    assert sum("faster than it can be decoded live" in line for line in said) == 1
    assert session.statuses()[0].rejects >= 1
