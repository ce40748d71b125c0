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

from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from datetime import date
from pathlib import Path
from typing import Any

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


# a LogContext option set for text carried in a container (a ROS string topic): each line's host prefix is the
# container's stamp of its message, and is its time even where the vendor's record has a clock of its own (a
# Water Linked DVL's time_of_validity, then kept beside it)
CONTAINER_TIME = "container_time"

Converter = Callable[[bytes, LogContext], Iterator["Output | Reject | Ignored | SourceBatch"]]
# the same conversion over the log read in blocks (`formats.log_blocks`), for formats whose family module lists
# it in BLOCK_CONVERTERS: the recording then holds one block of the log, not all of it
BlockConverter = Callable[[Iterable[Block], LogContext], Iterator["Output | Reject | Ignored"]]
# a converter whose decoder reads lines of a `formats.log_blocks.LogText`: it takes the log in blocks as it is
TextConverter = Callable[[LogText, LogContext], Iterator["Output | Reject | Ignored"]]


def blockwise(convert: TextConverter) -> BlockConverter:
    """`convert` over the log's blocks: one loop over its lines, so whatever it carries from line to line
    (a burst, an ensemble, a day clock) goes on across blocks, and the outputs are the whole log's."""
    def over_blocks(blocks: Iterable[Block], ctx: LogContext) -> Iterator[Output | Reject | Ignored]:
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
