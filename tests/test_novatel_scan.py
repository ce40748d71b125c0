"""NovAtel fast path: `novatel_scan.scan` against `novatel.decode`, the GNSS and SPAN converters against their references."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from formats.novatel import logs as nv
from formats.novatel import scan as novatel_scan
from formats.proto_encode import encode_columns, split
from formats.records import Reject
from formats.units import NS as S1
from recorders import gps, ins
from recorders.base import Batch, LogContext, Output, one_by_one
from recorders.value_checks import ValueChecks
from tests import reference_converters as reference

T0 = 1476259201_250_000_000  # 2016-10-12T08:00:01.25Z


def _comparable(value: object) -> object:
    """NaN made equal to itself (with its sign), tuples walked."""
    if isinstance(value, float) and value != value:
        return ("nan", math.copysign(1.0, value))
    if isinstance(value, tuple):
        return tuple(_comparable(v) for v in value)
    return value


def _reference(data: bytes, prefix: str) -> list:
    return [r if isinstance(r, Reject) else _comparable(novatel_scan.from_record(r)) for r in nv.decode(data, prefix)]


def _scanned(data: bytes, prefix: str) -> list:
    return [r if isinstance(r, Reject) else _comparable(r) for r in novatel_scan.scan(data, prefix)]


def _outputs(items) -> list:
    return [(o.topic, o.log_time_ns, o.publish_time_ns, o.where, o.message.SerializeToString())
            if isinstance(o, Output) else o for o in items]


def _resigned(line: str, at: int, char: str) -> str:
    """The line with one payload character replaced and its CRC made good again: odd fields, not bad CRCs."""
    star = line.rfind("*")
    payload = list(line[1:star])
    payload[at % len(payload)] = char
    text = "".join(payload)
    return f"{line[0]}{text}*{nv.crc32(text.encode('latin-1')):08x}\r\n"


_LINES = st.sampled_from([
    lambda t: nv.encode_bestposa(t, 45.7, 126.6, 120.0, undulation_m=-8.0),
    lambda t: nv.encode_bestposa(t, -45.7, -126.6, 12.0, solution_status="INSUFFICIENT_OBS", position_type="NONE"),
    lambda t: nv.encode_bestvela(t, 1.5, 45.0),
    lambda t: nv.encode_bestvela(t, 1.5, 45.0, solution_status="COLD_START"),
    lambda t: nv.encode_inspvaa(t, 45.7, 126.6, -10.0, 0.1, 0.2, 0.0, 1.0, 2.0, 93.0),
    lambda t: nv.encode_inspvaa(t, 45.7, 126.6, -10.0, 0.1, 0.2, 0.0, 1.0, 2.0, 93.0, short=True),
    lambda t: nv.encode_inspvaxa(t, 45.7, 126.6, -10.0, 0.1, 0.2, 0.0, 1.0, 2.0, 93.0, undulation_m=-8.0),
    lambda t: nv.encode_inspvaxa(t, 45.7, 126.6, -10.0, 0.1, 0.2, 0.0, 1.0, 2.0, 93.0, undulation_m=math.nan),
    lambda t: nv.encode_bestposa(t, 45.7, 126.6, 120.0)[:-5] + "0000\r\n",  # bad CRC
    lambda t: "2016-10-12T08:00:05.500Z " + nv.encode_bestvela(t, 1.0, 10.0),  # host prefix
    lambda t: "$GPGGA,080001.25,4542.0,N,12636.0,E,1,08,0.9,120.0,M,-8.0,M,,*4A\r\n",
    lambda t: "garbage\x00\r\n", lambda t: "[COM1]\r\n", lambda t: "#BESTPOSA,COM1;\r\n", lambda t: "\r\n",
    lambda t: nv.encode_ascii(nv.decode(nv.encode_bestposa(t, 1.0, 2.0, 3.0).encode()).__next__()).replace(
        "BESTPOS", "RANGE"),  # another log, CRC bad after the rename: a reject
])


@st.composite
def _log(draw) -> bytes:
    t, lines = T0, []
    for make, step, tweak in draw(st.lists(st.tuples(_LINES, st.integers(0, 2), st.one_of(
            st.none(), st.tuples(st.one_of(st.integers(0, 60), st.integers(0, 400)), st.sampled_from(list(",;*x0-9.\"A#%²"))))), max_size=25)):
        t += step * S1 // 2
        line = make(t)
        if tweak is not None and line.startswith(("#", "%")) and "*" in line:
            line = _resigned(line, *tweak)
        lines.append(line)
    data = "".join(lines).encode("latin-1")
    if draw(st.booleans()):  # binary logs in the file: the record path throughout
        rec = next(nv.decode(nv.encode_inspvaxa(t, 1.0, 2.0, 3.0, 0, 0, 0, 0, 0, 90).encode()))
        data += nv.encode_binary(rec) + nv.encode_binary(next(nv.decode(nv.encode_bestposa(t, 1, 2, 3).encode())))
    return data


@settings(max_examples=400, deadline=None)
@given(_log(), st.sampled_from(["auto", "none"]))
def test_scan_gives_what_decode_gives(data: bytes, prefix: str) -> None:
    assert _scanned(data, prefix) == _reference(data, prefix)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300))
def test_any_bytes_scan_as_decode_does(data: bytes) -> None:
    good = nv.encode_bestposa(T0, 1.0, 2.0, 3.0).encode()
    for blob in (data, good + data, data + b"\n" + good):
        assert _scanned(blob, "auto") == _reference(blob, "auto")


@settings(max_examples=200, deadline=None)
@given(_log(), st.integers(-2, 2))
def test_fast_novatel_paths_equal_the_record_based_references(data: bytes, offset_s: int) -> None:
    ctx = LogContext("boat", clock_offset_ns=offset_s * S1)
    assert _outputs(gps.convert_novatel(data, ctx)) == _outputs(reference.convert_novatel_reference(data, ctx))
    assert _outputs(ins.convert_span(data, ctx)) == _outputs(reference.convert_span_reference(data, ctx))


def assert_batch_is_its_items(batch: Batch) -> None:
    """A Batch's columns are its items' messages: topics in `order`, records in `keys`, times, the bytes each
    column encodes to, and the rows the value checks refuse."""
    outs = list(batch.outputs())
    assert all(type(o) is Output for o in outs)
    assert [batch.parts[j].topic for j in batch.order.tolist()] == [o.topic for o in outs]
    assert batch.keys.tolist() == [o.where.offset for o in outs]
    for part in batch.parts:
        mine = [o for o in outs if o.topic == part.topic]
        n = len(mine)
        assert part.log_times_ns.tolist() == [o.log_time_ns for o in mine]
        assert part.publish_times_ns.tolist() == [o.publish_time_ns for o in mine]
        assert split(*encode_columns(part.message_class, n, part.columns)) == [o.message.SerializeToString()
                                                                               for o in mine]
        checks = ValueChecks()
        refused = checks.refused_rows(part.message_class, n, part.columns, part.log_times_ns).tolist()
        assert refused == [checks.problem(o.message, o.log_time_ns) is not None for o in mine]


@settings(max_examples=200, deadline=None)
@given(_log(), st.integers(-2, 2))
def test_novatel_gnss_batches_are_their_items_and_the_reference(data: bytes, offset_s: int) -> None:
    ctx = LogContext("boat", clock_offset_ns=offset_s * S1, batches=True)
    items = list(gps.convert_novatel(data, ctx))
    for item in items:
        if type(item) is Batch and not item.one_by_one:
            assert_batch_is_its_items(item)
    assert _outputs(one_by_one(items)) == _outputs(reference.convert_novatel_reference(data, ctx))


def test_a_long_novatel_log_comes_in_batches_of_bounded_size() -> None:
    lines = []
    for k in range(700):
        t = T0 + k * S1
        lines += [nv.encode_bestposa(t, 45.7 + k * 1e-6, 126.6, 120.0 + k, undulation_m=-8.0),
                  nv.encode_bestvela(t, 1.5, 45.0 + k % 360)]
    data = "".join(lines).encode()
    items = list(gps.convert_novatel(data, LogContext("boat", batches=True)))
    assert [type(item) for item in items] == [Batch, Batch, Batch]  # 2,100 messages: 1,024-odd a batch
    assert sum(len(item.order) for item in items) == 2100
    for item in items:
        assert_batch_is_its_items(item)
    assert _outputs(one_by_one(items)) == _outputs(reference.convert_novatel_reference(data, LogContext("boat")))
