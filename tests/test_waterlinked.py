"""Water Linked serial (CRC-8) and TCP JSON: documented examples, damage, round trips."""

from __future__ import annotations

import json
import math

from hypothesis import given, settings
from hypothesis import strategies as st

from formats import waterlinked as wl
from formats.records import Reject

# the examples of Water Linked's protocol page, checksums as published
DOC = """wrz,0.120,-0.400,2.000,y,1.30,1.855,1e-07;0;1.4;0;1.2;0;0.2;0;1e+09,7,14,123.00,1*50
wru,0,0.070,1.10,-40,-95*9c
wru,1,-0.500,1.25,-62,-104*f0
wrp,49056.809,0.41,0.15,1.23,0.4,53.9,13.0,19.3,0*de
wrx,1164.94,0.000,0.000,0.000,2.707,-1.00,n,1*39
wrt,14.90,15.10,14.80,-1.00*53
"""


def test_crc8_check_value() -> None:
    assert wl.crc8(b"123456789") == 0xF4


def test_documented_serial_examples() -> None:
    z, u0, u1, p, x, t = list(wl.decode(DOC.encode()))
    assert z.velocity_mps == (0.12, -0.4, 2.0) and z.valid and z.altitude_m == 1.3
    assert z.figure_of_merit == 1.855 and len(z.covariance) == 9 and z.covariance[2] == 1.4
    assert (z.time_of_validity_us, z.time_of_transmission_us, z.since_last_ms, z.status) == (7, 14, 123.0, 1)
    assert (u1.id, u1.velocity_mps, u1.distance_m, u1.rssi_dbm, u1.nsd_dbm) == (1, -0.5, 1.25, -62.0, -104.0)
    assert (p.time_s, p.x_m, p.yaw_deg, p.status) == (49056.809, 0.41, 19.3, 0)
    assert x.source == "wrx" and not x.valid and math.isnan(x.altitude_m) and x.figure_of_merit == 2.707
    assert t.distance_m[:3] == (14.9, 15.1, 14.8) and math.isnan(t.distance_m[3])


def test_json_velocity_and_position() -> None:
    vel = {"time": 106.39, "vx": -3.7e-05, "vy": 5.7e-05, "vz": 2.5e-05, "fom": 0.00016,
           "covariance": [[1, 0, 0], [0, 2, 0], [0, 0, 3]], "altitude": 0.495,
           "transducers": [{"id": i, "velocity": 0.0, "distance": [0.55, 0.56, 0.57, 0.58][i], "rssi": -30,
                            "nsd": -88, "beam_valid": True} for i in range(4)],
           "velocity_valid": True, "status": 0, "format": "json_v3", "type": "velocity",
           "time_of_validity": 1638191471563017, "time_of_transmission": 1638191471752336}
    pos = {"ts": 49056.809, "x": 12.4, "y": 64.6, "z": 1.77, "std": 0.002, "roll": 0.6,
           "pitch": 0.6, "yaw": 0.6, "type": "position_local", "status": 0, "format": "json_v2"}
    resp = {"response_to": "get_config", "success": True, "type": "response"}
    data = "\n".join(json.dumps(o) for o in (vel, pos, resp)).encode() + b"\n{broken\n"
    v, p, r, b = list(wl.decode(data))
    assert v.source == "json" and v.time_of_validity_us == 1638191471563017
    assert v.covariance == (1, 0, 0, 0, 2, 0, 0, 0, 3) and len(v.transducers) == 4
    assert v.transducers[3].distance_m == 0.58 and v.valid and v.altitude_m == 0.495
    assert p.x_m == 12.4 and p.std_m == 0.002
    assert isinstance(r, Reject) and "'response'" in r.reason
    assert isinstance(b, Reject) and b.reason.startswith("not JSON")


def test_damage() -> None:
    lines = [DOC.splitlines()[1][:-2] + "00", "wru,0,0.070,1.10",
             f"wru,0,0.070,1.10,-40*{wl.crc8(b'wru,0,0.070,1.10,-40'):02x}",
             f"wrz,a,b,c,y,1,1,,1,2,3,0*{wl.crc8(b'wrz,a,b,c,y,1,1,,1,2,3,0'):02x}", "\x00\xffnoise"]
    out = list(wl.decode("\r\n".join(lines).encode()))
    assert out[0].bad_checksum and "no CRC-8" in out[1].reason
    assert "needs 5" in out[2].reason and "not a number" in out[3].reason
    assert out[4].reason == "not a Water Linked report"


@settings(max_examples=100, deadline=None)
@given(st.tuples(*[st.floats(-5, 5)] * 3), st.booleans(), st.one_of(st.just(math.nan), st.floats(0.05, 50)),
       st.floats(0, 3), st.integers(946_684_800_000_000, 4_102_444_799_000_000))
def test_wrz_round_trip(vel, valid, alt, fom, tov) -> None:
    (r,) = list(wl.decode(wl.encode_wrz(vel, valid, alt, fom, tov).encode()))
    assert r.valid == valid and r.time_of_validity_us == tov
    assert all(abs(a - b) <= 5e-4 for a, b in zip(r.velocity_mps, vel))
    assert (math.isnan(r.altitude_m) and math.isnan(alt)) or abs(r.altitude_m - alt) <= 0.005


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.binary(max_size=200),
                 st.text(alphabet='wrzuptx,.;*-0123456789abcdefyn{}":[]\n', max_size=200).map(str.encode)))
def test_no_input_raises(data: bytes) -> None:
    for rec in wl.decode(data):
        assert isinstance(rec, (Reject, wl.VelocityReport, wl.TransducerReport, wl.PositionReport,
                                wl.LegacyDistances))
