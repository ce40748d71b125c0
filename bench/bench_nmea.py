"""NMEA to MCAP end to end, against pynmea2 merely parsing the same lines.

Two synthetic 1 Hz logs written with our encoders: a receiver mix as a
u-blox or NovAtel port prints it (RMC, VTG, GGA, GSA, 3 x GSV, GLL, GST, ZDA:
10 sentences and one fix per epoch) and a GGA-only log (one sentence per
fix, the worst case for us: every sentence becomes two archive messages).

Columns, per sentence of the log (median of repeats, microseconds):
  pynmea2 parse       pynmea2.parse() on every line, nothing else
  ours decode         formats.nmea.decode (records, checksums verified)
  ours convert        recorders.gps.convert_nmea (LocationFix + GnssStatus)
  ours to MCAP        convert + formats.mcap_writer.ArchiveWriter (zstd, CRCs)
and the ratio pynmea2 parse / ours to MCAP (> 1: ours end to end is faster).
The pipelines run interleaved (one of each per round), so a load change on
the shared machine hits them all alike.

A second table splits one GGA-only epoch (one sentence, two archive
messages) into its stages, each timed alone in a loop: it says where the
time goes and why that log cannot reach 2x pynmea2 (see the note printed
under it).

Run: .venv/bin/python bench/bench_nmea.py [epochs]
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from datetime import date
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
    t = interleaved(repeats=REPEATS, fns={
        "pynmea2": lambda: pynmea2_parse(data),
        "decode": lambda: sum(1 for _ in nmea.decode(data)),
        "reference": lambda: sum(1 for _ in convert_nmea_reference(data, CTX)),
        "convert": lambda: sum(1 for _ in convert_nmea(data, CTX)),
        "mcap": lambda: ours_mcap(data, tmp / "bench.mcap"),
    })
    us = {k: v * 1e6 / lines for k, v in t.items()}
    return [name, lines, us["pynmea2"], us["decode"], us["reference"], us["convert"], us["mcap"],
            us["pynmea2"] / us["mcap"], us["pynmea2"] / us["decode"]]


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
    head = (f"{'log':<14}{'lines':>8}{'pynmea2 parse':>15}{'ours decode':>13}{'ref. convert':>14}{'ours convert':>14}"
            f"{'ours to MCAP':>14}{'parse/MCAP':>12}{'parse/decode':>14}")
    print(head)
    print("-" * len(head))
    for name, lines, py, dec, ref, conv, mcap, ratio, ratio_dec in rows:
        print(f"{name:<14}{lines:>8}{py:>15.2f}{dec:>13.2f}{ref:>14.2f}{conv:>14.2f}{mcap:>14.2f}"
              f"{ratio:>11.2f}x{ratio_dec:>13.2f}x")
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
