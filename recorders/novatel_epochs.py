"""NovAtel logs scanned (`formats.novatel.scan`) and grouped into timed epochs, for the GNSS and INS converters.

The fast paths' version of `recorders.gps.group_epochs` with `novatel_key`
and of `novatel_time`: an epoch is a dict {record kind: scanned tuple} in
arrival order; values sit at the positions of the record fields.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass, replace

import numpy as np

from formats.gpstime import gps_to_unix_ns, gps_to_unix_ns_column
from formats.lines import PREFIX_STYLES
from formats.novatel import columns as novatel_columns
from formats.novatel import logs as N
from formats.novatel import scan as novatel_scan
from formats.records import Reject
from formats.units import archivable_ns

from .base import Batch, LogContext


def novatel_scan_epochs(data: bytes, ctx: LogContext, kinds: frozenset[str], start: tuple[int, int] = (0, 1)
                        ) -> Iterator[dict[str, novatel_scan.Scanned] | Reject]:
    """`group_epochs(records, novatel_key)` over scanned logs of the given record kinds ('BestPos', ...), from
    `start` on (`novatel_scan.scan`)."""
    names = novatel_scan.KINDS
    epoch: dict[str, novatel_scan.Scanned] = {}
    epoch_time: tuple[int, int] | None = None
    for item in novatel_scan.scan(data, ctx.prefix, start):
        if isinstance(item, Reject):
            yield item
            continue
        name, _, week, sow, _, _, _, _ = item
        kind = names[name]
        if kind not in kinds:
            continue
        t = (week, round(sow * 1000) if math.isfinite(sow) else -1)
        if epoch and (kind in epoch or t != epoch_time):
            yield epoch
            epoch = {}
        if not epoch:
            epoch_time = t
        epoch[kind] = item
    if epoch:
        yield epoch


def implausible_week(week: int) -> str:
    """The reason for a GPS week that is no time of a trial (a 400-digit field)."""
    return f"GPS week {str(week)[:12]} is no time of a trial"


def novatel_scan_time(epoch: dict[str, novatel_scan.Scanned], ctx: LogContext) -> int | Reject:
    """`novatel_time` on scanned values."""
    first = next(iter(epoch.values()))
    _, _, week, sow, _, _, _, _ = first
    if week > 0 and math.isfinite(sow):
        try:
            t = gps_to_unix_ns(week, sow) + ctx.clock_offset_ns
        except OverflowError:
            t = -1
        return t if archivable_ns(t) else Reject(novatel_scan.where_of(first), implausible_week(week))
    for _, _, _, _, _, _, _, host in epoch.values():
        if host is not None:
            return host + ctx.clock_offset_ns
    return Reject(novatel_scan.where_of(first), "no time: GPS week 0 or unknown time status, and no host timestamp")


def novatel_publish_ns(item: novatel_scan.Scanned, t: int, ctx: LogContext) -> int:
    """A scanned log's publish time: its host time (offset applied), else its own time `t`."""
    _, _, _, _, _, _, _, host = item
    return t if host is None else host + ctx.clock_offset_ns


@dataclass(frozen=True, slots=True)
class ColumnEpochs:
    """`novatel_scan_epochs` over a clean file's columns: the logs of the kinds kept, grouped into epochs."""

    logs: np.ndarray    # the kept logs' positions in the columns, file order
    epoch: np.ndarray   # each kept log's epoch
    starts: np.ndarray  # each epoch's first log (a position in `logs`)
    t_ns: np.ndarray    # each epoch's time (`novatel_scan_time`, offset applied)


def novatel_column_epochs(cols: novatel_columns.NovatelColumns, ctx: LogContext, kinds: frozenset[str]
                          ) -> ColumnEpochs | None:
    """The epochs `novatel_scan_epochs` would group, with their times; None where the per-line path must decide
    (no log of the kinds, a kind twice in one time: the sequential rule splits there, or a time that is none)."""
    names = novatel_scan.KINDS
    kind_of = np.array([kind_code(names[n], kinds) for n in novatel_columns.NAMES], dtype=np.int64)
    kind = kind_of[cols.code]
    logs = np.flatnonzero(kind >= 0)
    if not len(logs):
        return None
    kind, week, sow = kind[logs], cols.week[logs], cols.seconds[logs]
    ms = np.rint(sow * 1000.0)  # round(sow * 1000): half to even, as Python's
    new = np.ones(len(logs), dtype=bool)
    new[1:] = (week[1:] != week[:-1]) | (ms[1:] != ms[:-1])
    epoch = np.cumsum(new) - 1
    for k in np.unique(kind).tolist():
        if (np.diff(epoch[kind == k]) <= 0).any():
            return None
    starts = np.flatnonzero(new)
    first_week, first_sow = week[starts], sow[starts]
    if (first_week <= 0).any():
        return None  # GPS week 0: the host time, or a Reject
    try:
        gps_ns = gps_to_unix_ns_column(first_week, first_sow)
    except OverflowError:
        return None
    if gps_ns is None or not -(1 << 62) < ctx.clock_offset_ns < 1 << 62:
        return None
    times = gps_ns + ctx.clock_offset_ns  # both within 2**62: no int64 wrap
    if not (archivable_ns(int(times.min())) and archivable_ns(int(times.max()))):
        return None
    return ColumnEpochs(logs, epoch, starts, times)


def kind_code(kind: str, kinds: frozenset[str]) -> int:
    """A record kind's number among `kinds` in sorted order, -1 for a kind not kept."""
    return sorted(kinds).index(kind) if kind in kinds else -1


def epoch_member(epochs: ColumnEpochs, cols: novatel_columns.NovatelColumns, names: tuple[str, ...]
                 ) -> tuple[np.ndarray, np.ndarray]:
    """For each epoch, its log of one of `names` (a position in the columns, -1 for none), and that log's row
    among its name's rows (-1 for none)."""
    n = len(epochs.starts)
    log, row = np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int64)
    for name in names:
        rows = cols.rows.get(name)
        if rows is None:
            continue
        at = np.searchsorted(epochs.logs, rows)
        found = at < len(epochs.logs)
        found[found] = epochs.logs[at[found]] == rows[found]
        e = epochs.epoch[at[found]]
        log[e], row[e] = rows[found], np.flatnonzero(found)
    return log, row


def scanned_epochs(cols: novatel_columns.NovatelColumns, epochs: ColumnEpochs, first: int, stop: int
                   ) -> list[dict[str, novatel_scan.Scanned]]:
    """Epochs first..stop-1 as `novatel_scan_epochs` gives them (dicts of scanned tuples), for the items of a
    Batch one by one."""
    names, kinds = novatel_columns.NAMES, novatel_scan.KINDS
    a = int(epochs.starts[first])
    b = int(epochs.starts[stop]) if stop < len(epochs.starts) else len(epochs.logs)
    at = epochs.logs[a:b]
    row_of = np.zeros(len(cols.code), dtype=np.int64)
    for rows in cols.rows.values():
        row_of[rows] = np.arange(len(rows))
    values = {name: [c.tolist() if isinstance(c, np.ndarray) else c for c in v] for name, v in cols.values.items()}
    out: list[dict[str, novatel_scan.Scanned]] = []
    last = -1
    for log, e in zip(at.tolist(), epochs.epoch[a:b].tolist()):
        name, row = names[int(cols.code[log])], int(row_of[log])
        item = (name, name + "A", int(cols.week[log]), float(cols.seconds[log]),
                tuple(c[row] for c in values[name]), int(cols.offsets[log]), int(cols.numbers[log]), None)
        if e != last:
            out.append({})
            last = e
        out[-1][kinds[name]] = item
    return out


def chunks(counts: np.ndarray, size: int) -> list[tuple[int, int]]:
    """Runs of epochs as `Rows` takes them: an epoch's messages (`counts`) added, the rows taken once they
    reach `size`."""
    out, first, held = [], 0, 0
    for e, c in enumerate(counts.tolist()):
        held += c
        if held >= size:
            out.append((first, e + 1))
            first, held = e + 1, 0
    if first < len(counts):
        out.append((first, len(counts)))
    return out


BLOCK_BYTES = 4 << 20  # the column path reads a clean file this much at a time: bounded memory

# the Batches of a clean block's epochs, each with its first epoch (`chunks`)
ColumnBuilder = Callable[[novatel_columns.NovatelColumns, ColumnEpochs, LogContext], list[tuple[int, Batch]]]


def novatel_column_path(data: bytes, ctx: LogContext, kinds: frozenset[str], build: ColumnBuilder
                        ) -> Generator[Batch, None, tuple[int, int] | None]:
    """A file's Batches from the column path, block by block (`BLOCK_BYTES`); returns None when it took the whole
    file, else where the per-line path must go on (offset, line number): from the start for a consumer of
    messages or a line prefix the column reader does not take, else at a block that is not clean.

    A block's last run of epochs (its last Batch, which may go on in the next block) is read again with the
    next block, so epochs and Batches are the whole file's, as the per-line path makes them.
    """
    if not (ctx.batches and ctx.prefix in PREFIX_STYLES):  # a consumer of messages, or lines the column reader
        return 0, 1                                          # does not take: the per-line path from the start
    if N._next_sync(data, 0) >= 0:  # binary logs: the record path reads the whole file
        return 0, 1
    start, line = 0, 1
    while start < len(data):
        end = len(data) if len(data) - start <= BLOCK_BYTES else data.rfind(b"\n", start, start + BLOCK_BYTES) + 1
        if end <= start:  # no line end in the window: the line whole
            found = data.find(b"\n", start + BLOCK_BYTES)
            end = len(data) if found < 0 else found + 1
        last = end == len(data)
        cols = novatel_columns.decode_columns(data[start:end], binary_checked=True)
        epochs = None if cols is None else novatel_column_epochs(cols, ctx, kinds)
        if cols is None or epochs is None:
            return start, line
        cols = replace(cols, offsets=cols.offsets + start, numbers=cols.numbers + (line - 1))
        batches = build(cols, epochs, ctx)
        if not batches:
            return start, line
        if not last:
            if len(batches) == 1 and end < len(data):
                return start, line  # one run in a whole block: the per-line path
            first, _ = batches.pop()
            log = int(epochs.logs[epochs.starts[first]])
            end, line_end = int(cols.offsets[log]), int(cols.numbers[log])
        else:
            line_end = line
        for _, batch in batches:
            yield batch
        start, line = end, line_end
    return None
