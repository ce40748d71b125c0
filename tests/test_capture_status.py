"""Capture's status and warnings, and the live view's entities: small cases built in the test."""

from __future__ import annotations

import socket
import time

import numpy as np
from rerun.chunk import RrdReader

from formats import schemas as S
from recorders.capture.session import CaptureOptions, CaptureSession
from recorders.capture.status import SourceStatus, status_block
from recorders.manifest import parse_manifest
from replay.cli import main
from replay.views.live import LiveView, open_stream

T0 = 1_476_237_600 * 10**9


def _udp_port() -> int:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def test_a_quiet_source_is_warned_about_and_its_return_noted(tmp_path):
    port = _udp_port()
    text = f"""[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "a"\nrole = "leader"\n
[[vehicles.logs]]\nsensor = "gps"\nformat = "nmea"\nsource = "udp://127.0.0.1:{port}"\n"""
    notes: list[str] = []
    session = CaptureSession(parse_manifest(text, tmp_path / "m.toml"), tmp_path / "q.mcap",
                             CaptureOptions(flush_s=0.05, quiet_s=0.2), report=notes.append)
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    line = b"$GPGGA,020000.00,4542.135726,N,12635.845169,E,1,08,0.9,117.87,M,-8.00,M,,*75\n"
    sent = [False]

    def should_stop() -> bool:
        waited = time.monotonic() - session.started_s
        if any("no data" in n for n in notes) and not sent[0]:
            sender.sendto(line, ("127.0.0.1", port))
            sent[0] = True
        return any("data again" in n for n in notes) or waited > 20

    summary = session.run(should_stop)
    sender.close()
    assert [n for n in notes if "no data" in n or "data again" in n] == [
        f"warning: a/gps.nmea: no data from udp://127.0.0.1:{port} for " + notes[1].rsplit("for ", 1)[1],
        "a/gps.nmea: data again"]
    assert summary.sources[0].bytes == len(line) and summary.recording.files[0].messages == 2  # fix + status


def test_status_lines_line_up():
    now = 100.0
    rows = [SourceStatus("leader1/gps.log", "udp://x:1", bytes=2048, records=12, rejects=1, last_record_s=99.5,
                         state="streaming"),
            SourceStatus("b/usbl.log", "tcp://x:2", state="retrying", error="refused", quiet=True)]
    lines = status_block(rows, now)
    assert lines[0].split() == ["leader1/gps.log", "2.0", "KiB", "12", "rec", "1", "rej", "0.5s", "ago", "streaming"]
    assert lines[1].endswith("retrying QUIET (refused)") and lines[1].index("B ") == lines[0].index("B ")


def test_live_view_sends_positions_and_estimates_on_the_time_timeline(tmp_path):
    path = tmp_path / "live.rrd"
    view = LiveView(open_stream("run-x", rrd=str(path)), "run-x").attach(T0)
    fixes = [S.location_fix(T0 + k * 10**9, "leader1", 45.7 + k * 1e-5, 126.6, 0.0) for k in range(5)]
    for k, fix in enumerate(fixes):
        view.recorded("/leader1/gps", T0 + k * 10**9, fix)
    view.estimates("follower", 2.5, {"ackf": (np.radians(45.71), np.radians(126.61), 1.0, 0.0, 1.0)})
    view.event(3.0, "warning", "training finished")
    view.finish(None)
    temporal: dict[str, list] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        if not chunk.is_static:
            temporal.setdefault(chunk.entity_path, []).append(chunk.to_record_batch())
    gps = temporal["/run-x/map/leader1/gps/position"]
    times = np.concatenate([b.column("time").cast("int64").to_numpy() for b in gps])
    assert list(times) == [T0 + k * 10**9 for k in range(5)]
    est = temporal["/run-x/map/follower/ackf/position"][0]
    assert est.column("time").cast("int64").to_pylist() == [T0 + 2_500_000_000]
    assert "/run-x/events" in temporal


def test_duration_stops_cleanly_and_renames(tmp_path):
    text = f"""[trial]\nname = "t"\n[[vehicles]]\nname = "a"\nrole = "leader"\n
[[vehicles.logs]]\nsensor = "gps"\nformat = "nmea"\nsource = "udp://127.0.0.1:{_udp_port()}"\n"""
    out = tmp_path / "d.mcap"
    session = CaptureSession(parse_manifest(text, tmp_path / "m.toml"), out, CaptureOptions(duration_s=0.3))
    assert session.part.exists() and not out.exists()
    started = time.monotonic()
    session.run(lambda: time.monotonic() - started > 20)
    assert out.exists() and not session.part.exists()


def test_bad_manifests_are_one_line_errors(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('[trial]\nname = "t"\n[[vehicles]]\nname = "a"\nrole = "leader"\n[[vehicles.logs]]\n'
                   'sensor = "gps"\nformat = "nmea"\nsource = "bogus://1"\n')
    assert main(["capture", str(bad), "-o", str(tmp_path / "x.mcap")]) == 1
    assert main(["feed", str(tmp_path / "missing.toml"), "--to", "pty"]) == 1
    assert main(["recover", str(bad), "-o", str(tmp_path / "y.mcap")]) == 1
    err = capsys.readouterr().err.splitlines()
    assert [line.split(":")[0] for line in err] == ["auvreplay capture", "auvreplay feed", "auvreplay recover"]
    assert "unknown source kind 'bogus'" in err[0] and "not an MCAP file" in err[2]
    assert not (tmp_path / "x.mcap.part").exists()
