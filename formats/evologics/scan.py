"""`formats.evologics.notifications.decode` as plain tuples: the recording hot path for EvoLogics logs.

`scan` yields what the range and USBL converters use, USBLLONG, USBLANGLES,
USBLPHYD and AT?T propagation times, as ``(keyword, values, offset, line,
host ns)`` tuples, and every Reject; other notifications are validated (they
move the AT?T peer) but not yielded. A well-formed unframed USBL line is read
here with one float() per field; every other line, and any USBL line the fast
reading doubts, goes through `evologics`' own decoder, so the results are
those of `decode` (tests/test_evologics_scan.py checks it on any bytes).

Values, by keyword (the record's fields after `where`, in order):

- USBLLONG / USBLANGLES: floats, the address (index 2) an int;
- USBLPHYD: current and measurement time, address, fix type (ints), the
  eight delays (NaN where the modem had none);
- AT?T: (propagation time µs, peer address or None).
"""

from __future__ import annotations

import math
from collections.abc import Generator, Iterator

from ..host_lines import ScannedLine, block_lines
from ..lines import PREFIX_STYLES
from ..log_blocks import LogText, blocks_in
from ..records import Reject, Where
from . import notifications as ev

Scanned = tuple[str, list, int, "int | None", "int | None"]  # keyword, values, offset, line, host ns
_FIELDS = {"USBLLONG": 16, "USBLANGLES": 13, "USBLPHYD": 12}
_INVALID = float(ev.INVALID_DELAY)
_NAN = math.nan
_KEYWORDS = {ev.UsblLong: "USBLLONG", ev.UsblAngles: "USBLANGLES"}


def _fast_usbl(keyword: str, body: str) -> list | None:
    """A USBL line's values when every field reads cleanly, else None (the decoder says why)."""
    parts = body.split(",")
    if len(parts) != _FIELDS[keyword] or not parts[2].isdigit() or len(parts[2]) > 9:  # an int32 address
        return None
    try:
        v = list(map(float, parts))
        v[2] = int(parts[2])
    except ValueError:
        return None
    if not math.isfinite(sum(v)):  # a NaN, an infinity or an overflow: let the decoder word it
        return None
    if keyword == "USBLLONG":
        return v if v[12] >= 0 else None
    if keyword == "USBLPHYD":
        v[3] = int(v[3])
        v[4:] = [_NAN if d == _INVALID or d == -_INVALID else d for d in v[4:]]
    return v


def _scanned(rec: ev.Record | Reject | None) -> Scanned | Reject | None:
    """A decoder record as `scan` yields it (None for what the converters do not use)."""
    if isinstance(rec, Reject):
        return rec
    if isinstance(rec, (ev.UsblLong, ev.UsblAngles)):
        values = [getattr(rec, name) for name in type(rec).__slots__[1:]]
        return _KEYWORDS[type(rec)], values, *_where(rec)
    if isinstance(rec, ev.UsblPhaseDelays):
        values = [rec.current_time_s, rec.measurement_time_s, rec.address, rec.fix_type, *rec.delays_ns]
        return "USBLPHYD", values, *_where(rec)
    if isinstance(rec, ev.PropagationTime):
        return "AT?T", [rec.propagation_time_us, rec.peer], *_where(rec)
    return None


def _where(rec: ev.Record) -> tuple[int, int | None, int | None]:
    w = rec.where
    return w.offset, w.line, w.host_time_ns


def scan(data: LogText, prefix: str = "auto") -> Iterator[Scanned | Reject]:
    """What `evologics.decode` yields for the converters, as tuples (see the module docstring); `data` may be
    the log in blocks: a block's last lines, which a +++AT frame may join to the next block's, wait for it."""
    if prefix not in PREFIX_STYLES:
        raise ValueError(f"unknown host-timestamp prefix style {prefix!r}; use one of {PREFIX_STYLES}")
    state = ev._Decoder()
    minutes: dict[str, int | None] = {}
    carry: list[ScannedLine] = []
    blocks = iter(blocks_in(data))
    block = next(blocks, None)
    while block is not None:
        following = next(blocks, None)
        lines = carry + list(block_lines(block, prefix, minutes))
        # a frame starting before `stop` peeks at most ev._MAX_JOIN - 1 lines on, all in `lines`
        stop = len(lines) if following is None else max(len(lines) - ev._MAX_JOIN, 0)
        done = yield from _scan_lines(state, lines, stop)
        carry = lines[done:]
        block = following


def _scan_lines(state: ev._Decoder, lines: list[ScannedLine], stop: int
                ) -> Generator[Scanned | Reject, None, int]:
    """`scan` over `lines` until a line at `stop` or later would come next; returns that line's index."""
    texts = [line[0] for line in lines]
    i, n = 0, stop
    while i < n:
        text, offset, number, host, _ = lines[i]
        if "+++AT" not in text:
            i += 1
            keyword, _, body = text.partition(",")
            if keyword in _FIELDS:
                # a USBL line clears a pending AT?T query and leaves the peer alone (`_Decoder.plain`)
                state.query_pending = False
                values = _fast_usbl(keyword, body)
                if values is not None:
                    yield keyword, values, offset, number, host
                    continue
            item = _scanned(state.plain(text, Where(offset, number, host)))
        else:
            item, used = _scan_framed(state, texts, i, Where(offset, number, host))
            i += used
        if item is not None:
            yield item
    return i


def _scan_framed(state: ev._Decoder, texts: list[str], i: int, where: Where) -> tuple[Scanned | Reject | None, int]:
    """`decode`'s step at a line holding '+++AT': (what it gives, lines consumed)."""
    framed = ev._framed(lambda k: texts[i + k] if i + k < len(texts) else None)
    if framed is None:
        return _scanned(state.plain(texts[i], where)), 1
    command, payload, want, used = framed
    if len(payload) != want:
        return Reject(where, f"+++AT frame declares {want} characters, has {len(payload)}"), used
    return _scanned(ev._framed_record(state, command, payload, where)), used
