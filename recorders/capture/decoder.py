"""A live stream through the converter `record` uses for its format, as the bytes arrive.

Converters take a whole log and keep state across records (epochs grouped
by time, a burst closed by the next one, the date of the last RMC), so a
stream cannot be cut anywhere and decoded in pieces. Instead each decode
runs the converter over a window of the stream and keeps only what is
settled:

- the window starts at the record of the last output committed before the
  current frontier (and at least MIN_WARMUP bytes before it), so the epoch
  that straddles the frontier is decoded whole, with its predecessor's
  records as warm-up; but at most MAX_WARMUP bytes before it, so that a
  long run without any output (garbage) is not decoded again at every
  decode, nor kept in memory;
- of the items, those at or after the frontier are committed, except the
  trailing epoch (the outputs after the last change of log time, and
  whatever follows them, up to MAX_WARMUP bytes): the next bytes may still
  belong to it.

A budgeted window that settles nothing (one epoch longer than the budget)
is not converted again whole: the next window is twice as long, so the
bytes converted stay within twice the window that settles.

Offsets and line numbers are rebased to the whole stream, so statistics
and diagnostics count as `record` counts a file. At the end (`final`)
everything left is committed, as `record` decodes a file to its end.

Text formats are decoded up to the last complete line; each line that has
no host-timestamp prefix gets one with its receive time (unless the log's
`prefix` is "none"), so formats without a clock of their own get one.
Binary formats are decoded as received.

A text line is assembled per peer (each client of a listener), so lines of
two senders are never spliced; a peer that hangs up mid-line leaves its
unfinished line to the next connection (a sender that reconnects goes on
where it stopped). An unfinished line is kept in one growing buffer (linear
time) of at most MAX_LINE_BYTES: a longer one is dropped up to its newline
and counted as one reject.
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterable

from formats.lines import strip_prefix
from formats.records import Reject, Where
from formats.units import NS

from ..base import Converter, Ignored, LogContext, Output, one_by_one
from ..registry import is_binary

MIN_WARMUP = 256
MAX_WARMUP = 16 << 10
HOLD_BYTES = 4096  # kept back while a window gives no output at all (noise, or a record still arriving)
MAX_LINE_BYTES = 1 << 20  # an unfinished line longer than this is no record of any text format we decode

Item = Output | Reject | Ignored   # batches given one by one (`one_by_one`)
# a host-timestamp prefix starts with "[" or a digit (formats.lines); a line may start with one only then
_MAY_HAVE_PREFIX = re.compile(rb"\n[\[0-9]")
# a line that holds more than whitespace (str.strip's, latin-1): after a newline, or at the start
_BLANK = rb" \t\n\r\f\v\x1c-\x1f\x85\xa0"
_NOT_BLANK = rb"(?=[" + _BLANK.replace(b"\\n", b"") + rb"]*[^" + _BLANK + rb"])"
_NEXT_LINE = re.compile(rb"\n" + _NOT_BLANK)
_FIRST_LINE = re.compile(_NOT_BLANK)
_PREFIX_STARTS = frozenset(bytes([c]) for c in b"[0123456789")


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
        self._partials: dict[int, bytearray] = {}  # each peer's unfinished line (text formats)
        self._carry = bytearray()   # the unfinished line of a peer that hung up: the next one goes on with it
        self._skipping: set[int] = set()  # peers inside an overlong line: dropped up to its newline
        self._dropped: list[Item] = []    # rejects of overlong lines, given by the next decode
        self._windowed = True       # False once a converter gives an output without a position
        self._pending = False       # bytes since the last decode
        self._stretch = 1           # budgets per window: doubled while a budgeted window settles nothing
        self.converted = 0          # bytes given to the converter (windows overlap: warm-up, the held epoch)

    def feed(self, data: bytes, receive_ns: int, peer: int = 0) -> None:
        """Append bytes received at `receive_ns` (ns UTC) from `peer` (a listener's client; else 0)."""
        if not self.text:
            self._buf += data
            self._pending = True
            return
        part = self._partials.pop(peer, None)
        if part is None:
            part, self._carry = self._carry, bytearray()
        if peer in self._skipping:
            newline = data.find(b"\n")
            if newline < 0:
                self._partials[peer] = part
                return
            self._skipping.discard(peer)
            data = data[newline + 1:]
        cut = data.rfind(b"\n") + 1
        if cut:
            self._append_lines(bytes(part) + data[:cut] if part else data[:cut], receive_ns)
            part = bytearray(data[cut:])
            self._pending = True
        else:
            part += data
        if len(part) > MAX_LINE_BYTES:
            self._dropped.append(Reject(Where(self._base + len(self._buf)),
                                        f"a line of more than {MAX_LINE_BYTES} bytes without a newline: dropped"))
            part = bytearray()
            self._skipping.add(peer)
            self._pending = True
        self._partials[peer] = part

    def end_peer(self, peer: int) -> None:
        """A peer hung up: its unfinished line is left for the next connection to finish."""
        self._skipping.discard(peer)
        part = self._partials.pop(peer, None)
        if part:
            self._carry += part
            if len(self._carry) > MAX_LINE_BYTES:
                del self._carry[:]

    def _append_lines(self, lines: bytes, receive_ns: int) -> None:
        if not self.stamp:
            self._buf += lines
            return
        stamp = stamp_prefix(receive_ns, self.ctx.prefix)
        if lines[:1] not in _PREFIX_STARTS and not _MAY_HAVE_PREFIX.search(lines) \
                and lines.count(b"\r") == lines.count(b"\r\n"):
            # no line can start with a host prefix (the common case, "$GPGGA..."): every non-blank line
            # gets the stamp in one pass in C, as the loop below would give it
            if _FIRST_LINE.match(lines):
                self._buf += stamp
            self._buf += _NEXT_LINE.sub(b"\n" + stamp.replace(b"\\", b"\\\\"), lines)
            return
        style = self.ctx.prefix
        for line in lines.splitlines(keepends=True):
            text = line.decode("latin-1")
            if text.strip() and strip_prefix(text, style)[1] is None:
                self._buf += stamp
            self._buf += line

    @property
    def pending(self) -> bool:
        """True when bytes arrived since the last decode, or a budget left some undecoded."""
        return self._pending

    @property
    def backlog(self) -> int:
        """Bytes received and not yet settled (what a decode with a budget left behind, mostly)."""
        return self._base + len(self._buf) - self._frontier

    def shed(self, keep: int) -> int:
        """Give up decoding the oldest undecoded bytes so that at most about `keep` wait; the bytes given up.

        For a socket, which cannot be left unread the way a file waits on
        disk: its bytes are archived raw as they arrive, and only the live
        decode skips them (one counted reject says how many), so `record` of
        the capture still decodes them and memory stays bounded.
        """
        over = self.backlog - keep
        if over <= 0 or not self._windowed:
            return 0
        cut = self._frontier - self._base + over
        if self.text:  # at a line start
            newline = self._buf.find(b"\n", cut)
            cut = len(self._buf) if newline < 0 else newline + 1
        skipped = self._base + cut - self._frontier
        self._dropped.append(Reject(Where(self._frontier), f"{skipped} bytes arrived faster than they could be "
                                    "decoded live: archived, not decoded (`auvreplay record` of the capture "
                                    "decodes them)"))
        self._lines_before += self._buf.count(b"\n", 0, cut)
        del self._buf[:cut]
        self._base += cut
        self._frontier = self._base
        self._pending = True
        return skipped

    def decode(self, final: bool = False, budget: int | None = None) -> list[Item]:
        """The items settled since the last call (with `final`, every item left).

        With a `budget`, the window ends about that many bytes past what is
        settled (at a line end for text), as if the stream had ended there:
        the loop decodes a fast stream in slices between its reads, and the
        rest stays `pending`.
        """
        if final:
            for part in (*self._partials.values(), self._carry):
                if part:
                    self._append_lines(bytes(part), time.time_ns())
            self._partials, self._carry = {}, bytearray()
        self._pending = False
        dropped, self._dropped = self._dropped, []
        if not self._buf or not (self._windowed or final):
            return dropped
        budgeted = budget is not None and not final and self._windowed
        end = self._window_end(budget * self._stretch) if budget is not None and budgeted else len(self._buf)
        items = self._convert(end)
        self._pending = end < len(self._buf)
        if any(type(i) is Output and i.where is None for i in items):
            self._windowed = False  # positions unknown: decode the whole stream once, at the end
            if not final:
                return dropped
        if self._pending and self._cut(items, end) <= self._frontier:
            # an epoch longer than the window: the next window is twice as long (not this one converted again
            # whole), so a slice's work stays bounded and the bytes converted at most twice the settling window
            self._stretch *= 2
            return dropped
        self._stretch = 1
        cut = len(self._buf) + self._base if final else self._cut(items, end)
        out = [i for i in items if self._frontier <= _offset(i) < cut]
        if cut > self._frontier:
            self._advance(items, cut)
        return dropped + out

    def _window_end(self, budget: int) -> int:
        """Where a window of about `budget` new bytes ends in `_buf` (after a newline for text)."""
        want = self._frontier - self._base + budget
        if want >= len(self._buf):
            return len(self._buf)
        if not self.text:
            return want
        newline = self._buf.find(b"\n", want)
        return len(self._buf) if newline < 0 else newline + 1

    def _convert(self, end: int) -> list[Item]:
        lines = self._lines_before
        with memoryview(self._buf) as view:   # released here: `_advance` resizes the buffer
            data = bytes(view[:end])
        self.converted += end
        return [_rebase(item, self._base, lines) for item in one_by_one(self.convert(data, self.ctx))]

    def _cut(self, items: list[Item], window: int) -> int:
        """Where the unsettled tail starts: the trailing epoch's first output, or HOLD_BYTES from the end."""
        outputs = [i for i in items if type(i) is Output]
        end = self._base + window
        if not outputs:
            return max(self._frontier, end - HOLD_BYTES)
        last = outputs[-1].log_time_ns
        cut = _offset(outputs[-1])
        for o in reversed(outputs):
            if o.log_time_ns != last:
                break
            cut = min(cut, _offset(o))
        # an epoch followed by MAX_WARMUP bytes without an output is over: what follows it is not held
        return max(cut, end - MAX_WARMUP)

    def _advance(self, items: Iterable[Item], cut: int) -> None:
        """Move the frontier to `cut` and the next window's start before it; drop the bytes before that."""
        if not self._windowed:
            return
        before = [_offset(i) for i in items if type(i) is Output and _offset(i) < cut]
        anchor = min(max(before), cut - MIN_WARMUP) if before else cut - MIN_WARMUP
        anchor = max(anchor, cut - MAX_WARMUP)
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
