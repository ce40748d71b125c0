"""NovAtel logs scanned (`formats.novatel.scan`) and grouped into timed epochs, for the GNSS and INS converters.

The fast paths' version of `recorders.gps.group_epochs` with `novatel_key`
and of `novatel_time`: an epoch is a dict {record kind: scanned tuple} in
arrival order; values sit at the positions of the record fields.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

from formats.gpstime import gps_to_unix_ns
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
