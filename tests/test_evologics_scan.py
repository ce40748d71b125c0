"""EvoLogics fast path: `host_lines.scan_lines`, `evologics_scan.scan` and the USBL converter on scanned
tuples, each judged by the record-based code it replaces, on built logs with damage and on any bytes."""

from __future__ import annotations

import math
from dataclasses import replace

from hypothesis import given, settings
from hypothesis import strategies as st

from formats import acoustic_messages as AM
from formats import host_lines
from formats.evologics import notifications as ev
from formats.evologics import scan as evs
from formats.lines import iter_lines
from formats.schemas import UsblObservation, timestamp
from recorders import modem, usbl
from recorders.base import Batch, LogContext, Output, one_by_one
from tests import reference_converters as reference
from tests.test_novatel_scan import assert_batch_is_its_items

PREFIXES = [
    "", "2016-10-12T02:00:03.263140Z ", "2016-10-12T23:59:59.5Z\t|", "[2016-10-12T02:00:03.263Z] ",
    "2016-10-12T02:00:03.2Z] ", "2016-10-12T02:00:60.1Z ", "2016-10-12 02:00:03,5Z ", "1476237603.25 ",
    "2016-13-12T02:00:03.2Z ", "2016-10-12T02:00:03.2+01:00 ", "2016-10-12T24:00:03.2Z ", "2016-10-12T02:00:03Z ",
    "2016-10-12T02:00:03.263140Z", "0000-10-12T02:00:03.1Z ",
]


def _where_tuples(data: bytes, prefix: str) -> list:
    return [(line.text, line.where.offset, line.where.line, line.where.host_time_ns) for line in iter_lines(data, prefix)]


def _scanned_lines(data: bytes, prefix: str) -> list:
    """scan_lines' tuples, their text offsets checked against the buffer and dropped."""
    out = []
    for text, offset, line, host, at in host_lines.scan_lines(data, prefix):
        assert data.decode("latin-1")[at : at + len(text)] == text and at >= offset
        out.append((text, offset, line, host))
    return out


_STYLES = st.sampled_from(["auto", "none", "iso8601", "unix"])


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(PREFIXES), st.text(max_size=12), st.sampled_from(["\n", "\r\n", "\r\r\n"])),
                max_size=12), _STYLES)
def test_scan_lines_equals_iter_lines(parts, prefix) -> None:
    data = "".join(p + text + end for p, text, end in parts).encode("utf-8")
    assert _scanned_lines(data, prefix) == _where_tuples(data, prefix)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=200), _STYLES)
def test_scan_lines_equals_iter_lines_on_any_bytes(data, prefix) -> None:
    assert _scanned_lines(data, prefix) == _where_tuples(data, prefix)


_LINES = st.sampled_from([
    lambda: ev.encode_usbllong(3, -1220.8, -896.4, 10.0, 1.04, current_time_s=603.26, measurement_time_s=603.24),
    lambda: ev.encode_usbllong(4, 1.0, 2.0, 0.0, 0.5, current_time_s=603.2, framed=True),
    lambda: ev.encode_usbllong(3, 1.0, 2.0, 0.0, 0.5, current_time_s=700.0, measurement_time_s=603.2),
    lambda: ev.encode_usblangles(3, 45.0, -10.0, current_time_s=603.2605, measurement_time_s=603.24),
    lambda: ev.encode_usblangles(4, 300.0, 5.0, current_time_s=603.2, framed=True),
    lambda: ev.encode_usblphyd(3, 0.4, -0.3, 75000.0, current_time_s=603.27, measurement_time_s=603.2405),
    lambda: ev.encode_usblphyd(3, 0.4, -0.3, 75000.0, current_time_s=603.3, measurement_time_s=603.2, framed=True),
    lambda: "USBLPHYD,603.27,603.24,3,0,16777215,-16777215,12,13,14,15,16,17\r\n",
    lambda: "USBLPHYP,603.27,603.24,3,0" + ",1.0" * 18 + "\r\n",
    lambda: ev.encode_delivered_im(5), lambda: ev.encode_delivered_im(6, framed=True),
    lambda: ev.encode_recvim(7, 3, b"hi\nthere"), lambda: ev.encode_recvim(8, 3, b"xy", framed=True),
    lambda: ev.encode_propagation_time(0.66), lambda: ev.encode_propagation_time(0.5, framed=False),
    lambda: "AT?T\r\n", lambda: "12345\r\n", lambda: "OK\r\n", lambda: "garbage \x00\xff\r\n",
    lambda: "+++AT:9:USBLLONG,\r\n", lambda: "RECVEND,1,2,-3,4\r\n",
])
# damage: a field emptied, padded, made non-finite, negative, oversized or not ASCII, a line cut short
_DAMAGE = st.sampled_from(["", " 1 ", "nan", "inf", "-5", "1e999", "\xb2", "1_0", "x", "+3", "-0.0"])


@st.composite
def _logs(draw) -> bytes:
    out = []
    for _ in range(draw(st.integers(0, 14))):
        line = draw(_LINES)()
        if draw(st.booleans()):
            fields = line.rstrip("\r\n").split(",")
            k = draw(st.integers(0, len(fields) - 1))
            fields[k] = draw(_DAMAGE) if draw(st.booleans()) else fields[k]
            line = ",".join(fields[: draw(st.integers(1, len(fields)))] if draw(st.booleans()) else fields) + "\r\n"
        out.append(draw(st.sampled_from(PREFIXES[:4])) + line)
    return "".join(out).encode("latin-1")


def _expected(data: bytes, prefix: str = "auto") -> str:
    """What `scan` must yield: `decode`'s records through `_scanned` (repr: NaN equals NaN)."""
    return repr([x for x in map(evs._scanned, ev.decode(data, prefix)) if x is not None])


@settings(max_examples=300, deadline=None)
@given(_logs())
def test_scan_equals_decode_on_built_logs_with_damage(data) -> None:
    assert repr(list(evs.scan(data))) == _expected(data)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300), _STYLES)
def test_scan_equals_decode_on_any_bytes(data, prefix) -> None:
    assert repr(list(evs.scan(data, prefix))) == _expected(data, prefix)


def _outputs(items: list) -> list:
    """Outputs and rejects as comparable values (messages as bytes: NaN != NaN)."""
    return [(o.topic, o.log_time_ns, o.publish_time_ns, o.where, o.message.SerializeToString())
            if isinstance(o, Output) else o for o in items]


@settings(max_examples=300, deadline=None)
@given(_logs(), st.sampled_from([{}, {"carrier_hz": 75000.0}, {"carrier_hz": 30000, "bearing_convention": "compass"}]),
       st.integers(-2, 2))
def test_fast_usbl_path_equals_the_record_based_reference(data, options, offset_s) -> None:
    ctx = LogContext("buoy1", options=options, address_book={3: "follower", 11: "buoy1"},
                     clock_offset_ns=offset_s * 1_000_000_000)
    fast = list(usbl.convert_evologics(data, ctx))
    expected = _outputs(list(reference.convert_usbl_evologics_reference(data, ctx)))
    assert _outputs(fast) == expected
    # as the recording takes them: Batches of observations (each one its items), in the same order
    items = list(usbl.convert_evologics(data, replace(ctx, batches=True)))
    for item in items:
        if type(item) is Batch and not item.one_by_one:
            assert_batch_is_its_items(item)
    assert _outputs(list(one_by_one(items))) == expected


_DOUBLE = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.just(-0.0), st.just(0.0))


@settings(max_examples=150, deadline=None)
@given(st.integers(-2**40, 2**62), st.text(max_size=5), st.text(max_size=5), st.text(max_size=5),
       st.lists(_DOUBLE, min_size=11, max_size=11))
def test_packed_usbl_observation_equals_the_keyword_constructor(t_ns, node, target, fmt, values) -> None:
    keys = ("travel_time_s", "range_m", "bearing_deg", "elevation_deg", "phase_x_rad", "phase_y_rad",
            "relative_east_m", "relative_north_m", "relative_up_m", "integrity", "rssi_db")
    ref = UsblObservation(timestamp=timestamp(t_ns), node=node, target=target, source_format=fmt,
                          **dict(zip(keys, values)))
    got = AM.usbl_observation(t_ns, node, target, fmt, *values)
    assert got.SerializeToString() == ref.SerializeToString()


def test_fast_mean_is_the_finite_values_mean() -> None:
    assert ev._nanmean((1e308, 1e308, -1.0, 2.0, 3.0)) == math.inf  # an overflow goes the list way, as before
    assert ev._nanmean((1.0, math.nan, 3.0)) == 2.0
    assert math.isnan(ev._nanmean((math.inf, -math.inf)))
    assert ev._nanmean((0.1, 0.2, 0.3)) == sum((0.1, 0.2, 0.3)) / 3


def test_non_ascii_digits_after_a_query_are_a_reject() -> None:
    recs = list(ev.decode("AT?T\r\n\xb2\r\n+++AT?T:1:\xb3\r\n".encode("latin-1")))
    assert [r.reason[:27] for r in recs] == ["AT?T reply is not a number "] * 2  # type: ignore[union-attr]


@settings(max_examples=300, deadline=None)
@given(_logs(), st.sampled_from([{}, {5: "leader1", 3: "follower", 11: "buoy1"}, {11: "buoy1", 12: "buoy1"}]),
       st.integers(-2, 2))
def test_fast_evologics_ranges_equal_the_record_based_reference(data, book, offset_s) -> None:
    ctx = LogContext("buoy1", address_book=book, clock_offset_ns=offset_s * 1_000_000_000, sound_speed_mps=1450.0)
    fast = list(modem.convert_evologics(data, ctx))
    assert _outputs(fast) == _outputs(list(reference.convert_modem_evologics_reference(data, ctx)))
