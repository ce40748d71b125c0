"""Issue 14, values: number text that parses but is no measurement is a counted Reject with its reason;
no converter raises on any number text; ranges <= 0 or beyond max_range_m are refused at record time and
the replay says so; a log of garbage costs bounded memory and bounded diagnostics."""

from __future__ import annotations

import math
import shutil
from datetime import date
from pathlib import Path

import pytest

from formats.mcap_reader import ArchiveReader
from formats.nmea.framing import nmea_checksum
from formats.records import Reject
from formats.waterlinked import crc8
from recorders.base import LogContext
from recorders.manifest import load_manifest
from recorders.record import DIAGNOSTICS_PER_KIND, record
from recorders.registry import converters
from recorders.value_checks import ValueChecks
from replay.cli import main
from tests.hostile import run_child

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "samples" / "lake_trial"
CTX = LogContext(vehicle="follower", trial_date=date(2016, 10, 12), address_book={1: "leader1", 3: "follower"})
BIG = "9" * 400


def nmea(body: str) -> str:
    return f"${body}*{nmea_checksum(body):02X}\r\n"


def items(sensor: str, fmt: str, data: bytes, ctx: LogContext = CTX) -> list:
    return list(converters()[(sensor, fmt)](data, ctx))


def refused(item) -> bool:
    """A Reject from the converter, or an Output the record-time checks refuse."""
    return isinstance(item, Reject) or ValueChecks().problem(item.message, item.log_time_ns) is not None


def test_water_linked_huge_numbers_are_rejects():
    def line(value: str, where: str = "status") -> bytes:
        fields = {"time_of_validity": "1476237600000000", "status": "0", "vx": "0.1", where: value}
        return ('2016-10-12T02:00:00Z {"type":"velocity","vy":0.0,"vz":0.0,"velocity_valid":true,"altitude":2.0,'
                '"fom":0.01,' + ",".join(f'"{k}":{v}' for k, v in fields.items()) + "}\r\n").encode()
    for value in ("1e400", BIG, "-" + BIG):
        for where in ("status", "time_of_validity", "vx"):
            (got,) = items("dvl", "waterlinked", line(value, where))
            # a huge status is only a status word; a time of validity that is none falls back to the host time
            assert refused(got) or (where != "vx" and got.log_time_ns == 1476237600 * 10**9), (value, where, got)
    body = f"wrz,0.1,0.0,0.0,y,2.0,0.01,1e-07;0;1.4;0;1.2;0;0.2;0;1e+09,{BIG},14,123.00,1"
    got = items("dvl", "waterlinked", f"{body}*{crc8(body.encode()):02x}\r\n".encode())
    assert got and all(map(refused, got)), got


@pytest.mark.parametrize("sensor", ["usbl", "modem"])
def test_evologics_400_digit_address_and_times_are_rejects(sensor):
    good = ("2016-10-12T02:00:03.263140Z USBLLONG,603.263140,603.243140,3,-1220.8199,-896.3857,0.0000,"
            "-1220.8199,-896.3857,0.0000,0.0000,0.0000,0.0000,1043791,-50,100,0.3000\r\n")
    for bad in (good.replace(",3,-1220", f",{BIG},-1220"), good.replace("1043791", BIG),
                good.replace("1043791", "1e400")):
        got = items(sensor, "evologics", (good + bad).encode())
        assert len(got) == 2 and sum(map(refused, got)) == 1, got  # the good line kept, the bad one refused


def _trial(tmp_path: Path, logs: dict[str, tuple[str, str, bytes, str]]) -> Path:
    """A one-follower manifest with these logs: name -> (sensor, format, bytes, extra TOML)."""
    text = '[trial]\nname = "v"\ndate = "2016-10-12"\n\n[[vehicles]]\nname = "leader1"\nrole = "leader"\n' \
           'modem_address = 1\n\n[[vehicles]]\nname = "follower"\nrole = "follower"\nmodem_address = 3\n'
    for name, (sensor, fmt, data, extra) in logs.items():
        (tmp_path / name).write_bytes(data)
        text += f'\n[[vehicles.logs]]\nsensor = "{sensor}"\nformat = "{fmt}"\npath = "{name}"\n{extra}\n'
    (tmp_path / "trial.toml").write_text(text)
    return tmp_path / "trial.toml"


def _fields_finite(message) -> bool:
    return all(math.isfinite(getattr(message, f.name)) or math.isnan(getattr(message, f.name))
               for f in message.DESCRIPTOR.fields if f.type == f.TYPE_DOUBLE and not f.is_repeated)


def test_nan_inf_1e400_under_valid_checksums_are_counted_rejects(tmp_path):
    gps = (nmea("GPGGA,020000.00,4542.135726,N,12635.845169,E,1,08,0.9,117.87,M,-8.00,M,,")
           + nmea("GPGST,020000.00,1.800,,,,1.273,1.273,3.000")
           + nmea("GPGGA,020001.00,4542.135726,N,12635.845169,E,1,08,0.9,117.87,M,-8.00,M,,")
           + nmea("GPGST,020001.00,1.800,,,,-inf,1.273,3.000")
           + nmea("GPRMC,020002.00,A,4542.135726,N,12635.845169,E,-inf,90.41,121016,,,A")
           + nmea("GPGGA,020003.00,nan,N,12635.845169,E,1,08,0.9,117.87,M,-8.00,M,,")
           + nmea("GPGGA,020004.00,4542.135726,N,12635.845169,E,1,08,1e400,117.87,M,-8.00,M,,"))
    ins = (nmea("PIXSE,POSITI,45.70224993,126.59742855,-1.500") + nmea("PIXSE,TIME__,020000.000000")
           + nmea("PIXSE,POSITI,NaN,126.59742855,-1.500") + nmea("PIXSE,TIME__,020001.000000")
           + nmea("PIXSE,POSITI,45.70224993,126.59742855,inf") + nmea("PIXSE,TIME__,020002.000000"))
    manifest = _trial(tmp_path, {"gps.log": ("gps", "nmea", gps.encode(), ""),
                                 "ins.log": ("ins", "phins", ins.encode(), "")})
    summary = record(load_manifest(manifest), tmp_path / "v.mcap")
    stats = {f.path: f for f in summary.files}
    # the decoders refuse the text (formats.numbers): rejects with their reason, before any record-time check
    assert stats["gps.log"].skipped == 4 and stats["ins.log"].skipped == 2
    assert stats["gps.log"].out_of_range == stats["ins.log"].out_of_range == 0
    with ArchiveReader(tmp_path / "v.mcap") as r:
        msgs = list(r.messages())
    data = [m for m in msgs if m.topic != "/diagnostics"]
    assert data and all(_fields_finite(m.message) for m in data)
    assert all(math.isfinite(v) or math.isnan(v) for m in data if m.topic.endswith("/gps")
               for v in m.message.position_covariance)
    reasons = " | ".join(m.message.message for m in msgs if m.topic == "/diagnostics")
    for words in ("bad GST sentence: field is not finite: '-inf'",
                  "bad RMC sentence: field is not finite: '-inf'", "bad GGA sentence: angle 'nan'",
                  "bad GGA sentence: field is not finite: '1e400'",
                  "bad PIXSE POSITI sentence: field is not finite: 'NaN'",
                  "bad PIXSE POSITI sentence: field is not finite: 'inf'"):
        assert words in reasons, reasons


def test_impossible_ranges_are_refused_at_record_time_and_the_replay_says_so(tmp_path, capsys):
    trial = tmp_path / "trial"
    shutil.copytree(SAMPLE, trial)
    bad = b"t,range,from\n" + b"".join(b"%d,%s,leader1\n" % (1476237800 + k, v) for k, v in
                                       enumerate([b"0", b"-5", b"nan", b"inf", b"1e12", b"25000"]))
    (trial / "follower" / "bad_ranges.csv").write_bytes(bad)
    text = (trial / "trial.toml").read_text().replace(
        'name = "follower"\nrole = "follower"', 'name = "follower"\nrole = "follower"\n\n[[vehicles.logs]]\n'
        'sensor = "modem"\nformat = "csv"\npath = "follower/bad_ranges.csv"\n'
        'columns = { time = "t", range_m = "range", source = "from" }\n', 1)
    assert "bad_ranges.csv" in text
    (trial / "trial.toml").write_text(text)
    out = tmp_path / "t.mcap"
    summary = record(load_manifest(trial / "trial.toml"), out)
    (f,) = [f for f in summary.files if f.path.endswith("bad_ranges.csv")]
    # "nan" and "inf" are no numbers: the CSV decoder refuses them (formats.numbers); 0, -5, 1e12 and 25 km are
    # numbers, and impossible ranges: refused at record time
    assert (f.parsed, f.skipped, f.bad_ranges) == (0, 6, 4)
    with ArchiveReader(out) as r:
        reasons = [m.message.message for m in r.messages(["/diagnostics"]) if "bad_ranges" in m.message.message]
    assert sum("range_m is not finite" in x for x in reasons) == 2, reasons
    rc = main(["replay", str(out), "--set", "methods=dead_reckoning,ckf", "--window", "0", "700",
               "-o", str(tmp_path / "r.mcap")])
    err = capsys.readouterr().err
    assert rc == 0 and "record time: 4 ranges refused" in err, err


def test_a_log_of_bad_checksums_costs_bounded_memory_and_diagnostics(tmp_path):
    line = nmea("GPGGA,020000.00,4542.135726,N,12635.845169,E,1,08,0.9,117.87,M,-8.00,M,,")
    bad = (line[:-4] + "00\r\n").encode()  # the checksum wrong
    n = 12_000_000 // len(bad)
    manifest = _trial(tmp_path, {"gps.log": ("gps", "nmea", bad * n, "")})
    out = tmp_path / "g.mcap"
    rc, err, peak_kb = run_child("record", str(manifest), "-o", str(out), "--quiet", "--workers", "1")
    assert rc == 0 and peak_kb < 400 * 1024, (err, peak_kb)
    with ArchiveReader(out) as r:
        diags = [m.message.message for m in r.messages(["/diagnostics"])]
        (f,) = r.metadata_json("recording")["files"]
    assert f["skipped"] == f["bad_checksum"] == n
    assert len(diags) == DIAGNOSTICS_PER_KIND + 1 and f"{n - DIAGNOSTICS_PER_KIND} more bad checksums" in diags[-1]


@pytest.mark.parametrize("pattern, ok", [
    (r"(?P<source>\d)?(?P<range_m>(a+)+)$", True),     # the issue's: 4.5 s per line on re, linear on regex
    (r"(?P<source>\d)?(?P<range_m>(a|aa)+)$", False),  # backtracks on regex too: refused with the line
])
def test_user_patterns_cannot_hang_record(tmp_path, capsys, pattern, ok):
    lines = b"".join(b"12:00:%02d.0 " % (k % 60) + b"a" * 30 + b"!\n" for k in range(300))
    extra = f"pattern = '{pattern}'\ntime_format = \"tod\""
    manifest = _trial(tmp_path, {"modem.log": ("modem", "regex", lines, extra)})
    rc = main(["record", str(manifest), "-o", str(tmp_path / "m.mcap"), "--quiet"])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    if ok:
        assert rc == 0, err
    else:
        (line,) = err.strip().splitlines()
        assert rc == 1 and "takes over 0.05 s on line 1" in line and "simplify it" in line
