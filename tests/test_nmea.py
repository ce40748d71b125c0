"""formats.nmea: published example sentences, quirks of real logs, round trips, no-raise."""

from __future__ import annotations

import math
from datetime import date

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.nmea import sentences as nmea
from formats.nmea.framing import build
from formats.records import Reject

# Published examples (NMEA 0183 references, receiver manuals) with their own checksums.
GGA = b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"
RMC = b"$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A\r\n"
ZDA = b"$GPZDA,201530.00,04,07,2002,00,00*60\r\n"
VTG = b"$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K*48\r\n"
GLL = b"$GPGLL,4916.45,N,12311.12,W,225444,A,*1D\r\n"
GST = b"$GPGST,172814.0,0.006,0.023,0.020,273.6,0.023,0.020,0.031*6A\r\n"
HDT = b"$HEHDT,116.581,T*25\r\n"
T0 = 1476259201250000000  # 2016-10-12T08:00:01.25Z


def one(data: bytes) -> object:
    out = list(nmea.decode(data))
    assert len(out) == 1, out
    return out[0]


def test_gga_published_example() -> None:
    r = one(GGA)
    assert isinstance(r, nmea.Gga)
    assert r.talker == "GP"
    assert r.time_s == 12 * 3600 + 35 * 60 + 19
    assert r.latitude == pytest.approx(48 + 7.038 / 60, abs=1e-12)  # 48.1173
    assert r.longitude == pytest.approx(11 + 31.0 / 60, abs=1e-12)  # 11.516667
    assert (r.quality, r.satellites, r.hdop) == (1, 8, 0.9)
    assert (r.altitude_msl_m, r.geoid_separation_m) == (545.4, 46.9)
    assert math.isnan(r.dgps_age_s) and r.dgps_station == ""
    assert (r.where.line, r.where.offset) == (1, 0)


def test_rmc_published_example() -> None:
    r = one(RMC)
    assert isinstance(r, nmea.Rmc) and r.valid
    assert r.date == date(1994, 3, 23)
    assert (r.speed_knots, r.course_deg) == (22.4, 84.4)
    assert r.magnetic_variation_deg == -3.1  # 3.1 W
    assert r.latitude == pytest.approx(48.1173, abs=1e-9)


def test_zda_vtg_gll_gst_hdt_published_examples() -> None:
    z = one(ZDA)
    assert z.date == date(2002, 7, 4) and z.time_s == 20 * 3600 + 15 * 60 + 30
    v = one(VTG)
    assert (v.course_true_deg, v.course_magnetic_deg, v.speed_knots, v.speed_kmh) == (54.7, 34.4, 5.5, 10.2)
    g = one(GLL)
    assert g.latitude == pytest.approx(49 + 16.45 / 60) and g.longitude == pytest.approx(-(123 + 11.12 / 60))
    assert g.valid and g.time_s == 22 * 3600 + 54 * 60 + 44
    s = one(GST)
    assert (s.rms_m, s.semi_major_m, s.semi_minor_m, s.orientation_deg) == (0.006, 0.023, 0.020, 273.6)
    assert (s.lat_std_m, s.lon_std_m, s.alt_std_m) == (0.023, 0.020, 0.031)
    h = one(HDT)
    assert isinstance(h, nmea.Hdt) and h.heading_deg == 116.581 and h.talker == "HE"


def test_ths_and_nmea1_vtg() -> None:
    t = one(build("INTHS", ["123.45", "A"]).encode())
    assert isinstance(t, nmea.Ths) and (t.talker, t.heading_deg, t.mode) == ("IN", 123.45, "A")
    v = one(build("GPVTG", ["054.7", "034.4", "005.5", "010.2"]).encode())
    assert (v.course_true_deg, v.course_magnetic_deg, v.speed_knots, v.speed_kmh) == (54.7, 34.4, 5.5, 10.2)


def test_bad_checksum_is_flagged() -> None:
    r = one(GGA.replace(b"*47", b"*48"))
    assert isinstance(r, Reject) and r.bad_checksum and "checksum" in r.reason


def test_lowercase_and_missing_checksum_are_accepted() -> None:
    line = build("GPHDT", ["1.8", "T"])
    assert line.endswith("*3C\r\n")  # hex letters in the checksum
    assert isinstance(one((line[:-4] + line[-4:-2].lower() + "\r\n").encode()), nmea.Hdt)
    assert one(GGA.split(b"*")[0] + b"\r\n").latitude == pytest.approx(48.1173, abs=1e-9)


def test_truncated_records_are_rejected() -> None:
    for cut in (20, 40, len(GGA) - 4):
        r = one(GGA[:cut])
        assert isinstance(r, Reject), cut
    r = one(GGA[:30] + b"\r\n")  # no checksum, too few fields
    assert isinstance(r, Reject) and "truncated GGA" in r.reason


def test_empty_fields_are_nan_not_zero() -> None:
    r = one(build("GNGGA", ["", "", "", "", "", "0", "", "", "", "", "", "", "", ""]).encode())
    assert isinstance(r, nmea.Gga)
    assert all(math.isnan(x) for x in (r.time_s, r.latitude, r.longitude, r.hdop, r.altitude_msl_m))
    assert (r.quality, r.satellites) == (0, -1)
    rmc = one(build("GPRMC", ["", "V", "", "", "", "", "", "", "", "", "", "N"]).encode())
    assert not rmc.valid and rmc.date is None and math.isnan(rmc.speed_knots)


def test_mixed_talkers_garbage_and_other_families() -> None:
    data = b"".join([
        build("GNGGA", GGA.decode()[7:].split("*")[0].split(",")).encode(),
        b"\x00\xff\x13garbage\x8f\r\n",
        build("GLGSV", ["1", "1", "00"]).encode(),  # other sentence type: skipped
        build("PIXSE", ["ATITUD", "1.0", "2.0"]).encode(),  # proprietary: skipped
        b"#BESTPOSA,COM1,0;x*00000000\r\n",  # NovAtel: skipped
        b"\x8e\x24\x01noise$XYGGA,123520,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,\n",
        build("INHDT", ["359.9", "T"]).encode(),
        build("GAZDA", ["000001.00", "13", "10", "2016", "", ""]).encode(),
    ])
    out = list(nmea.decode(data))
    kinds = [type(r).__name__ for r in out]
    assert kinds == ["Gga", "Reject", "Reject", "Gga", "Hdt", "Zda"]
    assert [r.talker for r in out if not isinstance(r, Reject)] == ["GN", "XY", "IN", "GA"]
    assert out[1].where.line == 2 and "no NMEA sentence" in out[1].reason
    assert "malformed" in out[2].reason  # the '$' inside the noise


def test_host_prefixes_and_line_endings() -> None:
    data = b"2016-10-12T08:00:01.300Z " + GGA + b"[1476259202.5] " + HDT.replace(b"\r\n", b"\n") + b"\n\n" + RMC
    out = list(nmea.decode(data))
    assert [type(r).__name__ for r in out] == ["Gga", "Hdt", "Rmc"]
    assert out[0].where.host_time_ns == 1476259201300000000
    assert out[1].where.host_time_ns == 1476259202500000000
    assert out[2].where.line == 5 and out[2].where.host_time_ns is None
    assert list(nmea.decode(data, prefix="none"))[0].where.host_time_ns is None


def test_out_of_range_values_are_rejected() -> None:
    for fields in (
        ["123519", "9107.038", "N", "01131.000", "E", "1", "08", "0.9", "545.4", "M", "46.9", "M", "", ""],
        ["123519", "4867.038", "N", "01131.000", "E", "1", "08", "0.9", "545.4", "M", "46.9", "M", "", ""],
        ["253519", "4807.038", "N", "01131.000", "E", "1", "08", "0.9", "545.4", "M", "46.9", "M", "", ""],
        ["123519", "4807.038", "Q", "01131.000", "E", "1", "08", "0.9", "545.4", "M", "46.9", "M", "", ""],
    ):
        assert isinstance(one(build("GPGGA", fields).encode()), Reject)


def test_encoders_write_what_the_simulator_means() -> None:
    gga = nmea.encode_gga(T0, 45.7, -126.6, hdop=0.9, altitude_msl_m=120.5, geoid_separation_m=-10.2, satellites=9)
    assert gga == "$GPGGA,080001.25,4542.00000,N,12636.00000,W,1,09,0.9,120.50,M,-10.20,M,,*5F\r\n"
    rmc = one(nmea.encode_rmc(T0, 45.7, 126.6, speed_knots=3.2, course_deg=45.0).encode())
    assert rmc.date == date(2016, 10, 12) and rmc.time_s == 8 * 3600 + 1.25
    assert one(nmea.encode_zda(T0 - 1_250_000_000 - 8 * 3600 * 10**9 - 1).encode()).date == date(2016, 10, 12)


def _same_or_nan(a: float, b: float, tol: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or abs(a - b) <= tol


finite_or_nan = st.one_of(st.just(float("nan")), st.floats(0, 999, allow_nan=False))
utc = st.integers(315_964_800 * 10**9, 3_471_292_799 * 10**9)  # 1980..2079: two-digit RMC years


@settings(max_examples=150, deadline=None)
@given(utc, st.floats(-90, 90), st.floats(-180, 180), st.integers(0, 9), st.integers(0, 40),
       finite_or_nan, st.floats(-400, 9000), st.floats(-100, 100), st.sampled_from(["GP", "GN", "IN", "GA"]))
def test_gga_round_trip(t: int, lat: float, lon: float, q: int, sats: int, hdop: float, alt: float,
                        sep: float, talker: str) -> None:
    line = nmea.encode_gga(t, lat, lon, quality=q, satellites=sats, hdop=hdop, altitude_msl_m=alt,
                           geoid_separation_m=sep, talker=talker)
    r = one(line.encode())
    assert isinstance(r, nmea.Gga) and r.talker == talker
    assert abs(r.latitude - lat) <= 1e-7 and abs(r.longitude - lon) <= 1e-7
    # HDOP is written with one decimal: off by up to half a unit, plus the binary rounding of e.g. 1.25 - 1.2
    assert _same_or_nan(r.hdop, hdop, 0.05 + 1e-9) and abs(r.altitude_msl_m - alt) <= 0.005 + 1e-9
    again = nmea.encode_gga(round(r.time_s * 1e9), r.latitude, r.longitude, quality=r.quality,
                            satellites=r.satellites, hdop=r.hdop, altitude_msl_m=r.altitude_msl_m,
                            geoid_separation_m=r.geoid_separation_m, talker=r.talker)
    assert again == line


@settings(max_examples=150, deadline=None)
@given(utc, st.floats(-90, 90), st.floats(-180, 180), st.floats(0, 99), finite_or_nan, st.booleans())
def test_rmc_zda_round_trip(t: int, lat: float, lon: float, sog: float, cog: float, valid: bool) -> None:
    line = nmea.encode_rmc(t, lat, lon, speed_knots=sog, course_deg=cog, valid=valid)
    r = one(line.encode())
    # two decimals: half a step, plus the float error of a value on the rounding boundary (0.875 -> 0.88)
    assert isinstance(r, nmea.Rmc) and r.valid == valid and abs(r.speed_knots - sog) <= 0.005 + 1e-9
    from recorders.clock import date_to_ns

    t_back = date_to_ns(r.date) + round(r.time_s * 1e9)
    assert abs(t_back - t) <= 5_000_000 + 1  # centisecond time
    assert nmea.encode_rmc(t_back, r.latitude, r.longitude, speed_knots=r.speed_knots,
                           course_deg=r.course_deg, valid=r.valid) == line
    z = one(nmea.encode_zda(t).encode())
    assert date_to_ns(z.date) + round(z.time_s * 1e9) == t_back


@settings(max_examples=100, deadline=None)
@given(utc, finite_or_nan, finite_or_nan, finite_or_nan, st.floats(0, 359), st.floats(0, 359))
def test_gst_vtg_hdt_round_trip(t: int, a: float, b: float, c: float, course: float, heading: float) -> None:
    line = nmea.encode_gst(t, lat_std_m=a, lon_std_m=b, alt_std_m=c, rms_m=a)
    g = one(line.encode())
    assert _same_or_nan(g.lat_std_m, a, 5e-4) and _same_or_nan(g.alt_std_m, c, 5e-4)
    assert nmea.encode_gst(round(g.time_s * 1e9), lat_std_m=g.lat_std_m, lon_std_m=g.lon_std_m,
                           alt_std_m=g.alt_std_m, rms_m=g.rms_m) == line
    v = one(nmea.encode_vtg(course, 5.0).encode())
    assert nmea.encode_vtg(v.course_true_deg, v.speed_knots) == nmea.encode_vtg(course, 5.0)
    h = one(nmea.encode_hdt(heading, talker="HE").encode())
    assert abs(h.heading_deg - heading) <= 5e-4
    s = one(nmea.encode_ths(heading, "E").encode())
    assert s.mode == "E" and s.heading_deg == h.heading_deg
    ll = one(nmea.encode_gll(t, -12.5, 100.25).encode())
    assert (ll.latitude, ll.longitude, ll.valid) == (-12.5, 100.25, True)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_no_bytes_make_decode_raise(data: bytes) -> None:
    for r in nmea.decode(data):
        assert isinstance(r, (Reject, *nmea.TIMED, nmea.Vtg, nmea.Hdt, nmea.Ths))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.text(alphabet="$GPRMCAZDVTHSL*,.0123456789NESW-\r", max_size=40), max_size=8))
def test_no_sentence_like_text_makes_decode_raise(parts: list[str]) -> None:
    data = ("$GPGGA," + ",".join(parts) + "\n$GPRMC," + ",".join(parts)).encode("latin-1")
    list(nmea.decode(data))
    for address in ("GPGGA", "GPRMC", "GPZDA", "GPVTG", "GPGST", "GPHDT", "GPTHS", "GPGLL"):
        list(nmea.decode(build(address, parts).encode("latin-1")))


def test_a_flood_of_dollars_is_one_broken_line_and_glued_sentences_still_frame() -> None:
    # found by tests/fuzz/live.py: a line of a million '$' was a million rejects (a minute of CPU in capture)
    flood = b"noise" + b"$" * 1_000_000 + GGA[:-2] + b"$$" + b"$GP,x" * 3 + HDT[:-2] + b"$BAD*00" + b"$\r\n"
    out = list(nmea.decode(GGA + flood + GGA))
    kinds = [type(r).__name__ for r in out]
    assert kinds == ["Gga", "Reject", "Gga", "Reject", "Hdt", "Reject", "Reject", "Gga"]
    assert out[1].reason == "malformed sentence address '' and 999999 more broken pieces after it"
    assert out[3].reason == "malformed sentence address '' and 4 more broken pieces after it"
    assert out[5].bad_checksum and not out[6].bad_checksum  # a bad checksum is a sentence of its own
    assert {r.where.line for r in out[1:7]} == {2}


_STAMPS = st.sampled_from(["", "2016-10-12T08:00:01.250000000Z ", "2016-10-12T08:00:01Z ", "[2016-10-12 08:00:02]\t",
                           "1476259201.5 ", "[1476259202],", "2016-10-12T08:00:01+02:00 ", "2016-13-45T99:00:00Z ",
                           "1476259201.5 junk ", "1476259201.5  "])
_SENTENCES = st.sampled_from([GGA, RMC, VTG, ZDA, HDT, GST, GLL, b"$GPGSV,1,1,00*79\r\n", b"$PIXSE,ATITUD,1,2*00\r\n",
                              b"$GPGGA,1*00\r\n", b"$gpgga,x*00\r\n", b"$GPGGA,123519,4807.038,N*47\r\n", b"\r\n"])


@given(st.lists(st.tuples(_STAMPS, _SENTENCES), max_size=12), st.sampled_from(["auto", "iso8601", "unix", "none"]))
@settings(max_examples=300)
def test_a_prefixed_line_gives_what_the_line_without_its_prefix_gives(lines, prefix) -> None:
    # the reference: each line's prefix stripped by strip_prefix, the rest scanned alone, its host time put back
    from formats.lines import strip_prefix
    data = b"".join(stamp.encode() + sentence for stamp, sentence in lines)
    expected: list = []
    offset = 0
    for number, raw in enumerate(data.decode("latin-1").split("\n"), start=1):
        rest, host = (raw, None) if prefix == "none" or raw[:1] in "$#%" else strip_prefix(raw, prefix)
        if raw.strip() and not rest.strip():   # a stamp alone on its line: "no NMEA sentence" as before
            expected += nmea._scan_general(raw, offset, number, prefix)
        for item in nmea.scan(rest.encode("latin-1"), "none", base=offset, lines=number - 1):
            if isinstance(item, Reject):
                w = item.where
                expected.append(Reject(type(w)(w.offset, w.line, host), item.reason, item.bad_checksum))
            else:
                expected.append((*item[:5], host))
        offset += len(raw) + 1
    assert repr(list(nmea.scan(data, prefix))) == repr(expected)
