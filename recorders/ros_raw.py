"""Every message of a ROS bag archived as itself, on ``/<vehicle>/ros/<topic>`` (the bag's topic path kept).

The message is the bag's own bytes on a ``ros1`` or ``cdr`` channel with its
type's ``ros1msg`` / ``ros2msg`` schema (`formats.ros_messages`), as rosbag2's
MCAP storage writes a bag: Foxglove, Rerun and the `mcap` library read every
topic without our code, /tf, markers and /rosout included. Messages mapped to
our schemas (`recorders.rosbag`) are archived as both: this one, and ours on the
vehicle's sensor topic.

Times: log time and publish time are both the bag's receive time (the time
rosbag2 stamps a message with), the log's clock offset applied; our decoded
messages take the header stamp as their log time instead (`recorders.rosbag`).

A topic that carries two types in one bag (ROS 1 allows it) keeps the first on
its path and puts each other below it, ``/<v>/ros/<topic>/<pkg>_<Type>``: one
channel, one schema.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Iterator

from formats.records import Reject, Where
from formats.ros_messages import TOPIC, RosMessage, RosSchema, topic_path
from formats.rosbag import BagMessage

from .base import Batch, Ignored, LogContext, Note, Output, SourceBatch
from .containers import EARLIEST_NS, LATEST_NS

# topics named with their counts in the recording's note; the rest are summed (the archive's info lists them all)
NOTE_TOPICS = 12
# a message waits in its topic's batch at most RAW_SPAN bag messages (well inside the window the recording counts
# distinct records in, record.RECORDS_WINDOW, with an Imu batch's IMU_SPAN), and the batches hold at most RAW_BYTES
RAW_SPAN = 1024
RAW_BYTES = 8 << 20


class RosTopics:
    """A bag's messages as themselves: the archive topic of each (bag topic, type), and the count of each.

    When the recording takes them (`LogContext.source_batches`), a topic's messages after its first go into one
    `SourceBatch` per topic, which it writes in one call and counts as one by one. The converter gives the batches
    out (`flush`) before anything the recording may refuse (a Reject, an Output outside 1980-2100: its diagnostic
    is stamped with the latest time archived) and when `due`, so each topic holds what it held message by message,
    in the same order, with the same counts.
    """

    def __init__(self, ctx: LogContext):
        self.ctx = ctx
        self.prefix = f"/{ctx.vehicle}/{TOPIC}/"
        self.offset_ns = ctx.clock_offset_ns
        self.topics: dict[tuple[str, RosSchema], str] = {}   # (bag topic, its type's schema) -> archive topic
        self.types: dict[str, str] = {}                      # archive topic -> its schema's text (one per channel)
        self.counts: Counter[str] = Counter()
        self.batching = ctx.source_batches
        self.batches: dict[str, SourceBatch] = {}
        self.seen: set[str] = set()   # topics whose first message went alone (its channel registered there)
        self.oldest = self.held = 0   # the number of the earliest bag message a batch holds; the bytes held

    def output(self, m: BagMessage, where: Where) -> Output | None:
        """The archive message of one bag message that decoded (its `schema` set), or None when it went into its
        topic's batch (counted when the batch is given out)."""
        schema = m.schema
        assert schema is not None
        topic = self.topics.get((m.topic, schema))
        if topic is None:
            topic = self._topic(m.topic, schema)
        t = m.bag_time_ns + self.offset_ns
        batch = self.batches.get(topic)
        if EARLIEST_NS <= t <= LATEST_NS and self.batching:
            if batch is None and topic in self.seen:
                if not self.batches:
                    self.oldest = where.message or 0
                times: list[int] = []   # log and publish times are the same: one list for both
                batch = self.batches[topic] = SourceBatch(topic, RosMessage(schema, b""), [], times, times, [])
            if batch is not None:
                data = m.data
                batch.payloads.append(data)
                batch.log_times_ns.append(t)
                batch.wheres.append(where)
                self.held += len(data)
                return None
            self.seen.add(topic)
        self.counts[topic] += 1
        return Output(topic, RosMessage(schema, m.data), t, t, where)

    def due(self, number: int) -> bool:
        """Whether the batches hold a message RAW_SPAN bag messages before message `number`, or RAW_BYTES."""
        return bool(self.batches) and (number - self.oldest >= RAW_SPAN or self.held >= RAW_BYTES)

    def flush(self) -> Iterator[SourceBatch]:
        """Every batch, each topic's messages in order."""
        counts = self.counts
        for batch in self.batches.values():
            batch.where = batch.wheres[-1]
            counts[batch.topic] += len(batch.payloads)
            yield batch
        self.batches = {}
        self.held = 0

    def released(self, items: Iterable[Output | Reject | Ignored | Batch]
                 ) -> Iterator[Output | Reject | Ignored | Batch | SourceBatch]:
        """The items, with the batches given out before each that the recording may refuse (a Reject, an Output
        outside 1980-2100 that `containers.checked_times` turns into one; a converter's Batch holds none of
        those, and where the value checks refuse one of its messages it goes one by one, as its Outputs would)."""
        for item in items:
            if self.batches and type(item) is not Batch and (type(item) is not Output or not (
                    EARLIEST_NS <= item.log_time_ns <= LATEST_NS and EARLIEST_NS <= item.publish_time_ns <= LATEST_NS)):
                yield from self.flush()
            yield item

    def _topic(self, bag_topic: str, schema: RosSchema) -> str:
        topic = self.prefix + topic_path(bag_topic)
        held = self.types.setdefault(topic, schema.schema)
        if held != schema.schema:   # a second type on one topic: a channel of its own below it
            topic += "/" + schema.schema_name.replace("/msg/", "/").replace("/", "_")
            self.types.setdefault(topic, schema.schema)
        self.topics[(bag_topic, schema)] = topic
        return topic

    def note(self, name: str, where: Where) -> Note | None:
        """One line for the recording: how many messages went to which topic, the busiest first."""
        if not self.counts:
            return None
        ranked = self.counts.most_common()
        shown = ", ".join(f"{t.removeprefix(self.prefix)} {n}" for t, n in ranked[:NOTE_TOPICS])
        rest = ranked[NOTE_TOPICS:]
        more = f", and {sum(n for _, n in rest)} on {len(rest)} more topics" if rest else ""
        return Note(where, f"{name}: {sum(self.counts.values())} messages archived as themselves on {self.prefix}...: "
                    f"{shown}{more}")

