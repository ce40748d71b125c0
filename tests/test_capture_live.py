"""Capture end to end: the sample trial fed over UDP, TCP and ptys; kill -9 and recover; tail and tcp-listen.

Everything binds 127.0.0.1 only; every wait is bounded; the processes stop by themselves
(capture by SIGINT or SIGTERM, feed when its logs are sent). Feeds play the first seconds of the trial
at high rate to keep the whole file to seconds.

How capture and `record` are compared: the same bytes (the prefix of each log the feed sent,
which `unpack` must give back byte for byte) are recorded from files; every topic's messages
(content and log time) must be equal, and the diagnostics as many. Publish times are not
compared: a live line without a host prefix is stamped with its receive time, which becomes
its publish time (and its log time where the format has no clock; the sample's formats all do).
"""

from __future__ import annotations

import json
import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader
from rerun.chunk import RrdReader

from formats.mcap_reader import ArchiveReader
from formats.mcap_recover import recover
from recorders.attachments import unpack
from recorders.capture.session import CaptureOptions, CaptureSession, part_path
from recorders.feed import live_manifest, make_targets, play, segments
from recorders.manifest import load_manifest, parse_manifest
from recorders.record import record
from recorders.registry import converters
from replay.commands.info import describe
from replay.run.config import load_config
from replay.run.pipeline import replay_archive

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "samples" / "lake_trial" / "trial.toml"
MANIFEST = load_manifest(SAMPLE)
N_LOGS = len(MANIFEST.logs())
WAIT_S = 60.0


def _free_ports(n: int) -> int:
    """A base port with n free TCP and UDP ports after it on 127.0.0.1."""
    rng = random.Random(os.getpid())
    for _ in range(100):
        base = rng.randrange(20000, 60000 - n)
        socks = []
        try:
            for port in range(base, base + n):
                for kind in (socket.SOCK_STREAM, socket.SOCK_DGRAM):
                    s = socket.socket(socket.AF_INET, kind)
                    socks.append(s)
                    s.bind(("127.0.0.1", port))
        except OSError:
            continue
        finally:
            for s in socks:
                s.close()
        return base
    raise RuntimeError("no free ports")


class _Lines:
    """A child's stderr lines, read on a thread so that waits stay bounded."""

    def __init__(self, stream) -> None:
        self.lines: list[str] = []
        self._t = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._t.start()

    def _read(self, stream) -> None:
        for line in stream:
            self.lines.append(line)

    def wait_for(self, text: str, proc: subprocess.Popen) -> None:
        deadline = time.monotonic() + WAIT_S
        while not any(text in line for line in self.lines):
            assert proc.poll() is None, f"exited {proc.returncode}: {''.join(self.lines)}"
            assert time.monotonic() < deadline, f"no {text!r} in {''.join(self.lines)}"
            time.sleep(0.02)


def _cli(*args: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen([sys.executable, "-m", "replay.cli", *args], env=env, text=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def _fed_prefixes(seconds: float) -> dict[str, bytes]:
    """The bytes of each log that `feed --seconds` sends: its segments up to that time after the start."""
    table = converters()
    segs = {}
    for log in MANIFEST.logs():
        data = (MANIFEST.root / log.path).read_bytes()
        segs[log.path] = (data, segments(MANIFEST, log, data, table))
    first = min(s[0][0] for _, s in segs.values() if s and s[0][0] >= 0)
    end = first + round(seconds * 1e9)
    return {path: b"".join(data[a:b] for t, a, b in s if max(t, first) <= end) for path, (data, s) in segs.items()}


def _messages(path: Path) -> dict[str, list]:
    """Topic -> sorted (log time, serialized message); raw streams left out."""
    out: dict[str, list] = {}
    with ArchiveReader(path) as reader:
        for m in reader.messages():
            if not m.topic.startswith("/raw/"):
                out.setdefault(m.topic, []).append((m.log_time_ns, m.message.SerializeToString()))
    return {t: sorted(v) for t, v in out.items()}


def _reference(tmp: Path, prefixes: dict[str, bytes]) -> Path:
    ref = tmp / "ref"
    for name, data in prefixes.items():
        (ref / name).parent.mkdir(parents=True, exist_ok=True)
        (ref / name).write_bytes(data)
    shutil.copy(SAMPLE, ref / "trial.toml")
    record(load_manifest(ref / "trial.toml"), tmp / "ref.mcap", workers=1)
    return tmp / "ref.mcap"


SECONDS, RATE = 30.0, 30.0


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ref")
    prefixes = _fed_prefixes(SECONDS)
    return prefixes, _messages(_reference(tmp, prefixes))


# the feed listens (capture connects, tcp://) or connects (capture listens, tcp-listen://); SIGTERM stops as SIGINT
@pytest.mark.parametrize("to, stop", [("udp", signal.SIGINT), ("tcp-listen", signal.SIGTERM), ("tcp", signal.SIGINT),
                                      ("pty", signal.SIGINT)], ids=["udp", "tcp-sigterm", "tcp-into-listener", "pty"])
def test_fed_trial_captured_equals_record(tmp_path, reference, to, stop):
    prefixes, want = reference
    target = "pty" if to == "pty" else f"{to}://127.0.0.1:{_free_ports(N_LOGS)}"
    live, go, out = tmp_path / "live.toml", tmp_path / "go", tmp_path / "trial.mcap"
    feed = _cli("feed", str(SAMPLE), "--to", target, "--rate", str(RATE), "--seconds", str(SECONDS),
                "--manifest-out", str(live), "--start-after", str(go), "--hold-s", "30")
    feed_err = _Lines(feed.stderr)
    try:
        deadline = time.monotonic() + WAIT_S
        while not live.exists():
            assert feed.poll() is None and time.monotonic() < deadline, "".join(feed_err.lines)
            time.sleep(0.02)
        online = ["--results", str(tmp_path / "online.mcap"), "--rrd", str(tmp_path / "live.rrd"), *ONLINE_SET] \
            if to == "udp" else []  # one transport is enough for the online run and the live view
        cap = _cli("capture", str(live), "-o", str(out), "--flush-s", "0.2", *online)
        cap_err = _Lines(cap.stderr)
        try:
            cap_err.wait_for("capturing", cap)
            go.touch()
            feed_err.wait_for("sent ", feed)
            time.sleep(0.5)  # the last bytes in flight
            cap.send_signal(stop)
            assert cap.wait(timeout=WAIT_S) == 0, "".join(cap_err.lines)
        finally:
            if cap.poll() is None:
                cap.kill()
    finally:
        feed.send_signal(signal.SIGTERM)
        feed.wait(timeout=WAIT_S)
    assert out.exists() and not part_path(out).exists()
    got = _messages(out)
    assert sorted(got) == sorted(want)
    for topic in want:
        if topic == "/diagnostics":
            assert len(got[topic]) == len(want[topic])
        else:
            assert got[topic] == want[topic], topic
    result = unpack(out, tmp_path / "unpacked")
    assert not result.refused and not result.mismatched and not result.incomplete
    for name, data in prefixes.items():
        assert (tmp_path / "unpacked" / name).read_bytes() == data, name
    if to == "udp":
        _check_online(tmp_path, out)


ONLINE_SET = ["--set", "training_window_s=12", "--set", "anfis.epochs=4"]


def _check_online(tmp_path: Path, capture: Path) -> None:
    """The online run's metrics are those of `replay` of the capture; the live recording has the replay views."""
    online = json.loads((tmp_path / "online.metrics.json").read_text())
    offline = replay_archive(capture, load_config(None, ONLINE_SET[1::2]), tmp_path / "offline.mcap")
    assert online["methods"] == offline.metrics["methods"] and online["epochs"] == offline.metrics["epochs"] > 0
    reader = RrdReader(tmp_path / "live.rrd")
    paths = {chunk.entity_path for chunk in reader.stream().to_chunks()}
    rid = online["run_id"]
    assert {f"/{rid}/map/follower/gps/position", f"/{rid}/map/follower/ackf/position", f"/{rid}/events"} <= paths
    assert reader.blueprints()  # the complete replay views, laid out, at the end


class _Logged:
    """A feed target that notes the wall time and size of every send."""

    def __init__(self, target, log: list) -> None:
        self.target, self.log = target, log

    def send(self, data: bytes) -> None:
        self.target.send(data)
        self.log.append((time.time(), len(data)))

    def __getattr__(self, name):
        return getattr(self.target, name)


FLUSH_S, SLACK_S = 0.2, 1.0  # slack: a feed thread and a capture process sharing a loaded machine


def test_kill_9_then_recover_keeps_all_but_the_last_flush(tmp_path):
    base = _free_ports(N_LOGS)
    targets = make_targets(f"udp://127.0.0.1:{base}", N_LOGS)
    live = tmp_path / "live.toml"
    live.write_text(live_manifest(MANIFEST, targets))
    originals = {log.path: (MANIFEST.root / log.path).read_bytes() for log in MANIFEST.logs()}
    record(MANIFEST, tmp_path / "all.mcap", workers=1)
    everything = {(t, lt, b) for t, v in _messages(tmp_path / "all.mcap").items() for lt, b in v}
    rng = random.Random(17)
    try:
        for run, delay in enumerate(rng.uniform(0.6, 1.8) for _ in range(2)):
            out = tmp_path / f"run{run}.mcap"
            sends: list[list] = [[] for _ in targets]
            logged = [_Logged(t, s) for t, s in zip(targets, sends)]
            cap = _cli("capture", str(live), "-o", str(out), "--flush-s", str(FLUSH_S))
            err = _Lines(cap.stderr)
            stop = threading.Event()
            try:
                err.wait_for("capturing", cap)
                feeder = threading.Thread(target=play, args=(MANIFEST, logged, 20.0, 120.0, stop.is_set, 0.0))
                feeder.start()
                # the kill comes a random time after data flows (a loaded machine starts the feed late);
                # in the first run `info` also reads the part file while it grows
                _wait_growing(part_path(out))
                time.sleep(delay)
                killed_at = time.time()
                cap.send_signal(signal.SIGKILL)
                cap.wait(timeout=WAIT_S)
            finally:
                stop.set()
                if cap.poll() is None:
                    cap.kill()
            feeder.join(timeout=WAIT_S)
            fixed = tmp_path / f"fixed{run}.mcap"
            report = recover(part_path(out), fixed)
            info = describe(str(fixed))
            assert not info["problems"] and info["messages"] == report.messages > 0
            with open(fixed, "rb") as f:  # the independent reader: summary, indexes and every message
                reader = make_reader(f)
                assert reader.get_summary() is not None
                assert sum(1 for _ in reader.iter_messages()) == report.messages
            streams = _raw_streams(fixed)
            for i, log in enumerate(MANIFEST.logs()):
                settled = sum(n for t, n in sends[i] if t <= killed_at - FLUSH_S - SLACK_S)
                got = streams.get(log.path, b"")
                assert got == originals[log.path][:len(got)], log.path  # in order, nothing invented
                assert len(got) >= settled, (log.path, len(got), settled)
            decoded = {(t, lt, b) for t, v in _messages(fixed).items() if t != "/diagnostics" for lt, b in v}
            assert decoded and decoded <= everything
    finally:
        for t in targets:
            t.close()


def _wait_growing(part: Path) -> None:
    """Wait until `info` on the part file shows flushed raw messages (and says the file was recovered)."""
    deadline = time.monotonic() + WAIT_S
    while True:
        growing = describe(str(part))
        assert growing["recovered"]
        if growing["topics"].get("/raw/leader1/gps.log", {}).get("count", 0) > 0:
            return
        assert time.monotonic() < deadline, growing
        time.sleep(0.05)


def _raw_streams(path: Path) -> dict[str, bytes]:
    parts: dict[str, dict[int, bytes]] = {}
    with ArchiveReader(path) as reader:
        for m in reader.messages([t for t in reader.summary().topics if t.startswith("/raw/")]):
            parts.setdefault(m.message.stream, {})[m.message.offset] = m.message.data
    return {name: b"".join(d for _, d in sorted(p.items())) for name, p in parts.items()}


def test_tail_and_tcp_listen_with_a_reconnect(tmp_path):
    """A growing file and a TCP sender that hangs up once and comes back: both streams whole, decoded as record."""
    gps = (MANIFEST.root / "leader1/gps.log").read_bytes()[:20_000]
    ins = (MANIFEST.root / "leader1/ins.log").read_bytes()[:20_000]
    port = _free_ports(1)
    grow = tmp_path / "gps.log"
    text = f"""[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "leader1"\nrole = "leader"\n
[[vehicles.logs]]\nsensor = "gps"\nformat = "nmea"\npath = "leader1/gps.log"\nsource = "tail:{grow}"\n
[[vehicles.logs]]\nsensor = "ins"\nformat = "phins"\npath = "leader1/ins.log"\n
source = "tcp-listen://127.0.0.1:{port}"\n"""
    manifest = parse_manifest(text, tmp_path / "live.toml")
    notes: list[str] = []
    session = CaptureSession(manifest, tmp_path / "t.mcap", CaptureOptions(flush_s=0.1), report=notes.append)
    done = threading.Event()

    def produce() -> None:
        with open(grow, "wb") as f:
            for i in range(0, len(gps), 4000):
                f.write(gps[i:i + 4000])
                f.flush()
                time.sleep(0.02)
        half = len(ins) // 2
        for piece in (ins[:half], ins[half:]):  # two connections: the stream goes on where it stopped
            deadline = time.monotonic() + WAIT_S
            while True:
                try:
                    sock = socket.create_connection(("127.0.0.1", port), timeout=1.0)
                    break
                except OSError:
                    assert time.monotonic() < deadline
                    time.sleep(0.05)
            sock.sendall(piece)
            sock.close()
            time.sleep(0.3)
        done.set()

    producer = threading.Thread(target=produce)
    producer.start()
    stop_at = [None]

    def should_stop() -> bool:
        if done.is_set() and stop_at[0] is None:
            stop_at[0] = time.monotonic() + 0.5
        return (stop_at[0] is not None and time.monotonic() > stop_at[0]) \
            or time.monotonic() - session.started_s > WAIT_S

    summary = session.run(should_stop)
    producer.join(timeout=WAIT_S)
    assert _raw_streams(tmp_path / "t.mcap") == {"leader1/gps.log": gps, "leader1/ins.log": ins}
    # the listener is opened again after each hang-up: the first, after the first sender, after the second
    assert [s.opens for s in summary.sources] == [1, 3] and any("closed" in n for n in notes)
    ref_dir = tmp_path / "ref"
    (ref_dir / "leader1").mkdir(parents=True)
    (ref_dir / "leader1/gps.log").write_bytes(gps)
    (ref_dir / "leader1/ins.log").write_bytes(ins)
    (ref_dir / "m.toml").write_text(text.replace(f'source = "tail:{grow}"', "").replace(
        f'source = "tcp-listen://127.0.0.1:{port}"', ""))
    record(load_manifest(ref_dir / "m.toml"), tmp_path / "ref.mcap", workers=1)
    assert _messages(tmp_path / "t.mcap") == _messages(tmp_path / "ref.mcap")
    assert [(f.path, f.parsed, f.skipped, f.messages) for f in summary.recording.files] == \
        [(f["path"], f["parsed"], f["skipped"], f["messages"]) for f in
         ArchiveReader(tmp_path / "ref.mcap").metadata_json("recording")["files"]]
