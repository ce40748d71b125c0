"""`formats.micromodem.sentences.decode` as plain tuples: the recording hot path for Micro-Modem logs.

`scan` yields every record as ``(kind, values, offset, line, host ns)``
tuples, and every Reject, so that the converter counts each line. The common sentences
of a ping exchange ($CCMPC, $CAMPC, $CAMPA, $CAMPR), starting the text and
checksummed, are read here, the checksum from a prefix XOR of the whole log;
every other line, and any of those the fast reading doubts, goes through
`micromodem.decode_sentence`, so the results are those of `decode`
(tests/test_micromodem_scan.py checks it on any bytes).

Kinds and values:

- "reply": (src, dest, one-way travel time s, reception UTC ns or None): $CAMPR, $CACMR,PNR;
- "sent": (src, dest, echo): $CCMPC (the host's command), $CAMPC (the modem's echo), $CCCMD/$CACMD,PNG;
- "heard": (src, dest, what, UTC ns or None): $CAMPA and $CACMA,PNG ("ping"), $CACYC ("cycle"),
  $CARXD and $CAMUA ("data");
- "other": (address,): a well-framed sentence nothing is read from ($CAREV, $CATXF...);
- "date": (date, time of day s): $CAXST; "clock": (UTC ns,): $CACLK;
- "rxstats": (src, time of day s): $CACST; "toa": (time of day s or None, UTC ns or None): $CATOA.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Literal

from ..host_lines import block_lines
from ..lines import PREFIX_STYLES
from ..log_blocks import Block, LogText, blocks_in
from ..nmea.framing import HEX, prefix_xor
from ..records import Reject, Where
from . import sentences as mm

Scanned = tuple[str, tuple, int, "int | None", "int | None"]  # kind, values, offset, line, host ns
_PING_COMMANDS = frozenset(("CCMPC", "CAMPC"))
_SEEN_MAX = 4096  # distinct sentence texts remembered per log (replies differ by travel time: bounded memory)


def _scanned(rec: mm.Record | Reject) -> Scanned | Reject | None:
    """A decoder record as `scan` yields it (None for what the converter does not use)."""
    if isinstance(rec, Reject):
        return rec
    w = rec.where
    where = w.offset, w.line, w.host_time_ns
    if isinstance(rec, mm.PingReply):
        return "reply", (rec.src, rec.dest, rec.one_way_travel_time_s, rec.utc_ns), *where
    if isinstance(rec, mm.PingHeard):
        return "heard", (rec.src, rec.dest, "ping", rec.utc_ns), *where
    if isinstance(rec, mm.CycleInit):
        return "heard", (rec.src, rec.dest, "cycle", None), *where
    if isinstance(rec, mm.ReceivedData):
        return "heard", (rec.src, rec.dest, "data", None), *where
    if isinstance(rec, mm.PingCommand):
        return "sent", (rec.src, rec.dest, rec.echo), *where
    if isinstance(rec, mm.TransmitStats):
        return "date", (rec.date, rec.tod_s), *where
    if isinstance(rec, mm.Clock):
        return "clock", (rec.utc_ns,), *where
    if isinstance(rec, mm.ReceiveStats):
        return "rxstats", (rec.src, rec.tod_s), *where
    if isinstance(rec, mm.TimeOfArrival):
        return "toa", (rec.tod_s, rec.utc_ns), *where
    if isinstance(rec, mm.OtherSentence):
        return "other", (rec.address,), *where
    return None


def _ascii_int(text: str) -> bool:
    """Digits that int() reads as `micromodem._int` does ('²' is a digit to isdigit alone)."""
    return text.isdigit() and text.isascii()


def _fast(fields: list[str], round_trip: bool) -> tuple[str, tuple] | None | Literal[False]:
    """A ping sentence's (kind, values), None when it is valid and unused, False when in doubt."""
    address = fields[0]
    if len(fields) < 3 or not (_ascii_int(fields[1]) and _ascii_int(fields[2])):
        return False
    if address in _PING_COMMANDS:
        return "sent", (int(fields[1]), int(fields[2]), address == "CAMPC")
    if address == "CAMPA":
        return "heard", (int(fields[1]), int(fields[2]), "ping", None)
    if address != "CAMPR" or len(fields) < 4:
        return False
    try:
        tt = float(fields[3])
    except ValueError:
        return False
    if not (0.0 <= tt < math.inf) or not fields[3].strip():
        return False
    return "reply", (int(fields[1]), int(fields[2]), tt / 2 if round_trip else tt, None)


def scan(data: LogText, prefix: str = "auto", campr_round_trip: bool = False) -> Iterator[Scanned | Reject]:
    """What `micromodem.decode` yields for the converter, as tuples (see the module docstring); `data` may be
    the log in blocks."""
    if prefix not in PREFIX_STYLES:
        raise ValueError(f"unknown host-timestamp prefix style {prefix!r}; use one of {PREFIX_STYLES}")
    # a ping exchange repeats its command and echo lines word for word: read each text once
    seen: dict[str, tuple[str, tuple] | None] = {}
    minutes: dict[str, int | None] = {}
    for block in blocks_in(data):
        yield from _scan_block(block, prefix, campr_round_trip, seen, minutes)


def _scan_block(block: Block, prefix: str, campr_round_trip: bool, seen: dict[str, tuple[str, tuple] | None],
                minutes: dict[str, int | None]) -> Iterator[Scanned | Reject]:
    """`scan` of one block of a log; `seen` and `minutes` go on from block to block."""
    pxor = prefix_xor(block.data)
    for text, offset, number, host, at in block_lines(block, prefix, minutes):
        found: tuple[str, tuple] | None | Literal[False] = seen.get(text, False)
        if found is False and text[:1] == "$":
            body = text[1:].rstrip("\r\n ")
            star = body.rfind("*")
            # `nmea.framing.frame`'s checksum: the XOR of the payload's bytes in `data` is pxor's two ends
            if (star >= 0 and len(body) - star - 1 >= 2
                    and HEX.get(body[star + 1 : star + 3]) == pxor[at + star] ^ pxor[at]):
                found = _fast(body[:star].split(","), campr_round_trip)
                if found is not False and len(seen) < _SEEN_MAX:
                    seen[text] = found
        if found is None:
            continue
        if found is not False:
            yield found[0], found[1], offset, number, host
            continue
        item = _scanned(mm.decode_sentence(text, Where(offset, number, host), campr_round_trip))
        if item is not None:
            yield item
