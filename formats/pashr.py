"""$PASHR attitude sentences (the RT300 / OxTS / Applanix / NovAtel SPAN layout).

    $PASHR,hhmmss.sss,HHH.HH,T,RRR.RR,PPP.PP,heave,rr.rrr,pp.ppp,hh.hhh,Q,S*CS

time of day (UTC), true heading (degrees, 'T'), roll and pitch (degrees,
signed: roll positive port side up, pitch positive bow up), heave (m), the
1-sigma roll, pitch and heading errors (degrees), the GNSS quality flag
(0 no position, 1 non-RTK fix, 2 RTK) and, when present, the INS status flag
(0 not aligned, 1 aligned). Ashtech receivers also use the address PASHR for
`$PASHR,POS,...`-style replies whose first field is a word, not a time: those
are skipped silently, as are other sentences; lines without a sentence and
bad checksums are Rejects.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

from .log_blocks import LogText
from .nmea.fields import parse_tod
from .nmea.framing import build
from .nmea.sentences import iter_frames
from .numbers import optional, optional_integer
from .records import Reject, Where


@dataclass(frozen=True, slots=True)
class Pashr:
    """One attitude record; NaN for empty fields, -1 for empty flags."""

    where: Where
    time_s: float
    heading_deg: float
    heading_true: bool
    roll_deg: float
    pitch_deg: float
    heave_m: float
    roll_std_deg: float
    pitch_std_deg: float
    heading_std_deg: float
    gnss_quality: int
    ins_status: int


_f = optional  # number fields: finite, NaN when empty (formats.numbers)
_i = optional_integer


def parse_fields(f: list[str], where: Where) -> Pashr | Reject | None:
    """A Pashr from the fields after the address; None for Ashtech-style replies."""
    if f and f[0][:1].isalpha():
        return None
    try:
        if len(f) < 9:
            raise IndexError(f"truncated PASHR: {len(f)} fields, 9 needed")
        return Pashr(
            where, parse_tod(f[0]), _f(f[1]), f[2] == "T", _f(f[3]), _f(f[4]), _f(f[5]),
            _f(f[6]), _f(f[7]), _f(f[8]), _i(f[9]) if len(f) > 9 else -1, _i(f[10]) if len(f) > 10 else -1,
        )
    except (ValueError, IndexError, OverflowError) as exc:
        return Reject(where, f"bad PASHR sentence: {exc}")


def decode(data: LogText, prefix: str = "auto") -> Iterator[Pashr | Reject]:
    """Stream every $PASHR attitude record (or Reject) in a log, in file order."""
    for item in iter_frames(data, prefix):
        if isinstance(item, Reject):
            yield item
            continue
        address, fields, where = item
        if address == "PASHR":
            result = parse_fields(fields[1:], where)
            if result is not None:
                yield result


def _n(x: float, spec: str) -> str:
    return format(x, spec) if math.isfinite(x) else ""


def encode_pashr(
    utc_ns: int, heading_deg: float, roll_deg: float, pitch_deg: float, *, heave_m: float = 0.0,
    roll_std_deg: float = 0.05, pitch_std_deg: float = 0.05, heading_std_deg: float = 0.1,
    gnss_quality: int = 1, ins_status: int = 1,
) -> str:
    """$PASHR line (CRLF); roll positive port up, pitch positive bow up, heading true."""
    ms = (utc_ns + 500_000) // 1_000_000 % 86_400_000
    h, rem = divmod(ms, 3_600_000)
    m, rem = divmod(rem, 60_000)
    fields = [
        f"{h:02d}{m:02d}{rem // 1000:02d}.{rem % 1000:03d}", _n(heading_deg % 360.0, "06.2f"), "T",
        _n(roll_deg, "+06.2f"), _n(pitch_deg, "+06.2f"), _n(heave_m, "+06.2f"),
        _n(roll_std_deg, ".3f"), _n(pitch_std_deg, ".3f"), _n(heading_std_deg, ".3f"),
        "" if gnss_quality < 0 else str(gnss_quality), "" if ins_status < 0 else str(ins_status),
    ]
    return build("PASHR", fields)
