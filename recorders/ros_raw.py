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

from .base import Ignored, LogContext, Note, Output, SourceBatch

# topics named with their counts in the recording's note; the rest are summed (the archive's info lists them all)
NOTE_TOPICS = 12


class RosTopics:
    """A bag's messages as themselves: the archive topic of each (bag topic, type), and the count of each."""

    def __init__(self, ctx: LogContext):
        self.ctx = ctx
        self.prefix = f"/{ctx.vehicle}/{TOPIC}/"
        self.topics: dict[tuple[str, RosSchema], str] = {}   # (bag topic, its type's schema) -> archive topic
        self.types: dict[str, str] = {}                      # archive topic -> its schema's text (one per channel)
        self.counts: Counter[str] = Counter()

    def output(self, m: BagMessage, where: Where) -> Output:
        """The archive message of one bag message that decoded (its `schema` set)."""
        schema = m.schema
        assert schema is not None
        topic = self.topics.get((m.topic, schema))
        if topic is None:
            topic = self._topic(m.topic, schema)
        self.counts[topic] += 1
        t = m.bag_time_ns + self.ctx.clock_offset_ns
        return Output(topic, RosMessage(schema, m.data), t, t, where)

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


# a source message waits in its topic's batch at most RAW_SPAN bag messages (well inside the window the recording
# counts distinct records in, record.RECORDS_WINDOW, with an Imu batch's IMU_SPAN), and the batches hold at most
# RAW_BYTES of messages
RAW_SPAN = 1024
RAW_BYTES = 8 << 20


def batched(items: Iterable[Output | Reject | Ignored]) -> Iterator[Output | Reject | Ignored | SourceBatch]:
    """The items, with the bag's messages as themselves (`RosTopics.output`) gathered into one `SourceBatch` per
    topic, which the recording writes in one call. A topic's first message goes alone (its channel is registered
    where it was), and every batch is given out before anything that is not an Output (a Reject's diagnostic is
    stamped with the latest time archived), so the archive holds what it held message by message: each topic's
    messages in the same order, the same counts."""
    batches: dict[str, SourceBatch] = {}
    seen: set[str] = set()
    oldest, held = 0, 0
    for item in items:
        if type(item) is Output and type(item.message) is RosMessage and item.where is not None:
            topic = item.topic
            batch = batches.get(topic)
            if batch is None:
                if topic not in seen:
                    seen.add(topic)
                    yield item
                    continue
                batch = batches[topic] = SourceBatch(topic, item.message, [], [], [], [])
                if len(batches) == 1:
                    oldest = item.where.message or 0
            data = item.message.data
            batch.payloads.append(data)
            batch.log_times_ns.append(item.log_time_ns)
            batch.publish_times_ns.append(item.publish_time_ns)
            batch.wheres.append(item.where)
            held += len(data)
            if (item.where.message or 0) - oldest >= RAW_SPAN or held >= RAW_BYTES:
                yield from _given_out(batches)
                held = 0
            continue
        if batches and type(item) is not Output:
            yield from _given_out(batches)
            held = 0
        yield item
    yield from _given_out(batches)


def _given_out(batches: dict[str, SourceBatch]) -> Iterator[SourceBatch]:
    for batch in batches.values():
        batch.where = batch.wheres[-1]
        yield batch
    batches.clear()
