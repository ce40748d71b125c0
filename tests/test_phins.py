"""formats.phins: a PHINS burst as the vendor's examples show it, quirks, round trips, no-raise."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import phins
from formats.nmea.framing import build
from formats.records import Reject

# One PHINS standard burst as printed in the iXblue protocol description (checksums theirs).
BURST = b"""$HEHDT,116.581,T*25\r
$PIXSE,ATITUD,-1.641,-0.490*6D\r
$PIXSE,POSITI,53.10245714,8.83994382,-0.115*71\r
$PIXSE,SPEED_,-0.802,-1.243,0.000*6F\r
$PIXSE,UTMWGS,U,32,489284.019,5883680.109,-0.115*39\r
$PIXSE,HEAVE_,-0.000,-0.000,0.014*7C\r
$PIXSE,TIME__,003356.016693*64\r
$PIXSE,STDHRP,1.997,0.082,0.101*7C\r
$PIXSE,STDPOS,20563.20,18004.65,50.00*7D\r
$PIXSE,STDSPD,19.747,13.032,10.002*41\r
$PIXSE,ALGSTS,00000045,00004000*60\r
$PIXSE,STATUS,00000000,00000000*6F\r
$PIXSE,HT_STS,FFFD5551*46\r
"""
T0 = 1476259201250000000


def test_vendor_burst_decodes_field_by_field() -> None:
    out = list(phins.decode(BURST))
    assert [type(r).__name__ for r in out] == [
        "Heading", "Atitud", "Positi", "Speed", "Utmwgs", "Heave", "Time", "StdHrp", "StdPos", "StdSpd",
        "StatusWords", "StatusWords", "StatusWords",
    ]
    hdg, att, pos, spd, utm, heave, tm, hrp, stdpos, stdspd, alg, sts, ht = out
    assert (hdg.talker, hdg.heading_deg) == ("HE", 116.581)
    assert (att.roll_port_up_deg, att.pitch_bow_down_deg) == (-1.641, -0.490)
    assert (pos.latitude, pos.longitude, pos.altitude_m) == (53.10245714, 8.83994382, -0.115)
    assert (spd.east_mps, spd.north_mps, spd.up_mps) == (-0.802, -1.243, 0.0)
    assert (utm.lat_zone, utm.lon_zone, utm.east_m, utm.north_m) == ("U", 32, 489284.019, 5883680.109)
    assert heave.heave_m == 0.014
    assert tm.time_s == pytest.approx(33 * 60 + 56.016693, abs=1e-9)
    assert (hrp.heading_std_deg, hrp.roll_std_deg, hrp.pitch_std_deg) == (1.997, 0.082, 0.101)
    assert (stdpos.lat_std_m, stdpos.lon_std_m, stdpos.altitude_std_m) == (20563.20, 18004.65, 50.0)
    assert stdspd.up_std_mps == 10.002
    assert (alg.kind, alg.lsb, alg.msb) == ("ALGSTS", 0x45, 0x4000)
    assert (sts.kind, sts.lsb, sts.msb) == ("STATUS", 0, 0)
    assert (ht.kind, ht.lsb) == ("HT_STS", 0xFFFD5551)


def test_longitude_0_360_is_wrapped() -> None:
    r = list(phins.decode(build("PIXSE", ["POSITI", "45.00000000", "233.40000000", "-12.000"]).encode()))[0]
    assert r.longitude == pytest.approx(-126.6, abs=1e-12)
    assert phins.wrap_longitude(359.99999999) == pytest.approx(-1e-8, abs=1e-12)
    assert phins.wrap_longitude(180.0) == -180.0 and phins.wrap_longitude(-180.0) == -180.0
    assert phins.wrap_longitude(8.83994382) == 8.83994382  # untouched, every digit kept


def test_phtro_letters_become_signs() -> None:
    a, b = phins.decode(build("PHTRO", ["1.50", "M", "2.25", "B"]).encode() + build("PHTRO", ["0.75", "P", "3.00", "T"]).encode())
    assert (a.pitch_bow_up_deg, a.roll_port_up_deg) == (1.5, -2.25)
    assert (b.pitch_bow_up_deg, b.roll_port_up_deg) == (-0.75, 3.0)
    bad = list(phins.decode(build("PHTRO", ["1.50", "X", "2.25", "B"]).encode()))[0]
    assert isinstance(bad, Reject) and "direction" in bad.reason


def test_bad_checksum_truncation_empty_fields_garbage_and_other_sentences() -> None:
    data = (
        BURST.splitlines(keepends=True)[1].replace(b"*6D", b"*6E")  # bad checksum
        + b"$PIXSE,POSITI,53.1024\r\n"  # truncated, no checksum
        + b"\x00\x01\xfe\xff\r\n"  # binary noise
        + build("PIXSE", ["SPEED_", "", "1.0", ""]).encode()  # empty fields
        + build("PIXSE", ["DEPIN_", "732.811", "085832.643253"]).encode()  # not handled: skipped
        + build("GPGGA", ["1"]).encode()  # another family: skipped
        + build("INTHS", ["10.5", "V"]).encode()
    )
    out = list(phins.decode(data))
    assert [type(r).__name__ for r in out] == ["Reject", "Reject", "Reject", "Speed", "Heading"]
    assert out[0].bad_checksum and not out[1].bad_checksum and "POSITI" in out[1].reason
    assert math.isnan(out[3].east_mps) and out[3].north_mps == 1.0 and math.isnan(out[3].up_mps)
    assert (out[4].talker, out[4].heading_deg, out[4].mode) == ("IN", 10.5, "V")


def test_epoch_encoder_writes_a_full_burst() -> None:
    text = phins.encode_epoch(T0, 45.7, -126.6, 12.5, 90.0, 1.0, 2.0, 1.0, 0.5, 0.1)
    lines = text.split("\r\n")[:-1]
    assert len(lines) == 12 and lines[0] == "$HEHDT,90.000,T*16"
    assert "$PIXSE,ATITUD,1.000,-2.000*" in text  # pitch bow up -> PHINS bow down
    assert "$PIXSE,POSITI,45.70000000,233.40000000,-12.500*" in text
    assert "$PIXSE,SPEED_,0.500,1.000,-0.100*" in text
    assert "$PIXSE,TIME__,080001.250000*" in text
    assert not any(isinstance(r, Reject) for r in phins.decode(text.encode()))


@settings(max_examples=150, deadline=None)
@given(st.floats(-90, 90), st.floats(-180, 180), st.floats(-6000, 100), st.floats(0, 359.999),
       st.floats(-90, 90), st.floats(-90, 90), st.integers(0, 86_399_999_999) )
def test_encode_decode_round_trip(lat: float, lon: float, alt: float, hdg: float, roll: float, pitch: float, us: int) -> None:
    lines = [phins.encode_positi(lat, lon, alt), phins.encode_hehdt(hdg), phins.encode_atitud(roll, pitch),
             phins.encode_time(us * 1000), phins.encode_phtro(pitch, roll), phins.encode_stdpos(1.5, 2.5, 0.25),
             phins.encode_status("ALGSTS", 0x12345678, 0x9ABCDEF0)]
    pos, h, att, tm, tro, std, st_ = phins.decode("".join(lines).encode())
    assert abs(pos.latitude - lat) <= 5e-9 and abs(pos.altitude_m - alt) <= 5e-4
    assert abs((pos.longitude - lon + 180) % 360 - 180) <= 5e-9 and -180 <= pos.longitude < 180
    assert phins.encode_positi(pos.latitude, pos.longitude, pos.altitude_m) == lines[0]
    assert phins.encode_hehdt(h.heading_deg) == lines[1]
    assert phins.encode_atitud(att.roll_port_up_deg, att.pitch_bow_down_deg) == lines[2]
    assert tm.time_s == pytest.approx(us / 1e6, abs=1e-7)
    assert phins.encode_phtro(tro.pitch_bow_up_deg, tro.roll_port_up_deg) == lines[4]
    assert (std.lat_std_m, std.lon_std_m, std.altitude_std_m) == (1.5, 2.5, 0.25)
    assert (st_.lsb, st_.msb) == (0x12345678, 0x9ABCDEF0)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_no_bytes_make_decode_raise(data: bytes) -> None:
    list(phins.decode(data))


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(list(phins.PIXSE) + ["XXXXXX"]), st.lists(st.text(alphabet="0123456789.-ABFUMPTB", max_size=12), max_size=6))
def test_no_sentence_like_text_makes_decode_raise(kind: str, parts: list[str]) -> None:
    list(phins.decode(build("PIXSE", [kind, *parts]).encode("latin-1")))
    list(phins.decode(build("PHTRO", parts).encode("latin-1")))
    list(phins.decode(build("HEHDT", parts).encode("latin-1")))


def _as_scanned(r: object) -> object:
    """A decode() record as scan() gives it: (key, values, offset, line, host); Rejects as they are."""
    if isinstance(r, Reject):
        return r
    values = tuple(getattr(r, f) for f in r.__slots__ if f != "where")  # type: ignore[attr-defined]
    key = r.kind if isinstance(r, phins.StatusWords) else type(r).__name__  # type: ignore[attr-defined]
    return key, values, r.where.offset, r.where.line, r.where.host_time_ns  # type: ignore[attr-defined]


_LINES = st.sampled_from([
    *BURST.splitlines(keepends=True), b"$PHTRO,1.50,M,2.25,B*00\r\n", b"$PIXSE,POSITI,53.1024\r\n",
    BURST.splitlines(keepends=True)[1].replace(b"*6D", b"*6E"), b"1476259205.000 $HEHDT,10.000,T*14\r\n",
    b"$HE*HDT,1,T*00\r\n", b"$PIXSE,ATITUD,1,2*4b\n", b"$PIXSE,ATITUD,1,2* 4\n", b"\r\n", b"$$PIXSE\r\n",
    b"$pixse,ATITUD,1,2*00\r\n", b"$PIXSE,TIME__,256000.0*00\r\n",
])


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.binary(max_size=300), st.lists(st.one_of(_LINES, st.binary(max_size=8)), max_size=20).map(b"".join)))
def test_scan_and_decode_agree_on_any_bytes(data: bytes) -> None:
    scanned = [s if isinstance(s, Reject) else (s[0], tuple(s[1]), *s[2:]) for s in phins.scan(data)]
    assert repr(scanned) == repr([_as_scanned(r) for r in phins.decode(data)])  # repr: NaN == NaN
