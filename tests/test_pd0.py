"""PD0 decoder and encoder: hand-built ensembles, damage, firmware quirks, round trips."""

from __future__ import annotations

import math
import struct

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.pd0 import ensembles as pd0
from formats.pd0 import frames
from formats.records import Reject

T0 = 1476259201_250_000_000  # 2016-10-12T08:00:01.25Z


def _hand_fixed_42() -> bytes:
    """An old-firmware 42-byte fixed leader: 600 kHz convex down-looking, 30°, ship coords."""
    fl = bytearray(42)
    fl[2], fl[3] = 16, 5  # firmware 16.05
    fl[4:6] = struct.pack("<H", 0x4000 | 0x0200 | 0x40 | 0x08 | 0x03)  # 30°, convex, 600 kHz
    fl[8], fl[9] = 4, 0  # beams, cells
    fl[25] = 0b00010111  # EX: ship, tilts, 3-beam, bin mapping
    fl[32:34] = struct.pack("<H", 123)  # bin 1 at 1.23 m
    return bytes(fl)


def _hand_variable_58(ens: int) -> bytes:
    """A variable leader without the Y2K clock: RTC 16-10-12 08:00:01.25."""
    vl = bytearray(58)
    vl[0:2] = b"\x80\x00"
    vl[2:4] = struct.pack("<H", ens & 0xFFFF)
    vl[4:11] = bytes([16, 10, 12, 8, 0, 1, 25])
    vl[11] = ens >> 16
    vl[14:16] = struct.pack("<H", 1482)  # sound speed
    vl[16:18] = struct.pack("<H", 125)  # 12.5 m depth
    vl[18:20] = struct.pack("<H", 27050)  # heading 270.50
    vl[20:24] = struct.pack("<hh", -150, 225)  # pitch -1.50, roll 2.25
    vl[26:28] = struct.pack("<h", 1234)  # 12.34 C
    return bytes(vl)


def _hand_bottom_81() -> bytes:
    """Bottom track without range MSBs; beam 4 has no bottom and a bad velocity."""
    bt = bytearray(81)
    bt[0:2] = b"\x00\x06"
    bt[2:4] = struct.pack("<H", 1)
    bt[16:24] = struct.pack("<4H", 1000, 1010, 990, 0)  # cm
    bt[24:32] = struct.pack("<4h", -250, 1500, 20, -32768)  # mm/s
    bt[40:44] = bytes([100, 100, 100, 0])
    return bytes(bt)


def _frame(types: list[bytes]) -> bytes:
    off = 6 + 2 * len(types)
    offsets = []
    for t in types:
        offsets.append(off)
        off += len(t)
    body = b"\x7f\x7f" + struct.pack("<HBB", off, 0, len(types))
    body += struct.pack(f"<{len(types)}H", *offsets) + b"".join(types)
    return body + struct.pack("<H", sum(body) & 0xFFFF)


def _only(records):
    out = list(records)
    assert len(out) == 1, out
    return out[0]


def test_hand_built_ensemble_values() -> None:
    ens = _only(pd0.decode(_frame([_hand_fixed_42(), _hand_variable_58(65541), _hand_bottom_81()])))
    assert isinstance(ens, pd0.Ensemble)
    assert ens.fixed.coordinates == "ship" and ens.fixed.beam_angle_deg == 30.0
    assert ens.fixed.frequency_khz == 600 and ens.fixed.convex and not ens.fixed.upward
    assert ens.fixed.serial_number is None and ens.fixed.bin1_distance_m == 1.23
    v = ens.variable
    assert v.ensemble_number == 65541 and v.y2k_rtc is None
    assert ens.time_ns == T0
    assert (v.sound_speed_mps, v.depth_m, v.heading_deg) == (1482.0, 12.5, 270.5)
    assert (v.pitch_deg, v.roll_deg, v.temperature_c) == (-1.5, 2.25, 12.34)
    bt = ens.bottom_track
    assert bt.velocity_mps[:3] == (-0.25, 1.5, 0.02) and math.isnan(bt.velocity_mps[3])
    assert bt.range_m[:3] == (10.0, 10.1, 9.9) and math.isnan(bt.range_m[3])
    assert bt.percent_good == (100, 100, 100, 0)


def test_ship_coordinates_become_body_frd() -> None:
    # bottom moving aft at 1.5 m/s and to port at 0.25 m/s: vehicle forward 1.5, starboard 0.25
    frame, x, y, z, e = frames.vehicle_velocity("ship", (-0.25, 1.5, 0.02, 0.01))
    assert frame == "BODY_FRD"
    assert (x, y, z, e) == (-1.5, 0.25, 0.02, 0.01)
    assert frames.bottom_velocity_from_frd(-1.5, 0.25, 0.02, 0.01) == (-0.25, 1.5, 0.02, 0.01)


def test_beam_transform_matches_hand_values() -> None:
    # 30°: a = 1, b = 1/(4 cos30) = 0.288675; beams (1, -1, 0, 0) -> X = 2
    x, y, z, e = frames.beam_to_instrument((1.0, -1.0, 0.0, 0.0), 30.0, convex=True)
    assert math.isclose(x, 2.0) and y == 0.0 and z == 0.0
    _, _, z, _ = frames.beam_to_instrument((1.0, 1.0, 1.0, 1.0), 30.0)
    assert math.isclose(z, 4 / (4 * math.cos(math.radians(30))))


def test_y2k_clock_wins_and_range_msb() -> None:
    data = pd0.encode_ensemble(T0, 7, (0.1, 0.2, 0.0, 0.0), (700.0, 10.0, 10.0, 10.0))
    ens = _only(pd0.decode(data))
    assert ens.variable.y2k_rtc[:2] == (20, 16)
    assert ens.time_ns == T0
    assert ens.bottom_track.range_m[0] == 700.0  # 70000 cm needs the MSB byte


def test_bad_checksum_truncation_and_noise() -> None:
    good = pd0.encode_ensemble(T0, 1, (0.1, 0.2, 0.0, 0.0), (10.0,) * 4)
    bad = bytearray(good)
    bad[40] ^= 0xFF
    stream = b"\x00\x7f\xffNOISE" + bytes(bad) + good + b"\x7f\x7f" + good[2:30]
    out = list(pd0.decode(stream))
    kinds = [type(r).__name__ for r in out]
    assert kinds.count("Ensemble") == 1
    checks = [r for r in out if isinstance(r, Reject) and r.bad_checksum]
    assert len(checks) == 1 and checks[0].where.offset == 8
    assert out[-1].reason.startswith("truncated ensemble")
    assert out[0].where.offset == 0 and "noise" in out[0].reason
    ens = next(r for r in out if isinstance(r, pd0.Ensemble))
    assert ens.where.offset == 8 + len(good)


def test_missing_fixed_leader_and_vendor_types() -> None:
    nav = b"\x13\x20" + bytes(83)  # a Pathfinder 0x2013-style type we do not know
    data = pd0.encode_ensemble(T0, 3, (0.0,) * 4, (5.0,) * 4, include_fixed=False, extra=[nav])
    ens = _only(pd0.decode(data))
    assert ens.fixed is None and ens.data_ids == (0x0080, 0x0600, 0x2013)
    assert ens.bottom_track.range_m == (5.0,) * 4


def test_profile_cells_and_five_beams() -> None:
    prof = np.arange(12, dtype=float).reshape(3, 4) / 10
    prof[1, 2] = np.nan
    ens = _only(pd0.decode(pd0.encode_ensemble(T0, 1, (0,) * 4, (1,) * 4, profile=prof),
                           profiles=True))
    np.testing.assert_array_equal(ens.velocity_profile, prof)
    ens = _only(pd0.decode(pd0.encode_ensemble(T0, 1, (0,) * 4, (1,) * 4, profile=prof)))
    assert ens.velocity_profile is None


def test_invalid_rtc_gives_no_time() -> None:
    vl = bytearray(_hand_variable_58(1))
    vl[5] = 13  # month 13
    ens = _only(pd0.decode(_frame([_hand_fixed_42(), bytes(vl), _hand_bottom_81()])))
    assert ens.time_ns is None


def test_bad_offset_table_is_rejected() -> None:
    data = bytearray(pd0.encode_ensemble(T0, 1, (0,) * 4, (1,) * 4))
    data[6:8] = struct.pack("<H", 4000)  # offset beyond the ensemble
    body = bytes(data[:-2])
    data[-2:] = struct.pack("<H", sum(body) & 0xFFFF)
    out = _only(pd0.decode(bytes(data)))
    assert isinstance(out, Reject) and "offset" in out.reason and not out.bad_checksum


finite_v = st.floats(-30.0, 30.0, allow_nan=False)
ranges = st.one_of(st.just(math.nan), st.floats(0.01, 2000.0))


@settings(max_examples=150, deadline=None)
@given(
    t=st.integers(946_684_800 * 10**9, 4_000_000_000 * 10**9),
    n=st.integers(0, 2**24 - 1),
    vel=st.tuples(finite_v, finite_v, st.one_of(st.just(math.nan), finite_v), finite_v),
    rng=st.tuples(ranges, ranges, ranges, ranges),
    y2k=st.booleans(),
)
def test_round_trip(t, n, vel, rng, y2k) -> None:
    if not y2k:
        t = min(t, 3_471_292_799 * 10**9)  # two-digit years cover 1980-2079
    ens = _only(pd0.decode(pd0.encode_ensemble(t, n, vel, rng, y2k=y2k)))
    assert ens.time_ns == t - t % 10_000_000
    assert ens.variable.ensemble_number == n
    for got, want in zip(ens.bottom_track.velocity_mps, vel):
        assert (math.isnan(got) and math.isnan(want)) or abs(got - want) <= 0.0005 + 1e-12
    for got, want in zip(ens.bottom_track.range_m, rng):
        assert (math.isnan(got) and math.isnan(want)) or abs(got - want) <= 0.005 + 1e-9


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=600))
def test_no_input_raises(data: bytes) -> None:
    for rec in pd0.decode(data, profiles=True):
        assert isinstance(rec, (pd0.Ensemble, Reject))


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 264), st.integers(0, 255), st.binary(max_size=40))
def test_damaged_ensemble_never_raises(pos: int, byte: int, noise: bytes) -> None:
    good = bytearray(pd0.encode_ensemble(T0, 9, (0.1,) * 4, (3.0,) * 4))
    good[pos % len(good)] = byte
    out = list(pd0.decode(noise + bytes(good) + noise, profiles=True))
    assert all(isinstance(r, (pd0.Ensemble, Reject)) for r in out)
