"""Fuzz targets of live capture: hostile streams through the capture decoder and the real sources.

- capture/stream: a log's bytes (the sample trial's, damaged) mixed with garbage, NUL floods, lines of up to
  2.5 MB without a newline and floods of blank lines, fed in random pieces from several peers (some hanging
  up mid-line) into `StreamDecoder` and `record`'s `LogRecorder`, decoded with random budgets; each peer's
  unfinished line must stay under the decoder's cap.
- capture/udp, capture/tail, capture/tcp-listen: such streams through a `CaptureSession` on the real source
  (UDP datagrams on 127.0.0.1, a file grown, truncated or replaced while read, up to 300 tcp-listen clients at
  once, some closing mid-line and some stalled); every byte sent must be in the archive (each client's whole
  on its own connection) unless the file was truncated or replaced.
- capture/stalled: clients that connect and stall (half a line, a NUL flood, nothing) beside a logger whose
  lines must be decoded while they stall.
- capture/long-line: `auvreplay capture` in a child process on a file holding a 100 MB line without a newline
  (letters, NULs or garbage), its peak RSS (the child's VmHWM) and the time from the stop to its exit.

A case using over HANG_S of CPU (or not ending in twice that wall time) is a hang; any exception, a lost byte, or a stalled client holding back another is a failure.
"""

from __future__ import annotations

import contextlib
import functools
import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from pathlib import Path

from formats.mcap_reader import ArchiveReader
from recorders.capture.decoder import MAX_LINE_BYTES, StreamDecoder
from recorders.capture.session import CaptureOptions, CaptureSession
from recorders.manifest import LogSpec, Manifest, load_manifest, parse_manifest
from recorders.record import FileStats, LogRecorder, log_context
from recorders.registry import converters
from tests.fuzz.importers import HANG_S, Hang, _gga, bounded, byte_damage, cpu_seconds, peak_rss_mb

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "samples" / "lake_trial"
LONG_LINE = 100 << 20


# ---- hostile streams ----------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=1)
def stream_seeds() -> tuple[Manifest, list[tuple[LogSpec, bytes]]]:
    """The sample trial's manifest and the first 30 KB of each of leader1's logs (NMEA, PHINS, PD0, Micro-Modem)."""
    manifest = load_manifest(SAMPLE / "trial.toml")
    logs = [log for log in manifest.logs() if log.vehicle == "leader1"]
    return manifest, [(log, (SAMPLE / log.path).read_bytes()[:30_000]) for log in logs]


def hostile_piece(rng: random.Random, seed: bytes, big: bool = True) -> bytes:
    """One hostile run of bytes: the log damaged, garbage, a NUL flood, a long line, blank lines, stray prefixes;
    with `big`, one in ten floods and lines runs past the decoder's cap on a line (else at most 60 KB)."""
    big = big and rng.random() < 0.1
    kind = rng.random()
    if kind < 0.4:
        start = rng.randrange(len(seed))
        return byte_damage(seed[start:start + rng.randrange(1, 8000)], rng)
    if kind < 0.55:
        return rng.randbytes(rng.randrange(1, 50_000))
    if kind < 0.7:
        return bytes(rng.choice([rng.randrange(1, 5000), rng.randrange(1, MAX_LINE_BYTES * 3 if big else 60_000)]))
    if kind < 0.8:
        size = rng.randrange(1, MAX_LINE_BYTES * 5 // 2 if big else 60_000)
        return bytes([rng.choice(b"A$,*0[")]) * size + (b"\r\n" if rng.random() < 0.5 else b"")
    if kind < 0.9:
        return rng.choice([b"\n", b"\r\n", b"\r", b" \t\n", b"\x1c\n", b"\x85\n"]) * rng.randrange(1, 20_000)
    return rng.choice([b"[", b"1476259201.5 ", b"2016-10-12T08:00:01Z ", b"$GPGGA,", b"*", b"\xa3\x95", b"\x7f"]) * \
        rng.randrange(1, 200)


def _pieces(data: bytes, rng: random.Random) -> list[bytes]:
    out, pos = [], 0
    while pos < len(data):
        n = rng.choice([rng.randrange(1, 64), rng.randrange(1, 4096), rng.randrange(1, 1 << 17)])
        out.append(data[pos:pos + n])
        pos += n
    return out


class _Dropped:
    """A sink for `LogRecorder` that keeps nothing (the stream case checks the decoder, not an archive)."""

    def write(self, topic: str, message: object, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Drop the message."""


def stream_case(rng: random.Random) -> int:
    """One hostile stream through the decoder and a recorder; the bytes fed. AssertionError on a broken bound."""
    manifest, seeds = stream_seeds()
    log, seed = rng.choice(seeds)
    convert = converters()[(log.sensor, log.format)]
    decoder = StreamDecoder(convert, log_context(manifest, log), log.sensor, log.format)
    recorder = LogRecorder(_Dropped(), log, FileStats(log.path, log.vehicle, log.sensor, log.format), 0)
    peers = rng.randrange(1, 4)
    fed = 0
    t = 1_476_259_200 * 10**9
    for _ in range(rng.randrange(1, 6)):
        for piece in _pieces(hostile_piece(rng, seed), rng):
            peer = rng.randrange(peers)
            t += rng.randrange(0, 10**8)
            decoder.feed(piece, t, peer)
            fed += len(piece)
            assert all(len(p) <= MAX_LINE_BYTES for p in decoder._partials.values()), "an unfinished line past the cap"
            assert len(decoder._carry) <= MAX_LINE_BYTES, "a carried line past the cap"
            if rng.random() < 0.05:
                decoder.end_peer(peer)
            if rng.random() < 0.2:
                for item in decoder.decode(budget=rng.choice([None, 1 << 10, 128 << 10])):
                    recorder.add(item)
    for item in decoder.decode(final=True):
        recorder.add(item)
    recorder.finish()
    return fed


# ---- sessions on the real sources ---------------------------------------------------------------------------
def free_port() -> int:
    """A TCP/UDP port free on 127.0.0.1 now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _manifest(folder: Path, source: str) -> Manifest:
    text = ('[trial]\nname = "live"\ndate = "2016-10-12"\n[[vehicles]]\nname = "a"\nrole = "leader"\n'
            f'[[vehicles.logs]]\nsensor = "gps"\nformat = "nmea"\npath = "a/gps.log"\nsource = "{source}"\n')
    return parse_manifest(text, folder / "live.toml")


def _session(folder: Path, source: str) -> CaptureSession:
    (folder / "out.mcap").unlink(missing_ok=True)
    return CaptureSession(_manifest(folder, source), folder / "out.mcap", CaptureOptions(flush_s=0.05, decode_s=0.01),
                          replace=True)


def raw_streams(path: Path) -> dict[int, bytes]:
    """The archive's raw bytes by connection number."""
    out: dict[int, list[tuple[int, bytes]]] = {}
    with ArchiveReader(path) as r:
        for m in r.messages([t for t in r.summary().topics if t.startswith("/raw/")]):
            out.setdefault(m.message.connection, []).append((m.message.offset, m.message.data))
    return {c: b"".join(d for _, d in sorted(parts)) for c, parts in out.items()}


def _lines(rng: random.Random, n: int) -> bytes:
    return b"".join(_gga(rng.randrange(3600)) + b"\r\n" for _ in range(n))


def _small_piece(rng: random.Random) -> bytes:
    return hostile_piece(rng, _lines(rng, 40), big=False) if rng.random() < 0.7 else _lines(rng, rng.randrange(1, 30))


def _run_until(session: CaptureSession, total: int, started: float) -> None:
    session.run(lambda: session.statuses()[0].bytes >= total or time.monotonic() - started > HANG_S)


def udp_case(rng: random.Random, folder: Path) -> str:
    """Datagrams of hostile bytes, sent in bursts between turns of the loop; "" or what went wrong."""
    port = free_port()
    session = _session(folder, f"udp://127.0.0.1:{port}")
    started = time.monotonic()
    session.step(started)
    sent = []
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        for _ in range(rng.randrange(1, 6)):
            for _ in range(rng.randrange(1, 16)):
                datagram = _small_piece(rng)[:rng.choice([60_000, 1400, 1400, 80])]
                s.sendto(datagram, ("127.0.0.1", port))
                sent.append(datagram)
            session.step(time.monotonic())
    data = b"".join(sent)
    _run_until(session, len(data), started)
    got = raw_streams(folder / "out.mcap")
    return "" if b"".join(got.values()) == data else f"{len(data)} bytes sent, {sum(map(len, got.values()))} archived"


def tail_case(rng: random.Random, folder: Path) -> str:
    """A file grown in hostile pieces while read (and at times truncated, replaced or removed)."""
    log = folder / "gps.log"
    first = b"".join(_small_piece(rng) for _ in range(rng.randrange(0, 3)))
    log.write_bytes(first)
    session = _session(folder, "tail:gps.log")
    started = time.monotonic()
    session.step(started)
    written, disturbed = [first], False
    for _ in range(rng.randrange(1, 6)):
        event = rng.random()
        if event < 0.08:
            log.write_bytes(b"")
            disturbed = True
        elif event < 0.12:
            (folder / "new.log").write_bytes(_small_piece(rng))
            os.replace(folder / "new.log", log)
            disturbed = True
        elif event < 0.14:
            log.unlink()
            disturbed = True
        piece = _small_piece(rng)
        with open(log, "ab") as f:
            f.write(piece)
        written.append(piece)
        for _ in range(rng.randrange(0, 3)):
            session.step(time.monotonic())
    data = b"".join(written)
    if disturbed:   # what a truncated file loses is not compared: a few turns more, then the archive must read
        turns = [0]
        session.run(lambda: (turns.__setitem__(0, turns[0] + 1) or turns[0] > 20))
        raw_streams(folder / "out.mcap")
        return ""
    _run_until(session, len(data), started)
    got = raw_streams(folder / "out.mcap")
    return "" if got == ({1: data} if data else {}) else f"{len(data)} bytes written, {sum(map(len, got.values()))} archived"


def tcp_listen_case(rng: random.Random, folder: Path) -> str:
    """Up to 300 clients at once, each sending hostile bytes; some hang up mid-line, some stay silent."""
    port = free_port()
    session = _session(folder, f"tcp-listen://127.0.0.1:{port}")
    started = time.monotonic()
    session.step(started)
    socks = [socket.create_connection(("127.0.0.1", port), timeout=5)
             for _ in range(rng.choice([1, 2, rng.randrange(1, 50), rng.randrange(1, 300)]))]
    sent = []
    try:
        for s in socks:
            payload = _small_piece(rng)[:rng.choice([60_000, 2000])] if rng.random() < 0.9 else b""
            s.sendall(payload)
            sent.append(payload)
            if rng.random() < 0.5:
                s.close()
        total = sum(map(len, sent))
        _run_until(session, total, started)
    finally:
        for s in socks:
            s.close()
    got = sorted(raw_streams(folder / "out.mcap").values())
    want = sorted(p for p in sent if p)
    return "" if got == want else f"{len(want)} clients sent {total} bytes, {len(got)} archived {sum(map(len, got))}"


def stalled_case(rng: random.Random, folder: Path) -> str:
    """Stalled clients (half a line, a NUL flood, nothing) beside a logger: its lines decoded while they stall."""
    port = free_port()
    decoded: list[int] = []
    (folder / "out.mcap").unlink(missing_ok=True)
    session = CaptureSession(_manifest(folder, f"tcp-listen://127.0.0.1:{port}"), folder / "out.mcap",
                             CaptureOptions(flush_s=0.05, decode_s=0.01), replace=True,
                             listener=lambda log, outputs: decoded.extend(o.log_time_ns for o in outputs))
    started = time.monotonic()
    session.step(started)
    stalled = []
    for _ in range(rng.randrange(1, 6)):
        s = socket.create_connection(("127.0.0.1", port), timeout=5)
        s.sendall(rng.choice([b"", _gga(5000)[:rng.randrange(1, 60)], bytes(rng.randrange(1, 60_000)),
                              rng.randrange(256).to_bytes(1, "big") * rng.randrange(1, 30_000)]))
        stalled.append(s)
    logger = socket.create_connection(("127.0.0.1", port), timeout=5)
    n = rng.randrange(5, 200)
    logger.sendall(b"".join(_gga(i) + b"\r\n" for i in range(n)))
    try:
        while len(decoded) < n - 2 and time.monotonic() - started < HANG_S:   # the last epoch waits for a later one
            session.step(time.monotonic())
        held = len(decoded) < n - 2
    finally:
        for s in (*stalled, logger):
            s.close()
    session.run(lambda: True)
    return f"the logger's {n} lines held back: {len(decoded)} decoded while others stalled" if held else ""


SESSION_CASES: dict[str, Callable[[random.Random, Path], str]] = {
    "capture/udp": udp_case, "capture/tail": tail_case, "capture/tcp-listen": tcp_listen_case,
    "capture/stalled": stalled_case,
}


# ---- a 100 MB line, at the command line ---------------------------------------------------------------------
def long_line_case(rng: random.Random, folder: Path) -> tuple[str, float, float]:
    """`auvreplay capture` of a file with a 100 MB line without a newline; (problem, peak RSS MB, stop-to-exit s)."""
    from tests.hostile import _CHILD
    log = folder / "gps.log"
    fill = rng.choice(["letters", "nul", "garbage"])
    with open(log, "wb") as f:
        f.write(_lines(rng, rng.randrange(0, 20)))
        block = {"letters": b"B" * (1 << 20), "nul": bytes(1 << 20),
                 "garbage": rng.randbytes(1 << 20).replace(b"\n", b"\xff")}[fill]
        for _ in range(LONG_LINE >> 20):
            f.write(block)
        if rng.random() < 0.7:
            f.write(b"\r\n" + _lines(rng, rng.randrange(1, 20)))
    (folder / "live.toml").write_text(_manifest(folder, "tail:gps.log").text)
    (folder / "out.mcap").unlink(missing_ok=True)
    duration = 0.5
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-c", _CHILD, "capture", "live.toml", "-o", "out.mcap", "--duration",
                             str(duration)], cwd=folder, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    lines: list[str] = []
    try:
        assert proc.stderr is not None
        opened = None
        for line in proc.stderr:   # bounded: the child stops at --duration, or is ended below
            lines.append(line)
            if opened is None and "capturing" in line:
                opened = time.monotonic()
        code = proc.wait(timeout=HANG_S * 10)
        stop_to_exit = time.monotonic() - (opened or time.monotonic()) - duration
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        return f"{fill}: no exit", 0.0, HANG_S * 10
    err, _, peak = "".join(lines).rpartition("#VmHWM ")
    peak_mb = int(peak) / 1024 if peak.strip().isdigit() else 0.0
    if code != 0 or "Traceback" in err or err.count("without a newline") != 1:
        return f"{fill}: exit {code}: {err.strip()[-500:]}", peak_mb, stop_to_exit
    with ArchiveReader(folder / "out.mcap") as r:
        files = r.metadata_json("recording")["files"]
    if files[0]["size"] != log.stat().st_size:
        return f"{fill}: {files[0]['size']} of {log.stat().st_size} bytes archived", peak_mb, stop_to_exit
    return "", peak_mb, stop_to_exit


LIVE = ("capture/stream", *SESSION_CASES, "capture/long-line")
# cases per case of a cheap entry: a session opens sockets and an archive, a long line is a process and 100 MB
COST = {"capture/stream": 1, "capture/udp": 10, "capture/tail": 10, "capture/tcp-listen": 100,
        "capture/stalled": 20, "capture/long-line": 5000}
PEAK_LIMIT_MB = 400


def live_cases(name: str, n: int, base_seed: int = 0, folder: Path | None = None) -> dict:
    """Run n cases of one live entry; counts of cases, failures (exceptions, lost bytes), hangs, peak RSS (MB).

    The peak is this process's (VmHWM), and for capture/long-line each child's, a peak over PEAK_LIMIT_MB a
    failure. Cases are reproducible from (name, base_seed, case number).
    """
    own = folder is None
    folder = folder or Path(tempfile.mkdtemp(prefix="fuzz-live-", dir="/dev/shm" if os.path.isdir("/dev/shm") else None))
    counts: dict = {"cases": 0, "ok": 0, "exceptions": 0, "hangs": 0, "bytes": 0}
    examples: list[str] = []
    slowest = peak = 0.0

    def fail(kind: str, case: int, text: str) -> None:
        counts[kind] += 1
        if len(examples) < 3:
            examples.append(f"case {case}: {text}")

    for case in range(n):
        rng = random.Random(f"{name}/{base_seed}/{case}")
        counts["cases"] += 1
        started, cpu = time.monotonic(), cpu_seconds()
        problem, seconds = "", 0.0
        try:
            with bounded(HANG_S * 12 if name == "capture/long-line" else HANG_S * 2):
                if name == "capture/stream":
                    counts["bytes"] += stream_case(rng)
                elif name == "capture/long-line":
                    problem, child_peak, seconds = long_line_case(rng, folder)
                    peak = max(peak, child_peak)
                    if child_peak > PEAK_LIMIT_MB:
                        problem = problem or f"peak RSS {child_peak:.0f} MB"
                else:
                    problem = SESSION_CASES[name](rng, folder)
        except Hang:
            fail("hangs", case, f"no end after {time.monotonic() - started:.1f} s")
            continue
        except Exception:  # noqa: BLE001 - the count this fuzz exists for
            fail("exceptions", case, traceback.format_exc(limit=-4).strip())
            continue
        if name != "capture/long-line":
            seconds = cpu_seconds() - cpu
        slowest = max(slowest, seconds)
        if problem:
            fail("exceptions", case, problem)
        elif seconds > HANG_S:
            fail("hangs", case, f"took {seconds:.1f} s of CPU ({time.monotonic() - started:.1f} s wall)")
        else:
            counts["ok"] += 1
    if own:
        shutil.rmtree(folder, ignore_errors=True)
    counts["slowest_s"] = round(slowest, 2)
    counts["peak_mb"] = round(max(peak, peak_rss_mb()))
    counts["examples"] = examples
    return counts
