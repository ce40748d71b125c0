"""PD4/PD5 decoder and encoder: hand-built records, damage, round trips."""

from __future__ import annotations

import math
import struct

from hypothesis import given, settings
from hypothesis import strategies as st

from formats import pd4
from formats.records import Reject


def _hand_pd4() -> bytes:
    """PD4 per the Pathfinder table: earth coordinates, beam 3 without bottom, 13:45:07.89."""
    b = bytearray(45)
    b[0], b[1] = 0x7D, 0
    b[2:4] = struct.pack("<H", 45)
    b[4] = 0b11_1_0_0_011  # earth, tilts, 600 kHz
    b[5:13] = struct.pack("<4h", 1234, -567, 8, -32768)
    b[13:21] = struct.pack("<4H", 2500, 2510, 0, 2490)
    b[35:39] = bytes([13, 45, 7, 89])
    b[41:43] = struct.pack("<H", 1490)
    b[43:45] = struct.pack("<h", -150)
    return bytes(b) + struct.pack("<H", sum(b) & 0xFFFF)


def test_hand_built_pd4() -> None:
    (rec,) = list(pd4.decode(_hand_pd4()))
    assert isinstance(rec, pd4.DvlOutput) and rec.structure == 0
    assert rec.coordinates == "earth"
    assert rec.velocity_mps[:3] == (1.234, -0.567, 0.008) and math.isnan(rec.velocity_mps[3])
    assert rec.range_m[0] == 25.0 and math.isnan(rec.range_m[2])
    assert rec.tod_s == 13 * 3600 + 45 * 60 + 7.89
    assert (rec.sound_speed_mps, rec.temperature_c) == (1490.0, -1.5)
    assert math.isnan(rec.heading_deg)
    # earth (east, north, up) of the vessel -> NED
    assert pd4.vehicle_velocity("earth", rec.velocity_mps)[:4] == ("EARTH_NED", -0.567, 1.234, -0.008)


def test_pd5_fields() -> None:
    data = pd4.encode(100.5, (0.1, 1.0, 0.0, 0.0), (5, 5, 5, 5), pd5=True, heading_deg=271.25,
                      pitch_deg=-1.5, roll_deg=2.0, depth_m=12.3, salinity_ppt=35,
                      dmg_bottom_m=(12.3, -4.5, 0.0, 0.1))
    assert len(data) == 88
    (rec,) = list(pd4.decode(data))
    assert rec.structure == 1 and rec.heading_deg == 271.25 and rec.depth_m == 12.3
    assert (rec.pitch_deg, rec.roll_deg, rec.salinity_ppt) == (-1.5, 2.0, 35.0)
    assert rec.dmg_bottom_m == (12.3, -4.5, 0.0, 0.1)
    assert pd4.vehicle_velocity("ship", rec.velocity_mps)[:4] == ("BODY_FRD", 1.0, 0.1, -0.0)


def test_damage_noise_and_truncation() -> None:
    good = _hand_pd4()
    bad = bytearray(good)
    bad[10] ^= 0x55
    out = list(pd4.decode(b"xx\x7d\x07yy" + bytes(bad) + good + good[:30]))
    assert [type(r).__name__ for r in out].count("DvlOutput") == 1
    assert out[0].where.offset == 0 and "noise" in out[0].reason
    assert any(isinstance(r, Reject) and r.bad_checksum and r.where.offset == 6 for r in out)
    assert out[-1].reason.startswith("truncated")


def test_bad_time_is_rejected() -> None:
    b = bytearray(_hand_pd4()[:-2])
    b[35] = 24  # hour 24
    (rec,) = list(pd4.decode(bytes(b) + struct.pack("<H", sum(b) & 0xFFFF)))
    assert isinstance(rec, Reject) and "time of first ping" in rec.reason


v = st.one_of(st.just(math.nan), st.floats(-30, 30))
r = st.one_of(st.just(math.nan), st.floats(0.01, 655.0))


@settings(max_examples=100, deadline=None)
@given(st.floats(0, 86399.99), st.tuples(v, v, v, v), st.tuples(r, r, r, r), st.booleans(),
       st.sampled_from(pd4.COORDINATES))
def test_round_trip(tod, vel, rng, pd5, coords) -> None:
    (rec,) = list(pd4.decode(pd4.encode(tod, vel, rng, pd5=pd5, coordinates=coords)))
    assert abs(rec.tod_s - round(tod * 100) / 100) < 1e-6 and rec.coordinates == coords
    for got, want in zip(rec.velocity_mps + rec.range_m, vel + rng):
        assert (math.isnan(got) and math.isnan(want)) or abs(got - want) <= 0.0051


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_no_input_raises(data: bytes) -> None:
    assert all(isinstance(x, (pd4.DvlOutput, Reject)) for x in pd4.decode(data))
