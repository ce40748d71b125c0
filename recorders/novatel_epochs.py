"""NovAtel logs scanned (`formats.novatel_scan`) and grouped into timed epochs, for the GNSS and INS converters.

The fast paths' version of `recorders.gps.group_epochs` with `novatel_key`
and of `novatel_time`: an epoch is a dict {record kind: scanned tuple} in
arrival order; values sit at the positions of the record fields.
"""

from __future__ import annotations

from typing import Iterator

from formats.novatel import scan as novatel_scan
from formats.gpstime import gps_to_unix_ns
from formats.records import Reject, Where

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
        kind = names[item[0]]  # type: ignore[index]
        if kind not in kinds:
            continue
        sow = item[3]
        t = (item[2], round(sow * 1000) if sow - sow == 0.0 else -1)  # type: ignore[operator]
        if epoch and (kind in epoch or t != epoch_time):
            yield epoch
            epoch = {}
        if not epoch:
            epoch_time = t  # type: ignore[assignment]
        epoch[kind] = item  # type: ignore[assignment]
    if epoch:
        yield epoch


def novatel_scan_time(epoch: dict[str, novatel_scan.Scanned], ctx: LogContext) -> int | Reject:
    """`novatel_time` on scanned values."""
    first = next(iter(epoch.values()))
    week, sow = first[2], first[3]
    if week > 0 and sow - sow == 0.0:
        return gps_to_unix_ns(week, sow) + ctx.clock_offset_ns
    for item in epoch.values():
        if item[7] is not None:
            return item[7] + ctx.clock_offset_ns
    return Reject(Where(*first[5:]), "no time: GPS week 0 or unknown time status, and no host timestamp")
