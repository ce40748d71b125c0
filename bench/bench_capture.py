"""Live capture: throughput as a multiple of the sample trial's data rate on one core, and latency.

Throughput: `auvreplay feed` (another process) plays the whole sample trial
over UDP on 127.0.0.1 at --rate times real time into a `CaptureSession` in
this process (raw bytes and decoded messages into a crash-safe archive,
chunks flushed and fsync'd every second). The figure is the trial's
duration over the CPU seconds the capture used (this process, one thread):
how many times the trial's data rate one core sustains. The run also checks
that nothing was lost (every byte received, as many messages as `record`).

Latency: from a line received to its position sent to Rerun by the live
view (`replay.views.live.LiveView`, into an .rrd file, batches at most every
0.1 s as in `capture --view`), over the lines the capture stamps with their
receive time (the NMEA GPS and PHINS INS logs: the others carry the
logger's own 2016 prefix or are binary); also to the decoded message alone. A GPS epoch or a PHINS burst is
complete only when the next one starts, so the latency includes one epoch
of the stream at the feed rate: at 1x that is about a second, by design of
the formats, at 20x a twentieth of it. Median and p95 are printed per rate.

Tail: a file of --tail-mb MB of GGA sentences, written whole before the
capture starts (a writer faster than any reader), captured through `tail:`
until every byte is archived and decoded: wall and CPU MB/s, bytes lost.

UDP burst: another process sends --udp-mbps MB/s of GGA sentences for
--udp-seconds in 1,400-byte datagrams to one `udp://` source: bytes sent
against bytes archived, and how long after the first datagram its bytes were
in the part file (read back with `ArchiveReader`, as `recover` would).

Run: .venv/bin/python bench/bench_capture.py [--rate 400] [--latency-rates 1,20] [--latency-seconds 10]
     [--tail-mb 30] [--udp-mbps 7] [--udp-seconds 5]
"""

from __future__ import annotations

import argparse
import math
import os
import random
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.common import print_table
from formats.mcap_reader import ArchiveReader
from recorders.capture.session import CaptureOptions, CaptureSession
from recorders.feed import live_manifest, make_targets
from recorders.manifest import load_manifest, parse_manifest
from recorders.record import record
from replay.views.live import LiveView, open_stream

SAMPLE = ROOT / "samples" / "lake_trial" / "trial.toml"


def _free_ports(n: int) -> int:
    rng = random.Random(os.getpid())
    for _ in range(100):
        base = rng.randrange(20000, 60000 - n)
        socks = []
        try:
            for port in range(base, base + n):
                s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                socks.append(s)
                s.bind(("127.0.0.1", port))
        except OSError:
            continue
        finally:
            for s in socks:
                s.close()
        return base
    raise RuntimeError("no free ports")


def _capture(tmp: Path, rate: float, seconds: float | None, listener=None) -> tuple[CaptureSession, float, float]:
    """Capture the sample fed at `rate`; returns the session, its CPU seconds and wall seconds."""
    manifest = load_manifest(SAMPLE)
    base = _free_ports(len(manifest.logs()))
    targets = make_targets(f"udp://127.0.0.1:{base}", len(manifest.logs()))
    text = live_manifest(manifest, targets)
    for t in targets:
        t.close()
    live = parse_manifest(text, tmp / "live.toml")
    out = tmp / f"capture-{rate:g}.mcap"
    session = CaptureSession(live, out, CaptureOptions(flush_s=1.0), listener=listener)
    go = tmp / f"go-{rate:g}"
    cmd = [sys.executable, "-m", "replay.cli", "feed", str(SAMPLE), "--to", f"udp://127.0.0.1:{base}",
           "--rate", str(rate), "--start-after", str(go), "--hold-s", "0"]
    if seconds is not None:
        cmd += ["--seconds", str(seconds)]
    feed = subprocess.Popen(cmd, env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    time.sleep(0.2)
    go.touch()
    cpu0, wall0 = time.thread_time(), time.monotonic()
    last_bytes, quiet_since = -1, time.monotonic()

    def should_stop() -> bool:
        nonlocal last_bytes, quiet_since
        total = sum(s.bytes for s in session.statuses())
        now = time.monotonic()
        if total != last_bytes:
            last_bytes, quiet_since = total, now
        return feed.poll() is not None and now - quiet_since > 0.5

    session.run(should_stop)
    cpu, wall = time.thread_time() - cpu0, time.monotonic() - wall0
    feed.wait(timeout=60)
    return session, cpu, wall


def throughput(tmp: Path, rate: float) -> None:
    manifest = load_manifest(SAMPLE)
    sizes = {log.path: (manifest.root / log.path).stat().st_size for log in manifest.logs()}
    record(manifest, tmp / "ref.mcap", workers=1)
    with ArchiveReader(tmp / "ref.mcap") as r:
        want = r.summary()
        assert want.start_ns is not None and want.end_ns is not None
        trial_s = (want.end_ns - want.start_ns) / 1e9
        want_messages = want.message_count
    session, cpu, wall = _capture(tmp, rate, None)
    got_bytes = {s.name: s.bytes for s in session.statuses()}
    with ArchiveReader(session.output) as r:
        got = r.summary()
        decoded = sum(v["count"] for t, v in got.topics.items() if not t.startswith("/raw/"))
    lost = sum(sizes.values()) - sum(got_bytes.values())
    rows = [[f"capture, fed at {rate:g}x over UDP", f"{cpu:.2f}", f"{trial_s / cpu:.0f}x", f"{wall:.2f}",
             sum(got_bytes.values()), lost, f"{decoded}/{want_messages}"]]
    print_table(f"capture throughput: the sample trial ({trial_s:.0f} s, {sum(sizes.values()) / 1e6:.2f} MB, "
                f"{sum(sizes.values()) / trial_s / 1e3:.1f} kB/s) on one core (goal >= 100x)",
                ["run", "CPU s", "trial s / CPU s", "wall s", "bytes in", "bytes lost", "messages / record's"],
                rows)


def _gga_lines(n: int) -> bytes:
    """n GGA sentences a second apart (times of day wrap at 24 h), with their checksums."""
    out = []
    for i in range(n):
        h, rest = divmod(i % 86400, 3600)
        body = (f"GPGGA,{h:02d}{rest // 60:02d}{rest % 60:02d}.00,4542.{i % 10000:04d},N,12636.0000,E,1,08,0.9,"
                "10.0,M,0.0,M,,")
        checksum = 0
        for c in body.encode():
            checksum ^= c
        out.append(f"${body}*{checksum:02X}\r\n")
    return "".join(out).encode()


def tail(tmp: Path, megabytes: float) -> None:
    one = len(_gga_lines(1))
    data = _gga_lines(int(megabytes * 1e6 / one))
    (tmp / "a").mkdir(exist_ok=True)
    (tmp / "a" / "gps.log").write_bytes(data)
    manifest = parse_manifest('[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "a"\n'
                              'role = "leader"\n[[vehicles.logs]]\nsensor = "gps"\nformat = "nmea"\n'
                              'path = "a/gps.log"\nsource = "tail:a/gps.log"\n', tmp / "live.toml")
    session = CaptureSession(manifest, tmp / "tail.mcap", CaptureOptions(flush_s=1.0))
    cpu0, wall0 = time.thread_time(), time.monotonic()
    read_s: list[float] = []

    def done() -> bool:
        if not read_s and session.statuses()[0].bytes >= len(data):
            read_s.append(time.monotonic() - wall0)
        return bool(read_s) and not session.logs[0].decoder.pending

    session.run(done)
    cpu, wall = time.thread_time() - cpu0, time.monotonic() - wall0
    st = session.statuses()[0]
    mb = len(data) / 1e6
    print_table(f"capture through tail: a {mb:.1f} MB file of GGA sentences written before the capture starts",
                ["run", "MB", "read+archived wall s", "all decoded wall s", "wall MB/s", "CPU s", "CPU MB/s",
                 "bytes lost", "records"],
                [["tail", f"{mb:.1f}", f"{read_s[0]:.2f}", f"{wall:.2f}", f"{mb / wall:.1f}", f"{cpu:.2f}",
                  f"{mb / cpu:.1f}", len(data) - st.bytes, st.records]])


SENDER = """
import socket, sys, time
port, mbps, seconds, path = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
data = open(path, "rb").read()
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
step, sent, t0 = 1400, 0, time.monotonic()
print(time.time_ns(), flush=True)
while sent < len(data):
    ahead = sent - (time.monotonic() - t0) * mbps * 1e6      # paced: never more than the rate asks
    if ahead > 0:
        time.sleep(min(ahead / (mbps * 1e6), 0.01))
        continue
    s.sendto(data[sent:sent + step], ("127.0.0.1", port))
    sent += step
print(time.monotonic() - t0, flush=True)
"""


def udp_burst(tmp: Path, mbps: float, seconds: float) -> None:
    one = len(_gga_lines(1))
    data = _gga_lines(int(mbps * seconds * 1e6 / one))
    (tmp / "burst.bin").write_bytes(data)
    port = _free_ports(1)
    manifest = parse_manifest('[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "a"\n'
                              'role = "leader"\n[[vehicles.logs]]\nsensor = "gps"\nformat = "nmea"\n'
                              f'source = "udp://127.0.0.1:{port}"\n', tmp / "burst.toml")
    out = tmp / "burst.mcap"
    session = CaptureSession(manifest, out, CaptureOptions(flush_s=1.0))
    session.step(time.monotonic())    # the socket bound before the first datagram is sent
    sender = subprocess.Popen([sys.executable, "-c", SENDER, str(port), str(mbps), str(seconds),
                               str(tmp / "burst.bin")], stdout=subprocess.PIPE, text=True)
    assert sender.stdout is not None
    first_ns = int(sender.stdout.readline())
    seen: list[float] = []

    def look() -> None:    # in its own thread: reading the part file must not hold up the capture's reads
        while not seen and sender_end[0] == math.inf:
            try:
                with ArchiveReader(session.part) as r:
                    if any(t.startswith("/raw/") and v["count"] for t, v in r.summary().topics.items()):
                        seen.append((time.time_ns() - first_ns) / 1e9)
            except Exception:  # noqa: BLE001 - no part file yet, or one mid-write: looked at again shortly
                pass
            time.sleep(0.05)

    sender_end = [math.inf]

    def stop() -> bool:
        if sender.poll() is None:
            return False
        if sender_end[0] == math.inf:
            sender_end[0] = time.monotonic()
        return session.statuses()[0].bytes >= len(data) or time.monotonic() - sender_end[0] > 2.0

    looker = threading.Thread(target=look, daemon=True)
    looker.start()
    session.run(stop)
    looker.join(timeout=5)
    send_s = float(sender.stdout.readline() or "nan")
    got = session.statuses()[0].bytes
    print_table(f"capture of a UDP burst: {len(data) / 1e6:.1f} MB of GGA sentences at {mbps:g} MB/s asked",
                ["run", "MB sent", "send wall s", "MB/s sent", "bytes archived", "bytes lost",
                 "first data in the part file"],
                [["udp", f"{len(data) / 1e6:.1f}", f"{send_s:.2f}", f"{len(data) / 1e6 / send_s:.1f}", got,
                  len(data) - got, f"{seen[0]:.2f} s" if seen else "not seen"]])


def latency(tmp: Path, rates: list[float], seconds: float) -> None:
    rows = []
    for rate in rates:
        lat: list[float] = []
        view = LiveView(open_stream(f"bench-{rate:g}", rrd=str(tmp / f"live-{rate:g}.rrd")), f"bench-{rate:g}",
                        measure=True)

        def listen(log, outputs, lat=lat, view=view) -> None:
            now = time.time_ns()
            if log.format not in ("nmea", "phins"):  # only these are stamped with their receive time
                return
            for o in outputs:
                if o.where is not None and o.where.host_time_ns is not None:
                    lat.append((now - o.where.host_time_ns) / 1e6)
                    view.recorded(o.topic, o.log_time_ns, o.message, o.where.host_time_ns)
            view.flush()

        _capture(tmp, rate, seconds * rate, listen)
        view.finish(None)
        for what, values in (("decoded", lat), ("sent to Rerun", view.latencies_ms)):
            q = statistics.quantiles(values, n=20)
            rows.append([f"{rate:g}x", what, len(values), f"{statistics.median(values):.1f}", f"{q[18]:.1f}",
                         f"{1000 / rate:.0f}"])
    print_table("capture latency: line received -> decoded, -> position sent to Rerun by the live view (ms)",
                ["feed rate", "to", "messages", "median ms", "p95 ms", "one 1 Hz epoch at this rate, ms"], rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rate", type=float, default=400.0)
    parser.add_argument("--latency-rates", default="1,20")
    parser.add_argument("--latency-seconds", type=float, default=8.0, help="wall seconds per latency run")
    parser.add_argument("--tail-mb", type=float, default=30.0, help="size of the file captured through tail:")
    parser.add_argument("--udp-mbps", type=float, default=7.0, help="rate of the UDP burst (MB/s)")
    parser.add_argument("--udp-seconds", type=float, default=5.0, help="length of the UDP burst (s)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        throughput(Path(tmp), args.rate)
        tail(Path(tmp), args.tail_mb)
        udp_burst(Path(tmp), args.udp_mbps, args.udp_seconds)
        latency(Path(tmp), [float(r) for r in args.latency_rates.split(",")], args.latency_seconds)


if __name__ == "__main__":
    main()
