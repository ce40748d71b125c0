"""Whole-log framing of clean NMEA-style sentences as columns, for the columnar fast paths.

A log is *clean* when every non-empty line is exactly ``$ADDRS,...*HH`` (LF or
CRLF, one '$', one '*', two hex digits at the end, checksum right). Then the
framing checks run once over the buffer with numpy, and the fields of all
lines of one sentence type come out of one join and one split: a Python step
per field column instead of several per line. Any other log gets None, and
the caller takes its per-line path, which knows every kind of damage.

The column helpers convert like the per-line parsers (Python's own `float`
and `int` on the same strings) or check the strings strictly enough that the
vectorised arithmetic is the per-line parser's, exactly; they return None
where the per-line path must decide (it may reject, or accept something odd).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from operator import itemgetter

import numpy as np

from ..numbers import HEX_VALUE
from .framing import prefix_xor


@dataclass(frozen=True, slots=True)
class CleanLines:
    """A clean log's sentences: text of each line, its byte offset and 1-based line number."""

    lines: list[str]  # every sentence line, without its line ending
    offsets: np.ndarray  # byte offset of each line in the log
    numbers: np.ndarray  # 1-based line number of each line in the log
    buf: np.ndarray  # the log's bytes
    count: int  # lines in the log, blank ones too (the end of the last line is no line)

    def heads(self, width: int) -> np.ndarray:
        """The `width` bytes after each line's '$' (bytes past the log's end read as NUL), as S<width>."""
        pos = self.offsets[:, None] + 1 + np.arange(width)
        chunk = np.append(self.buf, np.zeros(width, np.uint8))[np.minimum(pos, len(self.buf) + width - 1)]
        return np.ascontiguousarray(chunk).view(f"S{width}").ravel()


def clean_lines(data: bytes) -> CleanLines | None:
    """The log's sentence lines if every non-empty line is a clean ``$...*HH`` sentence, else None."""
    text = data.decode("latin-1")
    raw = text.split("\n")
    lens = np.fromiter(map(len, raw), dtype=np.int64, count=len(raw))
    starts = np.zeros(len(raw), dtype=np.int64)
    np.cumsum(lens[:-1] + 1, out=starts[1:])
    buf = np.frombuffer(data, dtype=np.uint8)
    if not len(buf):
        return None
    last = np.maximum(starts + lens - 1, 0)
    cr = (lens > 0) & (buf[np.minimum(last, len(buf) - 1)] == 13)
    size = lens - cr  # without '\r'
    keep = size > 0
    if not keep.any() or (cr & ~keep).any():
        return None  # nothing, or a line of just '\r' (the per-line path decides those)
    idx = np.flatnonzero(keep)
    s, n = starts[idx], size[idx]
    if (n < 10).any():
        return None
    for ch, where in ((ord("$"), s), (ord("*"), s + n - 3)):
        pos = np.flatnonzero(buf == ch)
        # exactly one of each per kept line, at its place; none on the skipped (empty) lines
        if len(pos) != len(idx) or not np.array_equal(pos, where):
            return None
    hi, lo = HEX_VALUE[buf[s + n - 2]], HEX_VALUE[buf[s + n - 1]]
    if (hi < 0).any() or (lo < 0).any():
        return None
    pxor = np.frombuffer(prefix_xor(data), dtype=np.uint8)
    if not np.array_equal((hi << 4) | lo, pxor[s + n - 4] ^ pxor[s]):
        return None  # a bad checksum: a Reject, the per-line path's job
    # lines keep a '\r': it sits in the checksum field, which no parser reads
    lines = raw[:-1] if len(idx) == len(raw) - 1 and not keep[-1] else select(raw, idx) if len(idx) != len(raw) else raw
    return CleanLines(lines, s, idx + 1, buf, len(raw) - (raw[-1] == ""))


def field_table(lines: Sequence[str], width: int) -> list[list[str]] | None:
    """Columns of `width` fields (address first, checksum last) of lines all holding width - 1 fields."""
    if not lines:
        return [[] for _ in range(width)]
    flat = ",".join(lines).replace("*", ",").split(",")
    if len(flat) != width * len(lines):
        return None
    columns = [flat[k::width] for k in range(width)]
    # each line has one '$', its first field: if all of them fall in column 0, every line has `width` fields
    if not all(a[:1] == "$" for a in set(columns[0])):
        return None
    return columns


def select(lines: list[str], idx: np.ndarray) -> list[str]:
    """lines[i] for every i in idx, in that order."""
    if len(idx) == 0:
        return []
    if len(idx) == 1:
        return [lines[int(idx[0])]]
    return list(itemgetter(*idx.tolist())(lines))


