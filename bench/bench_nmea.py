"""NMEA to MCAP end to end, against pynmea2 parsing the same lines and computing the same outputs.

Two synthetic 1 Hz logs written with our encoders: a receiver mix as a
u-blox or NovAtel port prints it (RMC, VTG, GGA, GSA, 3 x GSV, GLL, GST, ZDA:
10 sentences and one fix per epoch) and a GGA-only log (one sentence per
fix, the worst case for us: every sentence becomes two archive messages).

Like with like: both sides give, per epoch, the fix (time, latitude,
longitude, ellipsoidal altitude, ENU covariance from GST sigmas else HDOP)
and the velocity over ground (north, east, speed, course from VTG, else a
valid RMC). pynmea2's side parses every line (checksums verified), groups
the sentences into epochs by time of day as we do, takes the date from ZDA
or RMC, and computes those values as Python floats; the script checks they
equal ours (1e-9) before timing anything. Ours builds the protobuf
messages (fix, status, velocity), counts every sentence, and writes them
into a zstd-compressed, CRC-checked MCAP archive.

Columns, per sentence of the log (median of repeats, microseconds):
  pynmea2 parse       pynmea2.parse() on every line, nothing else (the old reference)
  pynmea2 outputs     parse + epochs + fix + velocity, the same values as ours
  ours decode         formats.nmea.decode (records, checksums verified)
  ours convert        recorders.gps.convert_nmea (LocationFix + GnssStatus + GnssVelocity messages)
  ours to MCAP        convert + formats.mcap_writer.ArchiveWriter (zstd, CRCs)
and the ratios pynmea2 outputs / ours to MCAP (the headline: ours does
more) and pynmea2 outputs / ours convert (> 1: ours is faster).
The pipelines run interleaved (one of each per round), so a load change on
the shared machine hits them all alike.

A second table splits one GGA-only epoch (one sentence, two archive
messages) into its stages, each timed alone in a loop: it says where the
time goes and why that log cannot reach 2x pynmea2 (see the note printed
under it).

Run: .venv/bin/python bench/bench_nmea.py [epochs]
"""

from __future__ import annotations

import math
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from datetime import date, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import pynmea2
from common import interleaved

from formats import schemas as S
from formats.mcap_writer import ArchiveWriter
from formats.nmea import sentences as nmea
from formats.nmea.framing import build
from formats.records import Where
from formats.units import NS
from recorders.base import LogContext, Output
from recorders.gps import convert_nmea, gnss_status
from tests.reference_converters import convert_nmea_reference

T0 = 1476259200 * NS  # 2016-10-12T08:00:00Z
REPEATS = 7
CTX = LogContext("boat", trial_date=date(2016, 10, 12))


def receiver_mix(epochs: int) -> bytes:
    """Ten sentences per 1 Hz epoch, the way receivers interleave them."""
    out = []
    for k in range(epochs):
        t = T0 + k * NS
        lat, lon = 45.7 + k * 1e-6, 126.6 + k * 1e-6
        out += [
            nmea.encode_rmc(t, lat, lon, speed_knots=3.1, course_deg=45.0),
            nmea.encode_vtg(45.0, 3.1),
            nmea.encode_gga(t, lat, lon, hdop=0.9, altitude_msl_m=120.0, geoid_separation_m=-10.0, satellites=9),
            build("GPGSA", ["A", "3", "04", "05", "09", "12", "24", "25", "29", "", "", "", "", "",
                            "1.6", "0.9", "1.3"]),
            *(build("GPGSV", ["3", str(i), "11", "03", "03", "111", "00", "04", "15", "270", "00",
                              "06", "01", "010", "00", "13", "06", "292", "00"]) for i in (1, 2, 3)),
            nmea.encode_gll(t, lat, lon),
            nmea.encode_gst(t, lat_std_m=1.2, lon_std_m=1.4, alt_std_m=2.5, rms_m=2.0),
            nmea.encode_zda(t),
        ]
    return "".join(out).encode()


def gga_only(epochs: int) -> bytes:
    """One GGA per epoch."""
    return "".join(nmea.encode_gga(T0 + k * NS, 45.7 + k * 1e-6, 126.6, hdop=0.9) for k in range(epochs)).encode()




KNOTS = 1852.0 / 3600.0
UERE_GPS_M = 4.0  # the UERE of a GPS fix (quality 1), as recorders.gnss_covariance uses it
_TIMED = ("GGA", "RMC", "GLL", "GST", "ZDA")


def pynmea2_outputs(data: bytes) -> list[tuple]:
    """pynmea2 parses every line; epochs by time of day; per epoch the fix and the velocity as plain values."""
    out: list[tuple] = []
    epoch: dict[str, object] = {}
    epoch_time = None
    day = [CTX.trial_date]  # the manifest's date, until a ZDA or RMC gives one
    for line in data.decode("latin-1").splitlines():
        msg = pynmea2.parse(line)
        kind = msg.sentence_type
        if kind not in ("GGA", "RMC", "GLL", "GST", "ZDA", "VTG"):
            continue
        t = msg.timestamp if kind in _TIMED else None
        if epoch and (kind in epoch or (t is not None and epoch_time is not None and t != epoch_time)):
            out += _pynmea2_epoch(epoch, day)
            epoch, epoch_time = {}, None
        epoch[kind] = msg
        if epoch_time is None:
            epoch_time = t
    if epoch:
        out += _pynmea2_epoch(epoch, day)
    return out


def _pynmea2_epoch(epoch: dict, day: list) -> list[tuple]:
    """('fix', t, lat, lon, alt, covariance) and ('velocity', t, north, east, speed, course) of one epoch."""
    zda, rmc, gga, gst, vtg = (epoch.get(k) for k in ("ZDA", "RMC", "GGA", "GST", "VTG"))
    if zda is not None:
        day[0] = zda.datetime.date()
    elif rmc is not None and rmc.status == "A":
        day[0] = rmc.datestamp
    first = next(m for k, m in epoch.items() if k in _TIMED)
    t = datetime.combine(day[0], first.timestamp)
    t_ns = round(t.timestamp() * 1e6) * 1000
    out = []
    if gga is not None and gga.gps_qual:
        alt = float(gga.altitude) + float(gga.geo_sep)
        if gst is not None:
            cov = (gst.std_dev_longitude ** 2, 0.0, 0.0, 0.0, gst.std_dev_latitude ** 2, 0.0, 0.0, 0.0,
                   gst.std_dev_altitude ** 2)
        else:
            h = float(gga.horizontal_dil) * UERE_GPS_M
            cov = (h * h / 2, 0.0, 0.0, 0.0, h * h / 2, 0.0, 0.0, 0.0, 4 * h * h)
        out.append(("fix", t_ns, gga.latitude, gga.longitude, alt, cov))
    speed = course = None
    if vtg is not None and vtg.faa_mode != "N":
        speed, course = float(vtg.spd_over_grnd_kts) * KNOTS, vtg.true_track
    elif rmc is not None and rmc.status == "A":
        speed, course = rmc.spd_over_grnd * KNOTS, rmc.true_course
    if speed is not None and course is not None:
        c = math.radians(course)
        out.append(("velocity", t_ns, speed * math.cos(c), speed * math.sin(c), speed, course))
    return out


def ours_outputs(data: bytes) -> list[tuple]:
    """Our fix and velocity messages as the same plain values (for the check that both sides agree)."""
    out = []
    for o in convert_nmea(data, CTX):
        m = o.message
        if o.topic.endswith("/gps"):
            out.append(("fix", o.log_time_ns, m.latitude, m.longitude, m.altitude, tuple(m.position_covariance)))
        elif o.topic.endswith("/gps/velocity"):
            out.append(("velocity", o.log_time_ns, m.velocity_north_mps, m.velocity_east_mps,
                        m.speed_over_ground_mps, m.course_over_ground_deg))
    return out


def check_same_outputs(data: bytes) -> int:
    """Raise unless pynmea2's values are ours (1e-9); the number of outputs."""
    theirs, ours = pynmea2_outputs(data), ours_outputs(data)
    assert len(theirs) == len(ours) and theirs, (len(theirs), len(ours))
    for a, b in zip(theirs, ours):
        assert a[:2] == b[:2], (a, b)
        flat_a = [*a[2:-1], *(a[-1] if isinstance(a[-1], tuple) else (a[-1],))]
        flat_b = [*b[2:-1], *(b[-1] if isinstance(b[-1], tuple) else (b[-1],))]
        assert all(math.isclose(x, y, rel_tol=1e-9, abs_tol=1e-9) for x, y in zip(flat_a, flat_b)), (a, b)
    return len(ours)


def pynmea2_parse(data: bytes) -> int:
    """Parse every line with pynmea2 (checksums verified), keep the objects."""
    parsed = []
    for line in data.decode("latin-1").splitlines():
        parsed.append(pynmea2.parse(line))
    return len(parsed)


def ours_mcap(data: bytes, path: Path) -> int:
    """The converter's messages written into an MCAP archive."""
    n = 0
    with ArchiveWriter(path) as writer:
        for out in convert_nmea(data, CTX):
            writer.write(out.topic, out.message, out.log_time_ns, out.publish_time_ns)
            n += 1
    return n


def row(name: str, data: bytes, tmp: Path) -> list[object]:
    """Timings (us per sentence) of every pipeline on one log, and the ratios."""
    lines = data.count(b"\n")
    check_same_outputs(data)
    t = interleaved(repeats=REPEATS, fns={
        "pynmea2": lambda: pynmea2_parse(data),
        "pynmea2 outputs": lambda: len(pynmea2_outputs(data)),
        "decode": lambda: sum(1 for _ in nmea.decode(data)),
        "reference": lambda: sum(1 for _ in convert_nmea_reference(data, CTX)),
        "convert": lambda: sum(1 for _ in convert_nmea(data, CTX)),
        "mcap": lambda: ours_mcap(data, tmp / "bench.mcap"),
    })
    us = {k: v * 1e6 / lines for k, v in t.items()}
    return [name, lines, us["pynmea2"], us["pynmea2 outputs"], us["decode"], us["reference"], us["convert"],
            us["mcap"], us["pynmea2 outputs"] / us["mcap"], us["pynmea2 outputs"] / us["convert"],
            us["pynmea2"] / us["mcap"]]


def per_call_us(fn: Callable[[], object], n: int = 20000, repeats: int = REPEATS) -> float:
    """Median microseconds per call of fn over `repeats` loops of n calls."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(n):
            fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e6 / n


def per_line_us(fn: Callable[[bytes], object], data: bytes, repeats: int = REPEATS) -> float:
    """Median microseconds per line of fn over a whole log (fixed costs amortized as in a real log)."""
    lines = data.count(b"\n")
    return statistics.median(_timed(lambda: fn(data)) for _ in range(repeats)) * 1e6 / lines


def _timed(fn: Callable[[], object]) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def stage_table(tmp: Path, log: bytes) -> list[tuple[str, float]]:
    """One GGA-only epoch split into stages (us per GGA line, or per call)."""
    line = log[: log.index(b"\n") + 1].decode()
    fields = line[7 : line.find("*")].split(",")
    cov = (1.62, 0.0, 0.0, 0.0, 1.62, 0.0, 0.0, 0.0, 12.96)
    fix = S.location_fix(T0, "boat", 45.7, 126.6, 0.0, cov, 1)
    status = gnss_status(T0, "boat", 1, 8, 0.9, "nmea:GGA", float("nan"), float("nan"), float("nan"))
    where = Where(0, 1)
    writer = ArchiveWriter(tmp / "stages.mcap")
    try:
        stages = [
            ("pynmea2.parse, per line", per_line_us(pynmea2_parse, log)),
            ("ours: nmea.scan, per line", per_line_us(lambda d: sum(1 for _ in nmea.scan(d)), log)),
            ("  of which GGA field values", per_call_us(lambda: nmea.VALUES["GGA"](fields))),
            ("ours: schemas.location_fix", per_call_us(lambda: S.location_fix(T0, "boat", 45.7, 126.6, 0.0, cov, 1))),
            ("ours: gps.gnss_status",
             per_call_us(lambda: gnss_status(T0, "boat", 1, 8, 0.9, "nmea:GGA", 0.0, 0.0, 0.0))),
            ("ours: Where + Output x 2", per_call_us(lambda: (Where(0, 1), Output("/b/gps", fix, T0, T0, where),
                                                              Output("/b/gps/status", status, T0, T0, where)))),
            ("ours: ArchiveWriter.write x 2", per_call_us(lambda: (writer.write("/b/gps", fix, T0),
                                                                   writer.write("/b/gps/status", status, T0)))),
            ("ours: convert_nmea, per line", per_line_us(lambda d: sum(1 for _ in convert_nmea(d, CTX)), log)),
            ("ours: to MCAP (file, fsync), per line", per_line_us(lambda d: ours_mcap(d, tmp / "s.mcap"), log)),
        ]
    finally:
        writer.abort()
    return stages


def main(argv: list[str] | None = None) -> int:
    """Print the tables."""
    args = sys.argv[1:] if argv is None else argv
    epochs = int(args[0]) if args else 3000
    with tempfile.TemporaryDirectory() as tmp:
        gga = gga_only(epochs * 3)
        rows = [row("receiver mix", receiver_mix(epochs), Path(tmp)), row("GGA only", gga, Path(tmp))]
        stages = stage_table(Path(tmp), gga)
    print(f"NMEA -> MCAP, median of {REPEATS} interleaved runs, microseconds per sentence")
    head = (f"{'log':<14}{'lines':>7}{'pynmea2 parse':>15}{'pynmea2 outputs':>17}{'ours decode':>13}"
            f"{'ref. convert':>14}{'ours convert':>14}{'ours to MCAP':>14}{'outputs/MCAP':>14}{'outputs/convert':>17}"
            f"{'parse/MCAP':>12}")
    print(head)
    print("-" * len(head))
    for name, lines, py, pyout, dec, ref, conv, mcap, ratio, ratio_conv, ratio_parse in rows:
        print(f"{name:<14}{lines:>7}{py:>15.2f}{pyout:>17.2f}{dec:>13.2f}{ref:>14.2f}{conv:>14.2f}{mcap:>14.2f}"
              f"{ratio:>13.2f}x{ratio_conv:>16.2f}x{ratio_parse:>11.2f}x")
    print("  (pynmea2 outputs: parse, epochs, fix and velocity values, checked equal to ours before timing;"
          " ours: fix, status and velocity messages, every sentence counted)")
    print("  (ref. convert: tests.reference_converters.convert_nmea_reference, the record-based path the fast one"
          " is tested against)")
    print("\nOne GGA-only epoch by stage, median microseconds (per GGA line of the log, or per call)")
    for name, us in stages:
        print(f"  {name:<38}{us:>8.2f}")
    parse = stages[0][1]
    floor = sum(us for name, us in stages[3:7])
    print(f"  2x pynmea2 leaves {parse / 2:.2f} us per GGA; building and writing the two messages alone "
          f"(fix, status, outputs, writes) takes {floor:.2f} us")
    return 0


if __name__ == "__main__":
    sys.exit(main())
