"""recorders.gps and recorders.ins: epochs, covariance, time, signs, rejects."""

from __future__ import annotations

import math
from datetime import date

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import pashr, phins
from formats import schemas as S
from formats.nmea import sentences as nmea
from formats.nmea.framing import build
from formats.novatel import logs as novatel
from formats.records import Reject, Where
from formats.units import NS as S1
from recorders import gnss_covariance, gps, ins
from recorders.base import LogContext, Output
from tests import reference_converters as reference

DAY = date(2016, 10, 12)
MIDNIGHT = 1476230400 * 10**9  # 2016-10-12T00:00:00Z
T0 = MIDNIGHT + (8 * 3600 + 1) * 10**9 + 250_000_000  # 08:00:01.25


def run(conv, data: bytes, **kw) -> tuple[list[Output], list[Reject]]:
    ctx = LogContext("boat", **kw)
    out = list(conv(data, ctx))
    return [o for o in out if isinstance(o, Output)], [o for o in out if isinstance(o, Reject)]


def fixes(outs: list[Output]) -> list[Output]:
    return [o for o in outs if o.topic == "/boat/gps"]


def test_gst_after_gga_gives_a_known_diagonal_covariance_and_rmc_gives_the_date() -> None:
    data = (nmea.encode_gga(T0, 45.7, 126.6, hdop=0.9, altitude_msl_m=120.0, geoid_separation_m=-10.0)
            + nmea.encode_gst(T0, lat_std_m=1.5, lon_std_m=2.0, alt_std_m=3.0)
            + nmea.encode_rmc(T0, 45.7, 126.6, speed_knots=10.0, course_deg=90.0)
            + nmea.encode_hdt(33.0)).encode()
    outs, rejects = run(gps.convert_nmea, data, clock_offset_ns=-2 * S1)
    assert not rejects and [o.topic for o in outs] == ["/boat/gps", "/boat/gps/status", "/boat/gps/velocity"]
    fix, status, velocity = outs[0].message, outs[1].message, outs[2].message
    assert outs[2].log_time_ns == outs[0].log_time_ns and outs[2].where == outs[0].where
    assert velocity.velocity_north_mps == pytest.approx(0.0, abs=1e-12)
    assert velocity.velocity_east_mps == pytest.approx(10 * 1852 / 3600)
    assert velocity.course_over_ground_deg == 90.0 and math.isnan(velocity.velocity_up_mps)
    assert outs[0].log_time_ns == T0 - 2 * S1 == S.to_ns(fix.timestamp)
    assert (fix.latitude, fix.longitude, fix.altitude, fix.frame_id) == (45.7, 126.6, 110.0, "boat")
    assert list(fix.position_covariance) == [4.0, 0, 0, 0, 2.25, 0, 0, 0, 9.0]  # ENU: lon, lat, alt
    assert fix.position_covariance_type == S.COVARIANCE_DIAGONAL_KNOWN
    assert (status.fix_quality, status.satellites, status.hdop, status.heading_deg) == (1, 8, 0.9, 33.0)
    assert status.speed_over_ground_mps == pytest.approx(10 * 1852 / 3600)
    assert status.course_over_ground_deg == 90.0 and status.source_format == "nmea:GGA,GST,RMC,HDT"


def test_hdop_covariance_is_approximated_with_the_documented_uere() -> None:
    data = nmea.encode_gga(T0, 45.7, 126.6, hdop=1.5, quality=2).encode()
    outs, _ = run(gps.convert_nmea, data, trial_date=DAY)
    cov = list(fixes(outs)[0].message.position_covariance)
    h = 1.5 * gnss_covariance.UERE_M[2]
    assert cov == pytest.approx([h * h / 2, 0, 0, 0, h * h / 2, 0, 0, 0, 4 * h * h])
    assert fixes(outs)[0].message.position_covariance_type == S.COVARIANCE_APPROXIMATED
    outs, _ = run(gps.convert_nmea, data, trial_date=DAY, options={"uere_m": 2.0})
    assert fixes(outs)[0].message.position_covariance[0] == pytest.approx((1.5 * 2.0) ** 2 / 2)
    rmc_only, _ = run(gps.convert_nmea, nmea.encode_rmc(T0, 1.0, 2.0).encode())
    fix = fixes(rmc_only)[0].message
    assert fix.position_covariance_type == S.COVARIANCE_UNKNOWN and math.isnan(fix.position_covariance[0])
    assert math.isnan(fix.altitude)


def test_time_of_day_without_any_date_is_rejected_clearly() -> None:
    outs, rejects = run(gps.convert_nmea, nmea.encode_gga(T0, 45.7, 126.6).encode())
    assert not outs and len(rejects) == 1 and "no date" in rejects[0].reason and "manifest" in rejects[0].reason
    outs, rejects = run(gps.convert_nmea, nmea.encode_gga(T0, 45.7, 126.6).encode(), trial_date=DAY)
    assert not rejects and outs[0].log_time_ns == T0


def test_midnight_rollover_duplicates_and_out_of_order_are_kept() -> None:
    late = MIDNIGHT + 86399 * S1
    data = "".join([
        nmea.encode_gga(late - S1, 1.0, 2.0), nmea.encode_gga(late - S1, 1.0, 2.0),  # duplicated epoch
        nmea.encode_gga(late, 1.0, 2.0), nmea.encode_gga(late - 2 * S1, 1.0, 2.0),  # out of order
        nmea.encode_gga(late + S1, 1.0, 2.0), nmea.encode_gga(late + 2 * S1, 1.0, 2.0),  # past midnight
    ]).encode()
    outs, rejects = run(gps.convert_nmea, data, trial_date=DAY)
    times = [o.log_time_ns for o in fixes(outs)]
    assert not rejects
    assert times == [late - S1, late - S1, late, late - 2 * S1, late + S1, late + 2 * S1]


def test_one_fix_per_epoch_even_with_gga_gll_and_rmc() -> None:
    data = (nmea.encode_rmc(T0, 10.0, 20.0) + nmea.encode_gga(T0, 10.5, 20.5) + nmea.encode_gll(T0, 11.0, 21.0)
            + nmea.encode_gll(T0 + S1, 12.0, 22.0) + nmea.encode_zda(T0 + S1)).encode()
    outs, _ = run(gps.convert_nmea, data)
    assert [(f.message.latitude, f.log_time_ns) for f in fixes(outs)] == [(10.5, T0), (12.0, T0 + S1)]
    no_fix = nmea.encode_gga(T0, float("nan"), float("nan"), quality=0).encode()
    outs, _ = run(gps.convert_nmea, no_fix, trial_date=DAY)
    assert [o.topic for o in outs] == ["/boat/gps/status"] and outs[0].message.fix_quality == 0


def test_untimed_sentences_take_the_host_time_or_are_rejected() -> None:
    data = b"2016-10-12T08:00:05.500Z " + nmea.encode_hdt(12.5).encode() + nmea.encode_hdt(13.5).encode()
    outs, rejects = run(gps.convert_nmea, data, clock_offset_ns=S1)
    assert len(outs) == 1 and outs[0].message.heading_deg == 12.5
    assert outs[0].log_time_ns == outs[0].publish_time_ns == MIDNIGHT + 8 * 3600 * S1 + 6_500_000_000
    assert len(rejects) == 1 and "no time" in rejects[0].reason


def test_bad_checksums_and_garbage_become_rejects_not_outputs() -> None:
    good = nmea.encode_gga(T0, 1.0, 2.0)
    data = (good[:-4] + "00\r\n" + "\x00\x01garbage\r\n" + good).encode("latin-1")
    outs, rejects = run(gps.convert_nmea, data, trial_date=DAY)
    assert len(fixes(outs)) == 1 and [r.bad_checksum for r in rejects] == [True, False]


def test_novatel_bestpos_and_bestvel_share_an_epoch() -> None:
    data = (novatel.encode_bestposa(T0, 45.7, 126.6, 100.0, lat_std_m=0.5, lon_std_m=0.75, height_std_m=1.25,
                                    undulation_m=-8.0, position_type="NARROW_INT", satellites_used=12)
            + novatel.encode_bestvela(T0, 2.5, 135.0, -0.25)).encode()
    outs, rejects = run(gps.convert_novatel, data)
    assert not rejects and [o.topic for o in outs] == ["/boat/gps", "/boat/gps/status", "/boat/gps/velocity"]
    velocity = outs[2].message  # BESTVEL's velocity on a topic of its own: components, speed and course
    assert outs[2].log_time_ns == T0 and velocity.source_format == "novatel:BESTPOSA,BESTVELA"
    assert (velocity.speed_over_ground_mps, velocity.course_over_ground_deg, velocity.velocity_up_mps) == \
        (2.5, 135.0, -0.25)
    assert velocity.velocity_north_mps == pytest.approx(-2.5 * math.sqrt(0.5))
    assert velocity.velocity_east_mps == pytest.approx(2.5 * math.sqrt(0.5))
    fix, status = outs[0].message, outs[1].message
    assert outs[0].log_time_ns == T0  # GPS week/seconds back to UTC through the leap seconds (18 s)
    assert (fix.latitude, fix.longitude, fix.altitude) == (45.7, 126.6, 92.0)
    assert list(fix.position_covariance) == [0.5625, 0, 0, 0, 0.25, 0, 0, 0, 1.5625]
    assert (status.fix_quality, status.satellites, status.speed_over_ground_mps, status.course_over_ground_deg) == (4, 12, 2.5, 135.0)
    assert status.source_format == "novatel:BESTPOSA,BESTVELA"
    binary = novatel.encode_binary(next(r for r in novatel.decode(data) if isinstance(r, novatel.BestPos)))
    outs_b, _ = run(gps.convert_novatel, binary)
    assert fixes(outs_b)[0].message.latitude == 45.7 and outs_b[1].message.source_format == "novatel:BESTPOSB"


def test_phins_bursts_become_one_ins_state_each_with_our_sign_conventions() -> None:
    data = (phins.encode_epoch(T0, 45.7, -126.6, 12.5, 90.0, 1.0, 2.0, 1.0, 0.5, 0.25, heading_std_deg=0.02)
            + phins.encode_epoch(T0 + S1 // 10, 45.7, -126.6, 13.0, 91.0, 1.0, 2.0, 1.0, 0.5)).encode()
    outs, rejects = run(ins.convert_phins, data, trial_date=DAY)
    assert not rejects and len(outs) == 2 and outs[1].log_time_ns == T0 + S1 // 10
    m = outs[0].message
    assert (m.latitude, m.longitude, m.depth_m, m.altitude_m) == (45.7, pytest.approx(-126.6, abs=1e-9), 12.5, -12.5)
    assert (m.heading_deg, m.roll_deg, m.pitch_deg) == (90.0, 1.0, 2.0)
    assert (m.velocity_north_mps, m.velocity_east_mps, m.velocity_down_mps) == (1.0, 0.5, 0.25)
    assert (m.heading_std_deg, m.position_std_north_m, m.position_std_east_m) == (0.02, 1.0, 1.0)
    assert m.status.startswith("ALGSTS=00000045,00000000") and m.source_format == "phins"
    assert outs[1].message.depth_m == 13.0
    _, rejects = run(ins.convert_phins, data)
    assert len(rejects) == 2 and "TIME__" in rejects[0].reason and "date" in rejects[0].reason


def test_phins_burst_without_time_uses_the_host_time_and_phtro_fills_attitude() -> None:
    data = (b"1476259205.000 " + phins.encode_hehdt(10.0).encode() + b"1476259205.001 "
            + phins.encode_phtro(1.5, -2.0).encode() + phins.encode_hehdt(11.0).encode())
    outs, rejects = run(ins.convert_phins, data)
    assert len(outs) == 1 and outs[0].log_time_ns == 1476259205 * S1
    assert (outs[0].message.pitch_deg, outs[0].message.roll_deg, outs[0].message.heading_deg) == (1.5, -2.0, 10.0)
    assert len(rejects) == 1 and "host timestamp" in rejects[0].reason
    assert math.isnan(outs[0].message.latitude) and math.isnan(outs[0].message.depth_m)


def test_pashr_span_and_nmea_heading_sources() -> None:
    outs, _ = run(ins.convert_pashr, pashr.encode_pashr(T0, 10.0, 1.0, -2.0, heading_std_deg=0.2).encode(), trial_date=DAY)
    m = outs[0].message
    assert outs[0].log_time_ns == T0 and (m.heading_deg, m.roll_deg, m.pitch_deg, m.heading_std_deg) == (10.0, 1.0, -2.0, 0.2)
    assert math.isnan(m.latitude) and m.status == "gnss_quality=1 ins_status=1"
    span = (novatel.encode_inspvaa(T0, 45.7, 126.6, 30.0, 1.0, 2.0, 0.5, 0.1, 0.2, 300.0)
            + novatel.encode_inspvaxa(T0, 45.7, 126.6, 30.0, 1.0, 2.0, 0.5, 0.1, 0.2, 300.0, undulation_m=32.0)).encode()
    outs, rejects = run(ins.convert_span, span)
    assert not rejects and len(outs) == 1
    m = outs[0].message
    assert (m.altitude_m, m.depth_m, m.velocity_down_mps, m.heading_deg, m.heading_std_deg) == (30.0, 2.0, -0.5, 300.0, 0.2)
    assert m.source_format == "novatel:INSPVAA,INSPVAXA" and m.status == "INS_SOLUTION_GOOD INS_PSRSP"
    gyro = b"2016-10-12T08:00:01.250Z " + nmea.encode_hdt(271.5, talker="HE").encode()
    outs, _ = run(ins.convert_nmea, gyro)
    assert outs[0].log_time_ns == T0 and outs[0].message.heading_deg == 271.5
    ins_nmea = (nmea.encode_gga(T0, 45.7, 126.6) + nmea.encode_vtg(90.0, 2.0) + nmea.encode_hdt(88.0)).encode()
    outs, _ = run(ins.convert_nmea, ins_nmea, trial_date=DAY)
    m = outs[0].message
    assert (m.latitude, m.heading_deg) == (45.7, 88.0) and m.velocity_east_mps == pytest.approx(2 * 1852 / 3600)
    assert m.velocity_north_mps == pytest.approx(0.0, abs=1e-12)


def test_converter_tables() -> None:
    assert set(gps.CONVERTERS) == {"nmea", "novatel"}
    assert set(ins.CONVERTERS) == {"phins", "pashr", "novatel", "nmea"}


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=400), st.sampled_from([
    gps.convert_nmea, gps.convert_novatel, ins.convert_phins, ins.convert_pashr, ins.convert_span, ins.convert_nmea,
]))
def test_no_bytes_make_a_converter_raise(data: bytes, conv) -> None:
    prefix = nmea.encode_gga(T0, 1.0, 2.0).encode() + phins.encode_epoch(T0, 1, 2, 3, 4, 5, 6, 7, 8).encode()
    for blob in (data, prefix + data, data + prefix):
        for item in conv(blob, LogContext("boat", trial_date=DAY)):
            assert isinstance(item, (Output, Reject))


def _scanned_outputs(items: list) -> list:
    """Outputs and rejects as comparable values (messages as bytes: NaN != NaN)."""
    return [(o.topic, o.log_time_ns, o.publish_time_ns, o.where, o.message.SerializeToString())
            if isinstance(o, Output) else o for o in items]


_SENTENCES = st.sampled_from([
    lambda t: nmea.encode_gga(t, 45.7, 126.6, hdop=0.9, geoid_separation_m=-8.0),
    lambda t: nmea.encode_gga(t, float("nan"), float("nan"), quality=0),
    lambda t: nmea.encode_rmc(t, 45.7, -126.6, speed_knots=2.0, course_deg=10.0),
    lambda t: nmea.encode_rmc(t, 45.7, 126.6, valid=False),
    lambda t: nmea.encode_gll(t, -45.7, 126.6), lambda t: nmea.encode_gll(t, 45.7, 126.6, valid=False),
    lambda t: nmea.encode_gst(t, lat_std_m=1.0, lon_std_m=2.0, alt_std_m=3.0),
    lambda t: nmea.encode_zda(t), lambda t: nmea.encode_vtg(90.0, 3.0), lambda t: nmea.encode_hdt(12.0),
    lambda t: nmea.encode_ths(13.0, "V"), lambda t: nmea.encode_ths(14.0, "A"),
    lambda t: "$GPGSV,3,1,11,03,03,111,00*4B\r\n", lambda t: "garbage\x00\r\n",
    lambda t: nmea.encode_gga(t, 1.0, 2.0)[:-4] + "00\r\n",  # bad checksum
    lambda t: "2016-10-12T08:00:05.500Z " + nmea.encode_hdt(15.0),  # host prefix
    lambda t: "$GPGGA,1234,x*00\r\n", lambda t: "$GPRMC,,V,,,,,,,,,,N\r\n",  # bad fields, no checksum
])


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(_SENTENCES, st.integers(0, 3), st.booleans()), max_size=40),
       st.sampled_from([None, DAY]), st.integers(-2, 2), st.sampled_from([{}, {"uere_m": 2.0}]))
def test_fast_nmea_path_equals_the_record_based_reference(parts, day, offset_s, options) -> None:
    lines, t = [], T0 - 2 * S1
    for make, step, crlf in parts:
        t += step * S1 // 2  # repeats, half seconds and whole seconds: epochs open and close every way
        line = make(t)
        lines.append(line if crlf else line.replace("\r\n", "\n"))
    data = "".join(lines).encode("latin-1")
    ctx = LogContext("boat", trial_date=day, clock_offset_ns=offset_s * S1, options=options)
    fast, ref = list(gps.convert_nmea(data, ctx)), list(reference.convert_nmea_reference(data, ctx))
    assert _scanned_outputs(fast) == _scanned_outputs(ref)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300))
def test_scan_and_decode_agree_on_any_bytes(data: bytes) -> None:
    records = list(nmea.decode(data))
    scanned = list(nmea.scan(data))
    assert len(records) == len(scanned)
    for r, s in zip(records, scanned):
        if isinstance(r, Reject):
            assert r == s
        else:
            assert (type(r).__name__.upper(), r.talker, r.where) == (s[0], s[1], Where(*s[3:]))


_PHINS_LINES = st.sampled_from([
    lambda t: phins.encode_hehdt(10.0), lambda t: phins.encode_atitud(1.0, -2.0), lambda t: phins.encode_phtro(1.5, -2.0),
    lambda t: phins.encode_positi(45.7, 233.4, -12.5), lambda t: phins.encode_speed(0.5, 1.0, -0.1),
    lambda t: phins.encode_time(t), lambda t: phins.encode_stdhrp(0.1, 0.2, 0.3), lambda t: phins.encode_stdpos(1, 2, 3),
    lambda t: phins.encode_status("ALGSTS", 0x45, 1), lambda t: phins.encode_status("HT_STS", 7),
    lambda t: phins.encode_heave(0.0, 0.0, 0.0), lambda t: build("INTHS", ["12.0", "V"]), lambda t: build("HETHS", ["13.0", "A"]), lambda t: "garbage\x00\r\n",
    lambda t: phins.encode_atitud(1.0, 2.0)[:-4] + "00\r\n",  # bad checksum
    lambda t: "2016-10-12T08:00:05.500Z " + phins.encode_hehdt(15.0),  # host prefix
    lambda t: "$PIXSE,TIME__,x*00\r\n", lambda t: "$PIXSE,POSITI,1,2\r\n",  # bad fields, no checksum
])


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(_PHINS_LINES, st.integers(0, 2)), max_size=40), st.sampled_from([None, DAY]), st.integers(-2, 2))
def test_fast_phins_path_equals_the_record_based_reference(parts, day, offset_s) -> None:
    lines, t = [], T0
    for make, step in parts:
        t += step * S1 // 2
        lines.append(make(t))
    data = "".join(lines).encode("latin-1")
    ctx = LogContext("boat", trial_date=day, clock_offset_ns=offset_s * S1)
    fast, ref = list(ins.convert_phins(data, ctx)), list(reference.convert_phins_reference(data, ctx))
    assert _scanned_outputs(fast) == _scanned_outputs(ref)


_DOUBLE = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.just(-0.0), st.just(0.0))


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**62), st.text(max_size=5), st.text(max_size=5), st.lists(_DOUBLE, min_size=15, max_size=15))
def test_packed_ins_state_equals_the_keyword_constructor(t_ns, name, status, values) -> None:
    keys = ("latitude", "longitude", "depth_m", "roll_deg", "pitch_deg", "heading_deg", "velocity_north_mps",
            "velocity_east_mps", "velocity_down_mps", "heading_std_deg", "position_std_north_m", "position_std_east_m",
            "roll_std_deg", "pitch_std_deg", "altitude_m")
    ref = S.InsState(timestamp=S.timestamp(t_ns), frame_id=name, source_format="src", status=status, **dict(zip(keys, values)))
    assert S.ins_state(t_ns, name, "src", status, *values).SerializeToString() == ref.SerializeToString()


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**62), st.text(max_size=5), st.integers(-1, 9), st.integers(-1, 40), st.text(max_size=12),
       st.lists(_DOUBLE, min_size=4, max_size=4))
def test_packed_gnss_status_equals_the_keyword_constructor(t_ns, name, quality, sats, source, values) -> None:
    hdop, speed, course, heading = values
    ref = S.GnssStatus(timestamp=S.timestamp(t_ns), frame_id=name, fix_quality=quality, satellites=sats, hdop=hdop,
                       source_format=source, speed_over_ground_mps=speed, course_over_ground_deg=course,
                       heading_deg=heading)
    got = S.gnss_status(t_ns, name, quality, sats, hdop, source, speed, course, heading)
    assert got.SerializeToString() == ref.SerializeToString()
