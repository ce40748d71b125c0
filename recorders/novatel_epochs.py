"""NovAtel logs scanned (`formats.novatel.scan`) and grouped into timed epochs, for the GNSS and INS converters.

The fast paths' version of `recorders.gps.group_epochs` with `novatel_key`
and of `novatel_time`: an epoch is a dict {record kind: scanned tuple} in
arrival order; values sit at the positions of the record fields.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from formats.gpstime import gps_to_unix_ns
from formats.novatel import columns as novatel_columns
from formats.novatel import scan as novatel_scan
from formats.records import Reject
from formats.units import archivable_ns

from .base import LogContext


def novatel_scan_epochs(data: bytes, ctx: LogContext, kinds: frozenset[str]
                        ) -> Iterator[dict[str, novatel_scan.Scanned] | Reject]:
    """`group_epochs(records, novatel_key)` over scanned logs of the given record kinds ('BestPos', ...)."""
    names = novatel_scan.KINDS
    epoch: dict[str, novatel_scan.Scanned] = {}
    epoch_time: tuple[int, int] | None = None
    for item in novatel_scan.scan(data, ctx.prefix):
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
    offset = ctx.clock_offset_ns
    try:
        times = [gps_to_unix_ns(w, s) + offset for w, s in zip(first_week.tolist(), first_sow.tolist())]
    except OverflowError:
        return None
    if not all(map(archivable_ns, times)):
        return None
    return ColumnEpochs(logs, epoch, starts, np.array(times, dtype=np.int64))


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
