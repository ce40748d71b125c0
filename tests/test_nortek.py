"""Nortek $PNORBT: documented examples (checksums as published), tags, damage, round trips."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from formats import nortek
from formats.records import Reject

# examples as printed in Nortek's Signature integrator's guide (DF300/301) and in
# the DVL1000 format list (as carried by pynmea2's tests)
SIG_300 = "$PNORBT,3,112813,072228.2345,0.1234,0.1234,1.11111,122.2,36.66,2.22222,F7*7A"
SIG_301 = ("$PNORBT,BEAM=3,DATE=112813,TIME=072228.2345,DT1=0.1234,DT2=0.1234,"
           "BV=1.11111,FM=122.2,DIST=36.66,WV=2.22222,STAT=F7*75")
BT0 = "$PNORBT0,1,040721,131335.3341,23.961,-48.122,-32.76800,10.00000,0.00,0x00000000*48"
BT4 = "$PNORBT4,1.234,-1.234,1.234,23.4,12.34567,12.3*3D"
BT7 = "$PNORBT7,1452244916.7508,1.234,-1.234,0.1234,0.1234,0.1234,12.34,23.45,23.45,23.45,23.45*39"
BT9 = ("$PNORBT9,1452244916.7508,1.234,-1.234,0.1234,0.1234,0.1234,12.34,23.45,23.45,23.45,"
       "23.45,23.4,1567.8,1.2,12.3,0x000FFFFF*1E")


def _one(text: str):
    (rec,) = list(nortek.decode(text.encode()))
    return rec


def test_signature_examples_with_and_without_tags() -> None:
    a, b = _one(SIG_300), _one(SIG_301)
    assert a == nortek.BeamReport(a.where, "PNORBT", 3, 1385623348_234_500_000, 0.1234, 0.1234,
                                  1.11111, 122.2, 36.66, "F7")
    assert (b.beam, b.time_ns, b.velocity_mps, b.distance_m) == (3, a.time_ns, 1.11111, 36.66)


def test_invalid_markers_become_nan() -> None:
    r = _one(BT0)
    assert r.beam == 1 and r.time_ns == 1617801215_334_100_000  # 2021-04-07 13:13:35.3341
    assert math.isnan(r.velocity_mps) and math.isnan(r.figure_of_merit) and math.isnan(r.distance_m)


def test_bt4_bt7_bt9_values() -> None:
    r = _one(BT4)
    assert (r.speed_mps, r.direction_deg, r.figure_of_merit, r.distance_m) == (1.234, 23.4, 12.34567, 12.3)
    r = _one(BT7)
    assert r.time_ns == 1452244916_750_800_000  # exact, no float rounding
    assert r.velocity_mps == (0.1234,) * 3 and r.distance_m == (23.45,) * 4
    assert math.isnan(r.sound_speed_mps) and r.status == ""
    r = _one(BT9)
    assert (r.battery_v, r.sound_speed_mps, r.pressure_dbar, r.temperature_c) == (23.4, 1567.8, 1.2, 12.3)
    assert r.status == "0x000FFFFF"


def test_bad_checksum_short_empty_and_noise() -> None:
    data = "\n".join([
        BT7[:-2] + "00",
        "$PNORBT7,1452244916.7508,1.2",
        "$PNORBT9,1452244916.7508,,,,,,,,,,,,,,,",
        "\x00\x01$GPGGA,1,2*00",
        "garbage without dollar",
        "$PNORBT5,1,2,3",
    ]).encode()
    out = list(nortek.decode(data))
    assert isinstance(out[0], Reject) and out[0].bad_checksum
    assert "needs 11" in out[1].reason
    assert isinstance(out[2], nortek.VelocityReport) and all(math.isnan(v) for v in out[2].velocity_mps)
    assert [r.reason for r in out[3:]] == ["not a $PNORBT sentence"] * 2 + ["PNORBT5: unsupported bottom-track sentence"]


def test_host_prefix_kept() -> None:
    (r,) = list(nortek.decode(("2016-10-12T08:00:01.5Z " + BT4 + "\r\n").encode()))
    assert r.where.host_time_ns == 1476259201_500_000_000


v = st.one_of(st.just(math.nan), st.floats(-10, 10))
d = st.one_of(st.just(math.nan), st.floats(0.01, 200))


@settings(max_examples=100, deadline=None)
@given(st.integers(946_684_800, 4_102_444_799), st.integers(0, 9999), st.tuples(v, v, v),
       st.tuples(d, d, d, d), st.booleans())
def test_round_trip(sec, frac, vel, dist, tags) -> None:
    t = sec * 1_000_000_000 + frac * 100_000
    r = _one(nortek.encode_pnorbt7(t, vel, dist, tags=tags))
    assert r.sentence == ("PNORBT6" if tags else "PNORBT7") and r.time_ns == t
    for got, want in zip(r.velocity_mps + r.distance_m, vel + dist):
        assert (math.isnan(got) and math.isnan(want)) or abs(got - want) <= 0.0051


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.binary(max_size=200),
                 st.text(alphabet="$PNORBT0123456789,.=*-xX\r\n", max_size=200).map(str.encode)))
def test_no_input_raises(data: bytes) -> None:
    for rec in nortek.decode(data):
        assert isinstance(rec, (Reject, nortek.BeamReport, nortek.SpeedReport, nortek.VelocityReport))
