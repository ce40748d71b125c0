"""formats.novatel: NovAtel's own example logs, CRC-32, headers, binary, quirks, round trips, no-raise."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import gpstime
from formats.gpstime import gps_to_unix_ns
from formats.novatel import logs as nv
from formats.records import Reject

# Example logs as NovAtel's EDIE decoder tests carry them (OEM7 firmware output).
BESTPOSA = (
    b"#BESTPOSA,COM1,0,83.5,FINESTEERING,2163,329760.000,02400000,b1f6,65535;"
    b"SOL_COMPUTED,SINGLE,51.15043874397,-114.03066788586,1097.6822,-17.0000,"
    b'WGS84,1.3648,1.1806,3.1112,"",0.000,0.000,18,18,18,0,00,02,11,01*c3194e35\r\n'
)
BESTPOSA_WAAS = (
    b"#BESTPOSA,COM1,0,60.5,FINESTEERING,2166,327153.000,02000000,b1f6,16248;SOL_COMPUTED,WAAS,"
    b"51.15043699323,-114.03067932462,1096.9772,-17.0000,WGS84,0.6074,0.5792,0.9564,"
    b'"131",7.000,0.000,42,34,34,28,00,0b,1f,37*47bbdc4f\r\n'
)
BESTPOSB = bytes.fromhex(
    "aa44121c2a0000204800 0000a3b47308 9874a813 00000002 f6b1ffff"
    "00000000 10000000 fcabe18241934940 ba32868af6815cc0 0010e5df71239140"
    "000088c1 3d000000 2421a53f f18f8f3f 43743c40 00000000 00000000 0000000015151500"
    "00021101 55cec389".replace(" ", "")
)
T0 = 1476259201000000000  # 2016-10-12T08:00:01Z


def one(data: bytes) -> object:
    out = list(nv.decode(data))
    assert len(out) == 1, out
    return out[0]


def test_crc32_matches_the_published_logs() -> None:
    body = BESTPOSA[1 : BESTPOSA.index(b"*")]
    assert nv.crc32(body) == 0xC3194E35
    assert nv.crc32(BESTPOSB[:-4]) == int.from_bytes(BESTPOSB[-4:], "little")


def test_bestposa_long_header_fields() -> None:
    r = one(BESTPOSA)
    assert isinstance(r, nv.BestPos)
    h = r.header
    assert (h.message, h.encoding, h.port, h.week, h.seconds) == ("BESTPOS", "ascii", "COM1", 2163, 329760.0)
    assert (h.time_status, h.idle_percent, h.receiver_status, h.sw_version) == ("FINESTEERING", 83.5, 0x02400000, 65535)
    assert (r.solution_status, r.position_type, r.datum) == ("SOL_COMPUTED", "SINGLE", "WGS84")
    assert (r.latitude, r.longitude, r.height_msl_m, r.undulation_m) == (51.15043874397, -114.03066788586, 1097.6822, -17.0)
    assert (r.lat_std_m, r.lon_std_m, r.height_std_m) == (1.3648, 1.1806, 3.1112)
    assert (r.satellites_tracked, r.satellites_used, r.extended_status, r.gps_glonass_mask) == (18, 18, 2, 1)
    # 2163 weeks and 329760 s after 1980-01-06 (Unix 315964800), minus 18 leap seconds: 2021-06-23T19:35:42Z
    assert nv.record_time_ns(r) == gps_to_unix_ns(2163, 329760.0) == (315964800 + 2163 * 604800 + 329760 - 18) * 10**9
    w = one(BESTPOSA_WAAS)
    assert (w.position_type, w.station_id, w.diff_age_s, w.satellites_used) == ("WAAS", "131", 7.0, 34)


def test_binary_bestpos_published_bytes() -> None:
    r = one(BESTPOSB)
    assert isinstance(r, nv.BestPos) and r.header.encoding == "binary"
    assert (r.header.week, r.header.seconds, r.header.time_status, r.header.port) == (2163, 329807.0, "FINESTEERING", "COM1")
    assert r.latitude == pytest.approx(51.1504367, abs=1e-7) and r.longitude == pytest.approx(-114.0306727, abs=1e-7)
    assert r.height_msl_m == pytest.approx(1096.8612, abs=1e-4) and r.undulation_m == -17.0
    assert (r.solution_status, r.position_type, r.datum, r.satellites_used) == ("SOL_COMPUTED", "SINGLE", "WGS84", 21)
    assert nv.encode_binary(r) == BESTPOSB  # byte-exact round trip


def test_bad_crc_truncation_and_garbage() -> None:
    bad = BESTPOSA.replace(b"1097.6822", b"1097.6823")
    r = one(bad)
    assert isinstance(r, Reject) and r.bad_checksum
    r = one(BESTPOSA[:120] + b"\r\n")  # cut before the CRC: too few fields
    assert isinstance(r, Reject) and not r.bad_checksum
    r = one(BESTPOSB[:-1] + bytes([BESTPOSB[-1] ^ 1]))
    assert isinstance(r, Reject) and r.bad_checksum
    assert isinstance(one(BESTPOSB[:50]), Reject)
    data = b"\x00\x13noise\xff\r\n" + BESTPOSA + b"$GPGGA,1*00\r\n<OK\r\n[COM1]\r\n" + BESTPOSB + b"\xaa\x44\x12" + BESTPOSA_WAAS
    out = list(nv.decode(data))
    assert [type(r).__name__ for r in out] == ["Reject", "BestPos", "BestPos", "Reject", "BestPos"]
    assert out[2].where.offset == data.index(BESTPOSB)


def test_short_headers_and_empty_fields() -> None:
    line = nv.encode_inspvaa(T0, 45.7, 126.6, 10.0, 1.0, 2.0, 3.0, 0.5, -0.5, 270.0, short=True)
    assert line.startswith("%INSPVASA,1918,288018.000;1918,288018.000000000,45.70000000000,")
    r = one(line.encode())
    assert isinstance(r, nv.InsPva) and r.header.encoding == "ascii-short" and r.header.message == "INSPVAS"
    assert (r.north_mps, r.east_mps, r.up_mps, r.roll_deg, r.pitch_deg, r.azimuth_deg) == (1, 2, 3, 0.5, -0.5, 270)
    assert nv.record_time_ns(r) == T0
    payload = "BESTVELA,COM1,0,50.0,FINESTEERING,1918,288018.000,00000000,0000,0;SOL_COMPUTED,DOPPLER_VELOCITY,,,1.5,,0.1,0.0"
    v = one(f"#{payload}*{nv.crc32(payload.encode()):08X}\r\n".encode())  # uppercase CRC, empty fields
    assert isinstance(v, nv.BestVel) and math.isnan(v.latency_s) and math.isnan(v.track_deg)
    assert v.horizontal_speed_mps == 1.5


def test_inspvaxa_and_binary_short_inspvas() -> None:
    line = nv.encode_inspvaxa(T0, -33.5, 151.25, 20.0, 0.1, 0.2, 0.3, 1.0, 2.0, 359.0, undulation_m=22.5, azimuth_std_deg=0.3)
    x = one(line.encode())
    assert isinstance(x, nv.InsPvax) and (x.status, x.position_type) == ("INS_SOLUTION_GOOD", "INS_PSRSP")
    assert (x.latitude, x.longitude, x.undulation_m, x.azimuth_deg, x.azimuth_std_deg) == (-33.5, 151.25, 22.5, 359.0, 0.3)
    p = one(nv.encode_inspvaa(T0, 1.0, 2.0, 3.0, 0, 0, 0, 0, 0, 90).encode())
    b = nv.encode_binary(p, short=True)
    assert b[:3] == nv.SYNC_SHORT and len(b) == 12 + 88 + 4
    q = one(b)
    assert q.header.encoding == "binary-short" and (q.latitude, q.azimuth_deg, q.status) == (1.0, 90.0, "INS_SOLUTION_GOOD")
    xb = one(nv.encode_binary(x))
    assert isinstance(xb, nv.InsPvax) and xb.header.encoding == "binary"
    assert (xb.latitude, xb.longitude, xb.azimuth_deg, xb.undulation_m) == (-33.5, 151.25, 359.0, 22.5)
    assert xb.azimuth_std_deg == pytest.approx(0.3, rel=1e-7)  # a float32 on the wire


finite = st.floats(-1e3, 1e3, allow_nan=False)


@settings(max_examples=120, deadline=None)
@given(st.integers((315_964_800 + 604_800) * 10**9, 4_000_000_000 * 10**9), st.floats(-90, 90), st.floats(-180, 180),
       finite, st.floats(0, 99), st.sampled_from(["SINGLE", "PSRDIFF", "NARROW_INT", "INS_PSRSP"]))
def test_ascii_and_binary_round_trip(t: int, lat: float, lon: float, hgt: float, std: float, kind: str) -> None:
    line = nv.encode_bestposa(t, lat, lon, hgt, lat_std_m=std, lon_std_m=std, position_type=kind)
    r = one(line.encode())
    assert isinstance(r, nv.BestPos) and r.position_type == kind
    assert abs(r.latitude - lat) <= 1e-11 and abs(r.height_msl_m - hgt) <= 1e-4
    assert abs(nv.record_time_ns(r) - t) <= 500_000  # header seconds have 3 decimals
    assert nv.encode_ascii(r) == line
    b = nv.encode_binary(r)
    assert nv.encode_binary(one(b)) == b
    rb = one(b)
    assert (rb.latitude, rb.longitude, rb.height_msl_m) == (r.latitude, r.longitude, r.height_msl_m)
    pva = one(nv.encode_inspvaa(t, lat, lon, hgt, 1.0, -1.0, 0.5, 2.0, -3.0, std).encode())
    assert nv.encode_ascii(pva) == nv.encode_inspvaa(t, lat, lon, hgt, 1.0, -1.0, 0.5, 2.0, -3.0, std)
    assert one(nv.encode_binary(pva)).azimuth_deg == pva.azimuth_deg


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_no_bytes_make_decode_raise(data: bytes) -> None:
    list(nv.decode(data))
    list(nv.decode(BESTPOSB[:30] + data))
    list(nv.decode(b"#BESTPOSA," + data))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.text(alphabet="0123456789.,-;\"ABESTPOSVLINSPVAX_", max_size=20), max_size=25), st.sampled_from(
    ["#BESTPOSA,", "#BESTVELA,", "#INSPVAA,", "%INSPVASA,", "#INSPVAXA,"]))
def test_no_log_like_text_makes_decode_raise(parts: list[str], head: str) -> None:
    payload = head[1:] + ",".join(parts)
    line = f"{head[0]}{payload}*{nv.crc32(payload.encode('latin-1')):08x}\r\n"
    list(nv.decode(line.encode("latin-1")))
    length = struct.pack("<H", len(parts))
    list(nv.decode(b"\xaa\x44\x12\x1c\x2a\x00\x00\x20" + length + "".join(parts).encode("latin-1")))


def _gps_to_unix_ns_reference(week: int, seconds_of_week: float) -> int:
    """The conversion worked out for the one time, no week's count kept: `gps_to_unix_ns`' judge."""
    gps_ns = (gpstime.GPS_EPOCH_UNIX_S + week * 604800) * 10**9 + round(seconds_of_week * 10**9)
    approx = gps_ns / 10**9
    return gps_ns - gpstime.leap_seconds_at_utc(approx - gpstime.leap_seconds_at_utc(approx)) * 10**9


@settings(max_examples=500, deadline=None)
@given(st.one_of(st.integers(0, 3000), st.sampled_from([1930, 1929, 1851, 1850, 1694, 0, 2163]),
                 st.integers(-10**6, 10**12)),
       st.one_of(st.floats(0.0, 604800.0, exclude_max=True), st.floats(-1e7, 1e7),
                 st.sampled_from([0.0, 604799.999999999, 604782.0, 604783.0, 604799.5, 17.5, 18.0])))
def test_gps_time_is_the_reference_whatever_the_week(week: int, seconds: float) -> None:
    """A week's one leap count (kept per week) gives each time what the conversion of that time alone gives,
    in the weeks a leap second falls in (1930: 2017-01-01) and around them too."""
    assert gps_to_unix_ns(week, seconds) == _gps_to_unix_ns_reference(week, seconds)
