"""Micro-Modem fast path: `micromodem_scan.scan` and the range converter on scanned tuples, judged by
`micromodem.decode` and the record-based converter on built logs with damage and on any bytes."""

from __future__ import annotations

from collections import Counter
from dataclasses import replace
from datetime import date
from functools import partial

from hypothesis import given, settings
from hypothesis import strategies as st

from formats import acoustic_messages as AM
from formats.micromodem import scan as mms
from formats.micromodem import sentences as mm
from formats.nmea.framing import build
from formats.schemas import AcousticRange, timestamp
from recorders import modem
from recorders.base import Batch, Ignored, LogContext, Output, one_by_one
from tests import reference_converters as reference
from tests.test_novatel_scan import assert_batch_is_its_items

T0 = 1476237600 * 1_000_000_000  # 2016-10-12T02:00:00Z
_LINES = st.sampled_from([
    lambda t: mm.encode_ccmpc(3, 1), lambda t: mm.encode_campc(3, 2), lambda t: mm.encode_campa(1, 3),
    lambda t: mm.encode_campa(3, 1), lambda t: mm.encode_campr(1, 3, 0.2848), lambda t: mm.encode_campr(3, 1, 0.5),
    lambda t: mm.encode_campr(2, 4, 0.7, round_trip=True), lambda t: mm.encode_cccmd_png(3, 1),
    lambda t: mm.encode_cacmr_pnr(t, 1, 3, 0.3), lambda t: mm.encode_catoa(t), lambda t: mm.encode_cacyc(2, 3),
    lambda t: mm.encode_carxd(1, 3, b"\x01\x02"), lambda t: mm.encode_caclk(t),
    lambda t: build("CACMA", ["2016-10-12T02:00:01.5", "PNG", "2", "3", "56.7"]),
    lambda t: build("CAXST", "6,20161012,020001.2500,3,1,200,4000,25000,1,1,2,0,1,1,1,32".split(",")),
    lambda t: build("CACST", ("6,0,020002.5000,3,1,2,3,4,5,6,7,8,9,1,2,1,0,1,1,0,10,11,12,13,14,15,0.3,16,"
                              "25000,4000").split(",")),
    lambda t: build("CAREV", ["x"]), lambda t: "$CAMPR,1,3,0.2848\r\n", lambda t: "$CAMPR,1,3,0.2848*00\r\n",
    lambda t: "noise $CAMPA,2,3*5C\r\n", lambda t: "$CAMPR,1,3,0.2848*7b  \r\n", lambda t: "garbage\x00\xff\r\n",
])
# damage: a field emptied, padded, signed, made non-finite, negative or not ASCII, a line cut short
_DAMAGE = st.sampled_from(["", " 1", "+3", "-2", "nan", "inf", "-0.5", "\xb2", "1_0", "x", "0"])
_PREFIX = st.sampled_from(["", "2016-10-12T02:00:03.263140Z ", "[2016-10-12T02:00:03.2Z] ", "1476237603.25 "])


@st.composite
def _logs(draw) -> bytes:
    out, t = [], T0
    for _ in range(draw(st.integers(0, 14))):
        t += draw(st.integers(0, 3)) * 500_000_000
        line = draw(_LINES)(t)
        if draw(st.booleans()):
            fields = line.rstrip("\r\n").split("*")[0].split(",")
            k = draw(st.integers(0, len(fields) - 1))
            fields[k] = draw(_DAMAGE) if k else fields[k]
            body = ",".join(fields[: draw(st.integers(1, len(fields)))] if draw(st.booleans()) else fields)
            start = body.find("$")
            if start >= 0 and draw(st.booleans()):  # checksummed again, so the fast reading takes it
                address, *rest = body[start + 1 :].split(",")
                line = body[:start] + build(address, rest)
            else:
                line = body + "\r\n"
        out.append(draw(_PREFIX) + line)
    return "".join(out).encode("latin-1")


def _expected(data: bytes, prefix: str = "auto", round_trip: bool = False) -> str:
    """What `scan` must yield: `decode`'s records through `_scanned` (repr: NaN equals NaN)."""
    return repr([x for x in map(mms._scanned, mm.decode(data, prefix, round_trip)) if x is not None])


@settings(max_examples=300, deadline=None)
@given(_logs(), st.booleans())
def test_scan_equals_decode_on_built_logs_with_damage(data, round_trip) -> None:
    assert repr(list(mms.scan(data, "auto", round_trip))) == _expected(data, "auto", round_trip)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300), st.sampled_from(["auto", "none", "iso8601", "unix"]))
def test_scan_equals_decode_on_any_bytes(data, prefix) -> None:
    assert repr(list(mms.scan(data, prefix))) == _expected(data, prefix)


def test_repeated_texts_are_read_once_and_still_checked() -> None:
    line = "2016-10-12T02:00:03.2Z $CAMPA,1,3*5C\r\n"
    data = (line * 3 + line.replace("*5C", "*00") + line).encode()
    assert repr(list(mms.scan(data))) == _expected(data)
    assert [type(x).__name__ for x in mms.scan(data)] == ["tuple"] * 3 + ["Reject", "tuple"]


def _outputs(items: list) -> list:
    """Outputs and rejects as comparable values (messages as bytes: NaN != NaN)."""
    return [(o.topic, o.log_time_ns, o.publish_time_ns, o.where, o.message.SerializeToString())
            if isinstance(o, Output) else o for o in items]


_OPTIONS = st.sampled_from([{}, {"campr_travel_time": "round_trip"}, {"owtt_period_s": 2.0},
                            {"owtt_period_s": 1.5, "owtt_offset_s": 0.25, "sound_speed_mps": 1450.0}])
_BOOKS = st.sampled_from([{}, {1: "leader1", 2: "leader2", 3: "follower"}, {3: "follower", 4: "follower"}])


@settings(max_examples=300, deadline=None)
@given(_logs(), _OPTIONS, _BOOKS, st.sampled_from([None, date(2016, 10, 12)]), st.integers(-2, 2))
def test_fast_micromodem_path_equals_the_record_based_reference(data, options, book, day, offset_s) -> None:
    ctx = LogContext("follower", options=options, address_book=book, trial_date=day,
                     clock_offset_ns=offset_s * 1_000_000_000)
    fast = list(modem.convert_micromodem(data, ctx))
    assert _outputs(fast) == _outputs(list(reference.convert_micromodem_reference(data, ctx)))


@settings(max_examples=300, deadline=None)
@given(_logs(), _OPTIONS, _BOOKS, st.sampled_from([None, date(2016, 10, 12)]), st.integers(-2, 2))
def test_micromodem_batches_are_their_items_and_the_reference(data, options, book, day, offset_s) -> None:
    """Given as batches (the recording's way), the events and ranges are the items one by one: each batch's
    columns its items' messages, the items in order the record-based reference's (Ignored ones included)."""
    ctx = LogContext("follower", options=options, address_book=book, trial_date=day,
                     clock_offset_ns=offset_s * 1_000_000_000, batches=True)
    items = list(modem.convert_micromodem(data, ctx))
    for item in items:
        if type(item) is Batch and not item.one_by_one:
            assert_batch_is_its_items(replace(item, outputs=partial(_messages, item)))
            assert item.ignored == Counter(o.reason for o in item.outputs() if type(o) is Ignored)
    assert _outputs(list(one_by_one(items))) == _outputs(list(reference.convert_micromodem_reference(data, ctx)))


def test_a_long_micromodem_log_comes_in_batches_of_bounded_size() -> None:
    lines = [f"2016-10-12T02:{k // 60:02d}:{k % 60:02d}.5Z " + mm.encode_campr(1, 3, 0.25 + k * 1e-4)
             for k in range(1500)]
    lines[700] = "2016-10-12T02:11:40.5Z " + mm.encode_campc(3, 1)
    items = list(modem.convert_micromodem("".join(lines).encode(), LogContext("follower", batches=True)))
    assert [type(item) for item in items] == [Batch, Batch]
    assert [len(item.order) for item in items] == [1024, 476]
    assert [[part.topic for part in item.parts] for item in items] == [
        ["/follower/modem/events", "/follower/modem/range"], ["/follower/modem/range"]]
    assert items[0].order.tolist().count(0) == 1  # the event
    for item in items:
        assert_batch_is_its_items(item)


def _messages(batch: Batch) -> list[Output]:
    """A batch's items without the Ignored ones among them (counted in `Batch.ignored`)."""
    return [o for o in batch.outputs() if type(o) is not Ignored]


_DOUBLE = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.just(-0.0), st.just(0.0))
_INT32 = st.integers(-2**31, 2**31 - 1)


@settings(max_examples=150, deadline=None)
@given(st.integers(-2**40, 2**62), st.text(max_size=5), st.text(max_size=5), _INT32, _INT32,
       st.lists(_DOUBLE, min_size=3, max_size=3), st.text(max_size=5), st.text(max_size=5))
def test_packed_acoustic_range_equals_the_keyword_constructor(t_ns, src, dst, a, b, values, kind, fmt) -> None:
    tt, rng, c = values
    ref = AcousticRange(timestamp=timestamp(t_ns), source=src, destination=dst, source_address=a,
                        destination_address=b, travel_time_s=tt, range_m=rng, sound_speed_mps=c, kind=kind,
                        source_format=fmt)
    got = AM.acoustic_range(t_ns, src, dst, a, b, tt, rng, c, kind, fmt)
    assert got.SerializeToString() == ref.SerializeToString()
