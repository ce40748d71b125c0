"""`formats.lines.iter_lines` as plain tuples, for decoders on the recording hot path.

Host loggers put the same ISO 8601 prefix shape before every line
(``2016-10-12T02:00:03.263140Z ``); parsing it with datetime costs more than
decoding the sentence behind it. Here the date, hour and minute are parsed
once per minute and cached; any other shape (brackets, a comma or zone
offset, Unix seconds, a second 60, no prefix) goes through
`formats.lines.strip_prefix`, so the results are those of `iter_lines`.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from datetime import UTC, datetime

from .lines import PREFIX_STYLES, strip_prefix
from .log_blocks import Block
from .units import NS

ScannedLine = tuple[str, int, int, "int | None", int]  # text, line offset, 1-based line number, host ns, text offset

# the common shape only; `lines._ISO` accepts it with the same extent and groups
_FAST_ISO = re.compile(r"(\d{4}-\d\d-\d\dT\d\d:\d\d:)(\d\d)\.(\d+)Z\]?[ \t,;|]*")


def _minute_ns(key: str) -> int | None:
    """Unix ns of 'YYYY-MM-DDTHH:MM:' at second 0, None when datetime refuses it."""
    try:
        return int(datetime.fromisoformat(key + "00").replace(tzinfo=UTC).timestamp()) * NS
    except ValueError:
        return None


def scan_lines(data: bytes, prefix: str = "auto") -> Iterator[ScannedLine]:
    """What `iter_lines` yields, as (text, offset, line, host ns, text offset) tuples; blank lines skipped.

    The text offset is where the text after the prefix starts in `data` (for checksums over the buffer).
    """
    return block_lines(Block(data), prefix)


def block_lines(block: Block, prefix: str = "auto", minutes: dict[str, int | None] | None = None
                ) -> Iterator[ScannedLine]:
    """`scan_lines` of one block of a log: offsets and line numbers the log's, the text offset the block's.

    `minutes` caches parsed prefix minutes from one block to the next.
    """
    if prefix not in PREFIX_STYLES:
        raise ValueError(f"unknown host-timestamp prefix style {prefix!r}; use one of {PREFIX_STYLES}")
    match = _FAST_ISO.match if prefix in ("auto", "iso8601") else None
    minutes = {} if minutes is None else minutes
    base = offset = block.offset
    for number, raw in enumerate(block.data.decode("latin-1").split("\n"), start=block.lines + 1):
        start = offset
        offset += len(raw) + 1
        text = raw.rstrip("\r")
        m = match(text) if match is not None else None
        if m is not None:  # not blank then
            key, second, frac = m.groups()
            minute = minutes.get(key, -1)
            if minute == -1:
                minute = minutes[key] = _minute_ns(key)
            if minute is not None and second < "60":
                end = m.end()
                yield (text[end:], start, number, minute + int(second) * NS + int((frac + "000000000")[:9]),
                       start - base + end)
                continue
        elif not text.strip():
            continue
        rest, host = strip_prefix(text, prefix)
        yield rest, start, number, host, start - base + len(text) - len(rest)
