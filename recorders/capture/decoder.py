"""A live stream through the converter `record` uses for its format, as the bytes arrive.

Converters take a whole log and keep state across records (epochs grouped
by time, a burst closed by the next one, the date of the last RMC), so a
stream cannot be cut anywhere and decoded in pieces. Instead each decode
runs the converter over a window of the stream and keeps only what is
settled:

- the window starts at the record of the last output committed before the
  current frontier (and at least MIN_WARMUP bytes before it), so the epoch
  that straddles the frontier is decoded whole, with its predecessor's
  records as warm-up;
- of the items, those at or after the frontier are committed, except the
  trailing epoch (the outputs after the last change of log time, and
  whatever follows them): the next bytes may still belong to it.

Offsets and line numbers are rebased to the whole stream, so statistics
and diagnostics count as `record` counts a file. At the end (`final`)
everything left is committed, as `record` decodes a file to its end.

Text formats are decoded up to the last complete line; each line that has
no host-timestamp prefix gets one with its receive time (unless the log's
`prefix` is "none"), so formats without a clock of their own get one.
Binary formats are decoded as received.
"""

from __future__ import annotations

import time
from collections.abc import Iterable

from formats.lines import strip_prefix
from formats.records import Reject, Where
from formats.units import NS

from ..base import Converter, Ignored, LogContext, Output
from ..registry import is_binary

MIN_WARMUP = 256
HOLD_BYTES = 4096  # kept back while a window gives no output at all (noise, or a record still arriving)

Item = Output | Reject | Ignored


def stamp_prefix(t_ns: int, style: str) -> bytes:
    """A host-timestamp prefix `formats.lines` reads back as `t_ns`: ISO 8601 UTC, or Unix seconds."""
    sec, frac = divmod(t_ns, NS)
    if style == "unix":
        return f"{sec}.{frac:09d} ".encode()
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(sec)).encode() + f".{frac:09d}Z ".encode()


class StreamDecoder:
    """Feeds one live log's bytes to its converter; `decode` returns the newly settled items."""

    def __init__(self, convert: Converter, ctx: LogContext, sensor: str, fmt: str):
        self.convert, self.ctx = convert, ctx
        self.text = not is_binary(sensor, fmt)  # binary formats: no line cutting and no stamping
        self.stamp = self.text and ctx.prefix != "none"
        self._buf = bytearray()     # the decoded stream from offset `_base` on: the next window
        self._base = 0
        self._lines_before = 0      # newlines before `_base`
        self._frontier = 0          # items before it are committed
        self._partial = b""         # an unfinished line (text formats)
        self._windowed = True       # False once a converter gives an output without a position
        self._pending = False       # bytes since the last decode

    def feed(self, data: bytes, receive_ns: int) -> None:
        """Append bytes received at `receive_ns` (ns UTC)."""
        if not self.text:
            self._buf += data
            self._pending = True
            return
        data = self._partial + data
        cut = data.rfind(b"\n") + 1
        self._partial = data[cut:]
        if cut:
            self._append_lines(data[:cut], receive_ns)
            self._pending = True

    def _append_lines(self, lines: bytes, receive_ns: int) -> None:
        if not self.stamp:
            self._buf += lines
            return
        stamp = None
        style = self.ctx.prefix
        for line in lines.splitlines(keepends=True):
            text = line.decode("latin-1")
            if text.strip() and strip_prefix(text, style)[1] is None:
                if stamp is None:
                    stamp = stamp_prefix(receive_ns, style)
                self._buf += stamp
            self._buf += line

    @property
    def pending(self) -> bool:
        """True when bytes arrived since the last decode."""
        return self._pending

    def decode(self, final: bool = False) -> list[Item]:
        """The items settled since the last call (with `final`, every item left)."""
        if final and self._partial:
            self._append_lines(self._partial, time.time_ns())
            self._partial = b""
        self._pending = False
        if not self._buf or not (self._windowed or final):
            return []
        lines = self._lines_before
        items = [_rebase(item, self._base, lines) for item in self.convert(bytes(self._buf), self.ctx)]
        if any(type(i) is Output and i.where is None for i in items):
            self._windowed = False  # positions unknown: decode the whole stream once, at the end
            if not final:
                return []
        cut = len(self._buf) + self._base if final else self._cut(items)
        out = [i for i in items if self._frontier <= _offset(i) < cut]
        if cut > self._frontier:
            self._advance(items, cut)
        return out

    def _cut(self, items: list[Item]) -> int:
        """Where the unsettled tail starts: the trailing epoch's first output, or HOLD_BYTES from the end."""
        outputs = [i for i in items if type(i) is Output]
        end = self._base + len(self._buf)
        if not outputs:
            return max(self._frontier, end - HOLD_BYTES)
        last = outputs[-1].log_time_ns
        cut = _offset(outputs[-1])
        for o in reversed(outputs):
            if o.log_time_ns != last:
                break
            cut = min(cut, _offset(o))
        return cut

    def _advance(self, items: Iterable[Item], cut: int) -> None:
        """Move the frontier to `cut` and the next window's start before it; drop the bytes before that."""
        if not self._windowed:
            return
        before = [_offset(i) for i in items if type(i) is Output and _offset(i) < cut]
        anchor = min(max(before), cut - MIN_WARMUP) if before else cut - MIN_WARMUP
        if self.text:  # a line start
            anchor = self._buf.rfind(b"\n", 0, max(anchor - self._base, 0)) + 1 + self._base
        self._frontier = cut
        drop = anchor - self._base
        if drop > 0:
            self._lines_before += self._buf.count(b"\n", 0, drop)
            del self._buf[:drop]
            self._base = anchor


def _rebase(item: Item, base: int, lines: int) -> Item:
    """The item with its offset and line counted over the whole stream."""
    where = item.where
    if where is None or (base == 0 and lines == 0):
        return item
    moved = Where(where.offset + base, None if where.line is None else where.line + lines, where.host_time_ns)
    if isinstance(item, Reject):
        return Reject(moved, item.reason, item.bad_checksum)
    if isinstance(item, Ignored):  # frozen, like Reject
        return Ignored(moved, item.reason)
    item.where = moved
    return item


def _offset(item: Item) -> int:
    return item.where.offset if item.where is not None else 0
