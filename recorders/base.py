"""The contract between the recording step and the sensor-family converters.

A converter turns one log file's bytes into archive messages. It is a plain
function ``convert(data: bytes, ctx: LogContext) -> Iterator[Output | Reject]``
registered in its family module's ``CONVERTERS`` mapping under the manifest's
format name (``recorders.gps.CONVERTERS["nmea"]``). Converters never raise on
bad records: they yield a `formats.records.Reject` and go on. A record's
outputs come together (per record, or per epoch as it closes): the recording
counts records parsed in a bounded window (`recorders.record.RecordCount`).

A line-based format's converter also takes the log in blocks: it is listed
in its module's ``BLOCK_CONVERTERS``, as is or through `blockwise` when its
decoder reads a `formats.log_blocks.LogText`; the recording then holds one
block of the log at a time, not the whole log.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from datetime import date
from pathlib import Path
from typing import Any

import numpy as np

from formats.log_blocks import Block, LogBlocks, LogText
from formats.nmea.counts import SentenceCounts
from formats.records import Reject, Where


@dataclass(frozen=True)
class LogContext:
    """What a converter knows about the log it converts (from the manifest)."""

    vehicle: str
    role: str = "follower"
    path: str = ""
    trial_date: date | None = None
    clock_offset_ns: int = 0     # added to every time: the log's clock offset, or its start (recorders.clock)
    time_base: str = "utc"       # "utc", or "sim"/"boot": the log's own clock counts from clock_offset_ns
    prefix: str = "auto"
    # format-specific keys from the manifest's [[vehicles.logs]] table
    options: Mapping[str, Any] = field(default_factory=dict)
    # modem address -> vehicle name, for every vehicle in the trial
    address_book: Mapping[int, str] = field(default_factory=dict)
    sound_speed_mps: float = 1500.0
    # the log's files on disk, in log order: for containers (ROS bags) that their library must open by path
    files: tuple[Path, ...] = ()
    # what the converter read, counted by kind and outcome (NMEA: every line by sentence address), for the
    # recording's statistics; a new one per context, shared by the contexts `replace` makes of it
    counts: SentenceCounts = field(default_factory=SentenceCounts, compare=False, repr=False)
    # the consumer takes `Batch` items (the recording step): a converter may then give a block of messages as
    # columns; everyone else gets the same messages as Outputs, one by one
    batches: bool = False
    # set by the recording, which writes `SourceBatch` items: a converter may then give its source messages so
    source_batches: bool = False

    def vehicle_for_address(self, address: int | None) -> str:
        """The vehicle name for a modem address, or 'addr<N>' when the manifest has none."""
        if address is None or address < 0:
            return ""
        return self.address_book.get(address, f"addr{address}")


@dataclass(slots=True)  # not frozen: built once per archive message, frozen's __setattr__ path costs
class Output:
    """One archive message: full topic, protobuf message, log and publish times (ns, UTC)."""

    topic: str
    message: Any
    log_time_ns: int
    publish_time_ns: int
    where: Where | None = None


@dataclass(slots=True)
class Columns:
    """One topic's messages of a `Batch`: their fields as columns (`formats.proto_encode.encode_columns`), times."""

    topic: str
    message_class: Any
    columns: dict[str, Any]  # field name -> a value per message (array or list), or one value for all
    log_times_ns: Any        # int64 array, one per message
    publish_times_ns: Any    # int64 array, one per message


@dataclass(slots=True)
class Batch:
    """A block of a converter's archive messages given as columns, not built one by one.

    The recorder checks the columns (`recorders.value_checks.ValueChecks.refused_rows`), encodes them
    (`formats.proto_encode`) and writes them in `order`; where a message would be refused, or anything the
    block does not carry must happen between its messages, it takes `outputs()` instead: the very same items
    one at a time, which decide. A batch holds no Reject: a block with one is given as items.
    """

    parts: list[Columns]
    order: Any               # per message, in write order: its part's number (int array)
    keys: Any                # per message, in write order: its record's byte offset (int array)
    where: Where             # the last message's record (for progress)
    outputs: Callable[[], Iterable[Output | Reject | Ignored]]  # never a Reject in practice (see above)
    ignored: dict[str, int] = field(default_factory=dict)  # records read and not archived, by reason
    one_by_one: bool = False  # the items must go one by one (the block's columns could not be made)


def batched(ctx: LogContext, batch: Batch | None) -> Iterator[Output | Reject | Ignored | Batch]:
    """`batch` itself for a consumer that takes batches (`LogContext.batches`), else its items one by one."""
    if batch is None:
        return iter(())
    return iter((batch,)) if ctx.batches else iter(batch.outputs())


def one_by_one(items: Iterable[Output | Reject | Ignored | Batch | SourceBatch]) -> Iterator[Output | Reject | Ignored]:
    """A converter's items with any batch given as its items one by one (for consumers typed without batches)."""
    for item in items:
        if type(item) is Batch or type(item) is SourceBatch:
            yield from item.outputs()
        else:
            yield item  # type: ignore[misc]


_INT64 = (-(1 << 63), (1 << 63) - 1)


def int64_times(times: Sequence[int | None], offset_ns: int = 0) -> np.ndarray | None:
    """Times plus an offset as an int64 column for a Batch; None when one is missing, or beyond int64 (the
    message-by-message path then keeps its own rules for it), or there are none."""
    if not len(times) or None in times:
        return None
    values = [t + offset_ns for t in times] if offset_ns else times  # type: ignore[operator]
    if min(values) < _INT64[0] or max(values) > _INT64[1]:  # type: ignore[type-var, operator]
        return None
    return np.array(values, dtype=np.int64)


@dataclass(frozen=True, slots=True)
class Ignored:
    """A record read whole and deliberately not archived (a topic nobody mapped, say): counted by reason.

    The recording lists each reason once with its count instead of one diagnostic per record.
    """

    where: Where
    reason: str


@dataclass(frozen=True, slots=True)
class Note(Ignored):
    """A line about the log as a whole (what a container held, topic by topic) in `reason`: kept in the log's
    notes and printed after the recording's table, once per log (an Ignored to whatever does not know it)."""


@dataclass(slots=True)
class SourceBatch:
    """Source messages of one archive topic, in order (a bag's messages as themselves, `recorders.ros_raw`): they
    carry no values to check, only their bytes, so the recording writes them in one call
    (`ArchiveWriter.write_serialized_batch`) and counts them as one Output each. `message` is one of them (its
    schema names the channel); `where` is the last one's, for progress."""

    topic: str
    message: Any
    payloads: list[bytes]
    log_times_ns: list[int]
    publish_times_ns: list[int]
    wheres: list[Where]
    where: Where | None = None

    def outputs(self) -> Iterator[Output]:
        """The same messages as one Output each (for a consumer that writes them one by one)."""
        for data, t, publish, where in zip(self.payloads, self.log_times_ns, self.publish_times_ns, self.wheres):
            yield Output(self.topic, replace(self.message, data=data), t, publish, where)


# a LogContext option set for text carried in a container (a ROS string topic): each line's host prefix is the
# container's stamp of its message, and is its time even where the vendor's record has a clock of its own (a
# Water Linked DVL's time_of_validity, then kept beside it)
CONTAINER_TIME = "container_time"

# (a Batch or SourceBatch only for a consumer that takes them: `LogContext.batches`, `.source_batches`)
Converter = Callable[[bytes, LogContext], Iterator["Output | Reject | Ignored | Batch | SourceBatch"]]
# the same conversion over the log read in blocks (`formats.log_blocks`), for formats whose family module lists
# it in BLOCK_CONVERTERS: the recording then holds one block of the log, not all of it
BlockConverter = Callable[[Iterable[Block], LogContext], Iterator["Output | Reject | Ignored | Batch"]]
# a converter whose decoder reads lines of a `formats.log_blocks.LogText`: it takes the log in blocks as it is
TextConverter = Callable[[LogText, LogContext], Iterator["Output | Reject | Ignored | Batch"]]


def blockwise(convert: TextConverter) -> BlockConverter:
    """`convert` over the log's blocks: one loop over its lines, so whatever it carries from line to line
    (a burst, an ensemble, a day clock) goes on across blocks, and the outputs are the whole log's."""
    def over_blocks(blocks: Iterable[Block], ctx: LogContext) -> Iterator[Output | Reject | Ignored | Batch]:
        return convert(LogBlocks(blocks), ctx)
    over_blocks.__doc__ = convert.__doc__
    return over_blocks


def output(ctx: LogContext, suffix: str, message: Any, t_ns: int, where: Where | None) -> Output:
    """An Output on /<vehicle>/<suffix>; publish time is the host time when the log has one.

    `t_ns` must already include the clock offset (see `recorders.clock`).
    """
    host = where.host_time_ns if where is not None else None
    publish = host + ctx.clock_offset_ns if host is not None else t_ns
    return Output(f"/{ctx.vehicle}/{suffix}", message, t_ns, publish, where)


ROWS_PER_BATCH = 1024  # messages a `Rows` holds before it is taken: bounded memory, numpy steps long enough


class Rows:
    """One topic's messages gathered as rows of their builder's arguments, taken as a Batch.

    A converter adds a row where it would build an Output, takes the Batch when
    `full` and before anything else it yields (a Reject), so the order of the
    log's items is kept. `build(t_ns, *values)` makes the message of a row: the
    Batch's message-by-message items are built by it, and its columns are the
    rows' values under `names` (the message's field names), plus `constants`.
    """

    __slots__ = ("topic", "message_class", "names", "build", "constants", "times", "publish", "offsets",
                 "values", "wheres")

    def __init__(self, topic: str, message_class: Any, names: tuple[str, ...], build: Callable[..., Any],
                 constants: Mapping[str, Any]):
        self.topic, self.message_class, self.names, self.build = topic, message_class, names, build
        self.constants = dict(constants)
        self.times: list[int] = []
        self.publish: list[int] = []
        self.wheres: list[Where] = []
        self.values: list[tuple] = []

    @property
    def full(self) -> bool:
        """Whether the rows should be taken now."""
        return len(self.times) >= ROWS_PER_BATCH

    def add(self, t_ns: int, publish_ns: int, where: Where, values: tuple) -> None:
        """One message: its log and publish times, its record and its builder's arguments after the time."""
        self.times.append(t_ns)
        self.publish.append(publish_ns)
        self.wheres.append(where)
        self.values.append(values)

    def take(self) -> Batch | None:
        """The rows so far as one Batch (None without any), and a fresh start."""
        if not self.times:
            return None
        times, publish, wheres, values = self.times, self.publish, self.wheres, self.values
        self.times, self.publish, self.wheres, self.values = [], [], [], []
        topic, build = self.topic, self.build

        def outputs() -> Iterator[Output]:
            for t, p, w, v in zip(times, publish, wheres, values):
                yield Output(topic, build(t, *v), t, p, w)

        log_ns, publish_ns = int64_times(times), int64_times(publish)
        if log_ns is None or publish_ns is None:  # a time beyond int64: the messages one by one
            return Batch([], np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), wheres[-1], outputs,
                         one_by_one=True)
        columns: dict[str, Any] = dict(self.constants)
        for name, column in zip(self.names, zip(*values)):
            columns[name] = list(column) if isinstance(column[0], str) else np.array(column, dtype=np.float64)
        columns["timestamp"] = log_ns
        return Batch([Columns(topic, self.message_class, columns, log_ns, publish_ns)],
                     np.zeros(len(times), dtype=np.int64), np.array([w.offset for w in wheres], dtype=np.int64),
                     wheres[-1], outputs)


def columns_batch(topic: str, message_class: Any, build: Callable[..., Any], constants: Mapping[str, Any],
                  names: tuple[str, ...], columns: Sequence[Any], log_ns: np.ndarray, publish_ns: np.ndarray,
                  offsets: np.ndarray, lines: np.ndarray) -> Batch:
    """The Batch `Rows` would take of the same messages, made from columns a converter computed at once: `columns`
    the builder's arguments after the time (a list of strings or a float array each, in `names`' order),
    `offsets` and `lines` each message's record (Where without a host time)."""
    def outputs() -> Iterator[Output]:
        values = [c if isinstance(c, list) else c.tolist() for c in columns]
        for t, p, offset, line, v in zip(log_ns.tolist(), publish_ns.tolist(), offsets.tolist(), lines.tolist(),
                                         zip(*values)):
            yield Output(topic, build(t, *v), t, p, Where(offset, line))

    cols: dict[str, Any] = dict(constants)
    cols.update(zip(names, columns))
    cols["timestamp"] = log_ns
    return Batch([Columns(topic, message_class, cols, log_ns, publish_ns)], np.zeros(len(log_ns), dtype=np.int64),
                 offsets, Where(int(offsets[-1]), int(lines[-1])), outputs)
