"""MOOS-IvP `.alog` files (pLogger): a `%%` header, then one posting per line.

    %% LOGSTART           1464207778.381
    10.123   NAV_X        uSimMarine     12.5

A posting is: seconds since the header's LOGSTART, the variable, the source
process (optionally `:aux`), and the value: the rest of the line, a number
or a string (which may contain spaces, commas and `=`). Times are absolute:
LOGSTART plus the line's seconds; a second `%% LOGSTART` (rotated logs read
as one) starts a new epoch. Postings before any LOGSTART, or whose time is
not a number, are rejected.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

from .lines import iter_lines
from .log_blocks import LogText
from .numbers import finite
from .records import Reject, Where
from .units import NS


@dataclass(frozen=True, slots=True)
class Posting:
    """One alog line: absolute time (ns, UTC), variable, source process, value text, number when it is one."""

    where: Where
    time_ns: int
    variable: str
    source: str
    text: str
    number: float = math.nan


def _seconds_ns(text: str) -> int | None:
    try:
        value = float(text)
    except ValueError:
        return None
    if not math.isfinite(value) or abs(value) > 1e11:
        return None
    return round(value * NS)


def decode(data: LogText) -> Iterator[Posting | Reject]:
    """Every posting of an alog, or a Reject saying why a line is not one; header lines give neither."""
    epoch: int | None = None
    for line in iter_lines(data, "none"):
        text = line.text
        if text.startswith("%%"):
            words = text[2:].split()
            if len(words) >= 2 and words[0] == "LOGSTART":
                start = _seconds_ns(words[1])
                if start is None:
                    yield Reject(line.where, f"LOGSTART {words[1]!r} is not a time")
                else:
                    epoch = start
            continue
        parts = text.split(None, 3)
        if len(parts) < 3:
            yield Reject(line.where, "not an alog posting (time, variable, source, value)")
            continue
        offset = _seconds_ns(parts[0])
        if offset is None:
            yield Reject(line.where, f"posting time {parts[0][:20]!r} is not a number")
            continue
        if epoch is None:
            yield Reject(line.where, "posting before the %% LOGSTART header line")
            continue
        value = parts[3].strip() if len(parts) > 3 else ""
        try:  # a value that is no finite number is a text posting (NaN number)
            number = finite(value)
        except ValueError:
            number = math.nan
        yield Posting(line.where, epoch + offset, parts[1], parts[2], value, number)
