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

Run: .venv/bin/python bench/bench_nmea.py [epochs]
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from datetime import date
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import pynmea2  # noqa: E402

from formats import nmea  # noqa: E402
from formats.mcap_writer import ArchiveWriter  # noqa: E402
from formats.sentence import build  # noqa: E402
from recorders.base import LogContext  # noqa: E402
from recorders.gps import convert_nmea  # noqa: E402

T0 = 1476259200 * 10**9  # 2016-10-12T08:00:00Z
REPEATS = 5


def receiver_mix(epochs: int) -> bytes:
    """Ten sentences per 1 Hz epoch, the way receivers interleave them."""
    out = []
    for k in range(epochs):
        t = T0 + k * 10**9
        lat, lon = 45.7 + k * 1e-6, 126.6 + k * 1e-6
        out += [
            nmea.encode_rmc(t, lat, lon, speed_knots=3.1, course_deg=45.0),
            nmea.encode_vtg(45.0, 3.1),
            nmea.encode_gga(t, lat, lon, hdop=0.9, altitude_msl_m=120.0, geoid_separation_m=-10.0, satellites=9),
            build("GPGSA", ["A", "3", "04", "05", "09", "12", "24", "25", "29", "", "", "", "", "", "1.6", "0.9", "1.3"]),
            *(build("GPGSV", ["3", str(i), "11", "03", "03", "111", "00", "04", "15", "270", "00",
                              "06", "01", "010", "00", "13", "06", "292", "00"]) for i in (1, 2, 3)),
            nmea.encode_gll(t, lat, lon),
            nmea.encode_gst(t, lat_std_m=1.2, lon_std_m=1.4, alt_std_m=2.5, rms_m=2.0),
            nmea.encode_zda(t),
        ]
    return "".join(out).encode()


def gga_only(epochs: int) -> bytes:
    """One GGA per epoch."""
    return "".join(nmea.encode_gga(T0 + k * 10**9, 45.7, 126.6, hdop=0.9) for k in range(epochs)).encode()


def median_time(fn: Callable[[], object]) -> float:
    """Median wall time of REPEATS runs, seconds."""
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def pynmea2_parse(data: bytes) -> int:
    """Parse every line with pynmea2 (checksums verified), keep the objects."""
    parsed = []
    for line in data.decode("latin-1").splitlines():
        parsed.append(pynmea2.parse(line))
    return len(parsed)


def ours_convert(data: bytes) -> int:
    """Every archive message the GPS converter makes from the log."""
    return sum(1 for _ in convert_nmea(data, LogContext("boat", trial_date=date(2016, 10, 12))))


def ours_mcap(data: bytes, path: Path) -> int:
    """The converter's messages written into an MCAP archive."""
    n = 0
    with ArchiveWriter(path) as writer:
        for out in convert_nmea(data, LogContext("boat", trial_date=date(2016, 10, 12))):
            writer.write(out.topic, out.message, out.log_time_ns, out.publish_time_ns)
            n += 1
    return n


def row(name: str, data: bytes, tmp: Path) -> tuple[str, int, float, float, float, float]:
    """Timings (us per sentence) of the four pipelines on one log."""
    lines = data.count(b"\n")
    per = 1e6 / lines
    py = median_time(lambda: pynmea2_parse(data)) * per
    dec = median_time(lambda: sum(1 for _ in nmea.decode(data))) * per
    conv = median_time(lambda: ours_convert(data)) * per
    mcap = median_time(lambda: ours_mcap(data, tmp / "bench.mcap")) * per
    return name, lines, py, dec, conv, mcap


def main(argv: list[str] | None = None) -> int:
    """Print the table."""
    args = sys.argv[1:] if argv is None else argv
    epochs = int(args[0]) if args else 3000
    with tempfile.TemporaryDirectory() as tmp:
        rows = [row("receiver mix", receiver_mix(epochs), Path(tmp)), row("GGA only", gga_only(epochs), Path(tmp))]
    print(f"NMEA -> MCAP, {epochs} epochs, median of {REPEATS} runs, microseconds per sentence")
    head = f"{'log':<14}{'lines':>8}{'pynmea2 parse':>15}{'ours decode':>13}{'ours convert':>14}{'ours to MCAP':>14}{'parse/MCAP':>12}{'parse/decode':>14}"
    print(head)
    print("-" * len(head))
    for name, lines, py, dec, conv, mcap in rows:
        print(f"{name:<14}{lines:>8}{py:>15.2f}{dec:>13.2f}{conv:>14.2f}{mcap:>14.2f}{py / mcap:>11.2f}x{py / dec:>13.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
