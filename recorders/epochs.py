"""Records grouped into epochs: the rule every record-based epoch converter shares.

A receiver writes several records per epoch and their order varies, so an
epoch is a run of consecutive records: a record joins the open epoch unless
its kind is already in it or it carries a time different from the epoch's.
The fast paths (`recorders.gps`, `recorders.ins`, `recorders.novatel_epochs`)
apply the same rule inline on scanned tuples.
"""

from __future__ import annotations

from typing import Callable, Hashable, Iterable, Iterator, Protocol, TypeVar

from formats.records import Reject, Where

from .base import LogContext

R = TypeVar("R")


class Located(Protocol):
    """A record that knows where in its log it was read."""

    @property
    def where(self) -> Where: ...


def group_epochs(
    items: Iterable[R | Reject], key: Callable[[R], tuple[str, Hashable | None]]
) -> Iterator[list[R] | Reject]:
    """Consecutive records as epochs; `key` gives (kind, time or None). Rejects pass straight through.

    An epoch closes when a record's kind is already in it, or when the
    record has a time and the epoch has a different one.
    """
    epoch: list[R] = []
    kinds: set[str] = set()
    epoch_time: Hashable | None = None
    for item in items:
        if isinstance(item, Reject):
            yield item
            continue
        kind, t = key(item)
        if epoch and (kind in kinds or (t is not None and epoch_time is not None and t != epoch_time)):
            yield epoch
            epoch, kinds, epoch_time = [], set(), None
        epoch.append(item)
        kinds.add(kind)
        if epoch_time is None:
            epoch_time = t
    if epoch:
        yield epoch


def host_time_ns(records: Iterable[Located], ctx: LogContext) -> int | None:
    """The first host-timestamp prefix among the records, plus the clock offset."""
    for rec in records:
        host = rec.where.host_time_ns
        if host is not None:
            return host + ctx.clock_offset_ns
    return None
