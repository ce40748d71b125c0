"""The value checks of a block at once (`ValueChecks.passing`, `LogRecorder.add_block`) against one at a time."""

from __future__ import annotations

from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from formats import schemas as S
from formats.records import Reject, Where
from recorders.base import Ignored, Output
from recorders.manifest import parse_manifest
from recorders.record import FileStats, LogRecorder
from recorders.value_checks import _RULES, ValueChecks

T0 = 1476259200 * 10**9
CLASSES = [S.MESSAGE_CLASSES[name] for name in sorted(_RULES)] + [S.Log]

values = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -0.0, 1e-10, -1.0, 3e3,
                                                                                     20_000.0, 20_000.1, 91.0]))
times = st.one_of(st.just(T0), st.integers(-10, 2**64), st.sampled_from([0, 7_258_118_400 * 10**9]))


@st.composite
def messages(draw) -> object:
    cls = draw(st.sampled_from(CLASSES))
    msg = cls()
    for field in cls.DESCRIPTOR.fields:
        if field.type in (field.TYPE_DOUBLE, field.TYPE_FLOAT) and not field.is_repeated and draw(st.booleans()):
            setattr(msg, field.name, draw(values))
    if cls is S.MESSAGE_CLASSES["foxglove.LocationFix"] and draw(st.booleans()):
        msg.position_covariance.extend(draw(st.lists(values, min_size=9, max_size=9)))
        msg.position_covariance_type = draw(st.integers(0, 3))
    return msg


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(messages(), times), max_size=30), st.sampled_from([20_000.0, 500.0]))
def test_passing_is_problem_finding_nothing(items, max_range):
    block = ValueChecks(max_range).passing([m for m, _ in items], [t for _, t in items])
    one = ValueChecks(max_range)
    assert block == [one.problem(m, t) is None for m, t in items]


class Sink:
    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def write(self, topic, message, log_time_ns, publish_time_ns=None) -> None:
        self.calls.append((topic, message.SerializeToString(), log_time_ns, publish_time_ns))


@settings(max_examples=150, deadline=None)
@given(st.lists(st.one_of(st.tuples(messages(), times), st.sampled_from(["reject", "bad crc", "ignored"])),
                max_size=40), st.integers(1, 7))
def test_a_block_writes_what_its_items_one_by_one_write(items, cut):
    manifest = parse_manifest('[[vehicles]]\nname = "a"\nrole = "leader"\n[[vehicles.logs]]\nsensor = "gps"\n'
                              'format = "nmea"\npath = "a.log"\n', Path("/x/trial.toml"))
    log = manifest.logs()[0]
    outs = []
    for k, item in enumerate(items):
        where = Where(k, k + 1)
        if item == "reject":
            outs.append(Reject(where, "bad GGA sentence: x"))
        elif item == "bad crc":
            outs.append(Reject(where, "bad checksum '00'", bad_checksum=True))
        elif item == "ignored":
            outs.append(Ignored(where, "a reason"))
        else:
            message, t = item
            outs.append(Output(f"/a/{type(message).__name__}", message, t, t, where))
    results = []
    for by_block in (False, True):
        sink = Sink()
        stats = FileStats("a.log", "a", "gps", "nmea")
        rec = LogRecorder(sink, log, stats, T0)
        if by_block:
            for start in range(0, len(outs), cut):
                rec.add_block(outs[start:start + cut])
        else:
            for item in outs:
                rec.add(item)
        rec.finish()
        results.append((sink.calls, stats.as_json()))
    assert results[0] == results[1]
