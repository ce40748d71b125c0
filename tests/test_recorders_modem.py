"""Modem and USBL recorders: archive messages, times, addresses and rejects from built logs."""

from __future__ import annotations

import math
from datetime import date

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import regex_lines as rx
from formats.evologics import notifications as ev
from formats.micromodem import sentences as mm
from formats.records import FormatError, Reject
from formats.units import NS as S
from recorders import modem, usbl
from recorders.base import Ignored, LogContext, Output

T0 = 1476259200_000_000_000  # 2016-10-12T08:00:00Z
BOOK = {1: "leader1", 2: "leader2", 3: "follower", 9: "buoy1"}


def ctx(vehicle: str = "follower", **kw: object) -> LogContext:
    base: dict = dict(trial_date=date(2016, 10, 12), address_book=BOOK)
    base.update(kw)
    return LogContext(vehicle, **base)


def run(conv: object, data: bytes, c: LogContext) -> tuple[list[Output], list[Reject]]:
    out = list(conv(data, c))  # type: ignore[operator]
    # the ranges; a modem log's events (/modem/events) are checked on their own
    return ([o for o in out if isinstance(o, Output) and not o.topic.endswith("/modem/events")],
            [o for o in out if isinstance(o, Reject)])


def test_micromodem_ping_range_time_and_endpoints() -> None:
    data = "".join(mm.ping_exchange_lines(T0, 3, 1, 0.4)).encode()
    (o,), rejects = run(modem.CONVERTERS["micromodem"], data, ctx(clock_offset_ns=2 * S))
    assert rejects == []
    assert o.topic == "/follower/modem/range"
    m = o.message
    assert (m.source, m.destination, m.source_address, m.destination_address) == ("leader1", "follower", 1, 3)
    assert m.travel_time_s == pytest.approx(0.4) and m.range_m == pytest.approx(600.0)
    assert (m.kind, m.source_format, m.sound_speed_mps) == ("ping", "micromodem", 1500.0)
    # reply logged at T0 + 0.4 s; range epoch = the remote's reply = T0, plus the clock offset
    assert o.log_time_ns == T0 + 2 * S and o.publish_time_ns == T0 + 2 * S + 400_000_000
    assert m.timestamp.seconds == 1476259202


def test_micromodem_options_swap_round_trip_and_sound_speed() -> None:
    line = mm.host_line(T0, mm.encode_campr(3, 1, 0.4, round_trip=True)).encode()  # pinger written first
    (o,), _ = run(modem.convert_micromodem, line, ctx(options={"campr_travel_time": "round_trip", "sound_speed_mps": 1450}))
    assert (o.message.source, o.message.travel_time_s) == ("leader1", pytest.approx(0.4))
    assert o.message.range_m == pytest.approx(0.4 * 1450)
    with pytest.raises(FormatError, match="campr_travel_time"):
        modem.convert_micromodem(line, ctx(options={"campr_travel_time": "both"}))
    with pytest.raises(FormatError, match="sound_speed_mps"):
        modem.convert_micromodem(line, ctx(options={"sound_speed_mps": "fast"}))


def test_micromodem_rejects_without_time_or_with_foreign_addresses() -> None:
    data = (mm.encode_campr(1, 3, 0.2) + mm.host_line(T0, mm.encode_campr(2, 1, 0.2))).encode()
    outs, rejects = run(modem.convert_micromodem, data, ctx())
    assert outs == []
    assert "no time" in rejects[0].reason and rejects[0].where.line == 1
    assert "neither is follower's" in rejects[1].reason


def test_mm2_reply_uses_its_own_time() -> None:
    data = mm.encode_cacmr_pnr(T0 + 500_000_000, 1, 3, 0.25).encode()
    (o,), _ = run(modem.convert_micromodem, data, ctx(clock_offset_ns=-S))
    assert o.log_time_ns == T0 + 250_000_000 - S
    assert o.publish_time_ns == o.log_time_ns  # no host time in the line


def test_synchronous_time_of_arrival_ranges() -> None:
    lines = [
        "$CAXST,6,20161012,080000.0000,3,1,200,4000,25000,1,3,2,0,1,1,1,32\r\n",  # gives the date
        "$CACST,6,0,080010.3000,3,1,2,3,4,5,6,7,8,9,1,2,3,0,1,1,0,10,11,12,13,14,15,0.3,16,25000,4000\r\n",
        mm.encode_cacyc(1, 3),
        mm.encode_catoa(T0 + 20 * S + 200_000_000),
    ]
    data = "".join(lines).encode()
    outs, rejects = run(modem.convert_micromodem, data, ctx(trial_date=None, options={"owtt_period_s": 1.0}))
    assert rejects == []
    a, b = outs
    assert (a.message.source, a.message.kind) == ("leader2", "toa")
    assert a.message.travel_time_s == pytest.approx(0.3) and a.log_time_ns == T0 + 10 * S + 150_000_000
    assert (b.message.source, b.message.travel_time_s) == ("leader1", pytest.approx(0.2))
    none, _ = run(modem.convert_micromodem, data, ctx())
    assert none == []  # without owtt_period_s a time of arrival is not a range


def test_time_of_arrival_needs_a_date() -> None:
    data = (mm.encode_cacyc(1, 3) + mm.encode_catoa(T0)).encode()
    _, (r,) = run(modem.convert_micromodem, data, ctx(trial_date=None, options={"owtt_period_s": 1}))
    assert "no date" in r.reason


def test_evologics_propagation_time_and_usbllong_ranges() -> None:
    data = (
        mm.host_line(T0, ev.encode_delivered_im(2))
        + mm.host_line(T0 + S, ev.encode_propagation_time(0.3))
        + ev.encode_propagation_time(0.3)
        + mm.host_line(T0 + 2 * S, ev.encode_usbllong(1, 30, 40, 0, 0.05, current_time_s=10.5, measurement_time_s=10.0))
    ).encode()
    outs, rejects = run(modem.CONVERTERS["evologics"], data, ctx())
    ping, fix = outs
    assert (ping.message.source, ping.message.kind, ping.message.travel_time_s) == ("leader2", "ping", pytest.approx(0.3))
    assert ping.log_time_ns == T0 + S - 300_000_000
    assert (fix.message.source, fix.message.kind, fix.message.range_m) == ("leader1", "usbl", pytest.approx(75.0))
    assert fix.log_time_ns == T0 + 2 * S - 500_000_000 - 50_000_000
    assert [r.reason for r in rejects] == ["no time: EvoLogics line without host timestamp"]


BENTHOS = (
    b"12:00:05.200 Range 1 to 2 : 500.1 m (Round-trip 666.8 ms)\n"
    b"12:00:10.000 modem busy\n"
    b"11:59:59.000 Range 1 to 2 : 499.0 m (Round-trip 665.3 ms)\n"
)


def test_regex_modem_converter_keeps_log_order() -> None:
    opts = {"pattern": rx.EXAMPLE_PATTERN, "time_format": "tod", "travel_time_scale": rx.EXAMPLE_SCALE}
    outs, rejects = run(modem.CONVERTERS["regex"], BENTHOS, ctx("leader1", options=opts))
    assert [r.reason for r in rejects] == ["no match"]
    first, second = outs
    assert (first.message.source, first.message.destination, first.message.kind) == ("leader2", "leader1", "user")
    assert first.message.travel_time_s == pytest.approx(0.3334)
    assert first.log_time_ns == T0 + 4 * 3600 * S + 5_200_000_000
    assert second.log_time_ns < first.log_time_ns  # out of order, kept as logged


def test_regex_errors() -> None:
    with pytest.raises(FormatError, match="does not compile"):
        modem.convert_regex(b"", ctx(options={"pattern": "(?P<source>"}))
    with pytest.raises(FormatError, match="'source'"):
        modem.convert_regex(b"", ctx(options={"pattern": r"(?P<range_m>\d+)"}))
    opts = {"pattern": rx.EXAMPLE_PATTERN}
    _, (r, _, _) = run(modem.convert_regex, BENTHOS, ctx(trial_date=None, options=opts))
    assert "no date" in r.reason


def _usbl_log() -> bytes:
    lines = [
        (T0, ev.encode_usbllong(3, 30.0, 40.0, -10.0, 0.034, current_time_s=100.3, measurement_time_s=100.0)),
        (T0 + 100_000_000, ev.encode_usblphyd(3, 1.5, -2.5, 75e3, current_time_s=100.4, measurement_time_s=100.0000005)),
        (T0 + 200_000_000, ev.encode_usblphyd(3, 0.5, 0.25, 75e3, current_time_s=105.1, measurement_time_s=105.0)),
        (T0 + 5 * S, ev.encode_usblangles(1, 135.0, -20.0, current_time_s=106.0, measurement_time_s=106.0)),
    ]
    return "".join(mm.host_line(t, s) for t, s in lines).encode()


def test_evologics_usbl_groups_one_measurement() -> None:
    outs, rejects = run(usbl.CONVERTERS["evologics"], _usbl_log(), ctx("buoy1", options={"carrier_hz": 75000}))
    assert rejects == []
    full, phases_only, angles = (o.message for o in outs)
    assert outs[0].topic == "/buoy1/usbl"
    assert (full.node, full.target, full.source_format) == ("buoy1", "follower", "evologics")
    assert full.range_m == pytest.approx(0.034 * 1500)
    assert full.bearing_deg == pytest.approx(math.degrees(math.atan2(30, 40)))
    assert full.elevation_deg == pytest.approx(math.degrees(math.atan2(-10, 50)))
    assert (full.relative_east_m, full.relative_north_m, full.relative_up_m) == (30, 40, -10)
    assert (full.phase_x_rad, full.phase_y_rad) == pytest.approx((1.5, -2.5), abs=1e-3)
    assert outs[0].log_time_ns == T0 - 300_000_000 - 34_000_000
    assert math.isnan(phases_only.range_m) and phases_only.phase_x_rad == pytest.approx(0.5, abs=1e-3)
    assert (angles.target, angles.bearing_deg, angles.elevation_deg) == ("leader1", pytest.approx(135.0), pytest.approx(-20.0))
    assert math.isnan(angles.phase_x_rad) and math.isnan(angles.travel_time_s)


def test_evologics_usbl_without_carrier_has_no_phases() -> None:
    outs, _ = run(usbl.convert_evologics, _usbl_log(), ctx("buoy1"))
    assert math.isnan(outs[0].message.phase_x_rad) and outs[0].message.range_m == pytest.approx(51.0)


def test_regex_usbl_converter() -> None:
    pattern = r"(?P<time>\S+) T(?P<target>\d+) E(?P<east_m>\S+) N(?P<north_m>\S+) U(?P<up_m>\S+) R(?P<range_m>\S+)"
    data = b"08:00:01.0 T3 E-10 N0 U-5 R11.18\n"
    (o,), _ = run(usbl.CONVERTERS["regex"], data, ctx("buoy1", options={"pattern": pattern}))
    m = o.message
    assert (m.target, m.bearing_deg, m.range_m) == ("follower", pytest.approx(270.0), pytest.approx(11.18))
    assert m.travel_time_s == pytest.approx(11.18 / 1500) and m.elevation_deg < 0
    assert math.isnan(m.phase_y_rad)
    with pytest.raises(FormatError, match="'target'"):
        usbl.convert_regex(b"", ctx(options={"pattern": r"(?P<range_m>\d+)"}))


@settings(max_examples=100, deadline=None)
@given(data=st.binary(max_size=400))
def test_no_input_makes_a_converter_raise(data: bytes) -> None:
    regex = {"pattern": r"(?P<time>\S+) (?P<source>\S+) (?P<travel_time_s>\S+)"}
    usbl_regex = {"pattern": r"(?P<time>\S+) (?P<target>\S+) (?P<bearing_deg>\S+)"}
    for conv, opts in (
        (modem.convert_micromodem, {"owtt_period_s": 1.0}), (modem.convert_evologics, {}),
        (modem.convert_regex, regex), (modem.convert_regex, {**regex, "time_format": "unix"}),
        (modem.convert_regex, {**regex, "time_format": "iso8601"}), (usbl.convert_evologics, {"carrier_hz": 26000}),
        (usbl.convert_regex, usbl_regex),
    ):
        for out in conv(data, ctx(options=opts)):
            assert isinstance(out, (Output, Reject, Ignored))   # Ignored: read whole, counted, not archived
