"""PD6/PD13 ASCII: the documented example, grouping, damage, prefixes, round trips."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from formats import pd6
from formats.records import Reject

# the PD13 example of the Pathfinder DVL Guide (spaces inside fields as printed)
EXAMPLE = """:SA, -2.31, +1.92, 75.20
:TS,04081111563644,35.0,+21.0, 0.0,1524.0, 0
:RA, 0.00, 71.31, 71.32, 71.32, 71.31
:WI,-32768,-32768,-32768,-32768,V
:WS,-32768,-32768,-32768,V
:WE,-32768,-32768,-32768,V
:WD, +0.00, +0.00, +0.00, 20.00, 0.00
:BI, +24, -6, -20, -4,A
:BS, -13, +21, -20,A
:BE, +17, +18, -20,A
:BD, -0.02, -0.03, +0.02, 7.13, 0.21
"""
T_EXAMPLE = 1092225396_440_000_000  # 2004-08-11T11:56:36.44Z


def test_documented_example() -> None:
    (ens,) = list(pd6.ensembles(EXAMPLE.encode()))
    assert ens.attitude.pitch_deg == -2.31 and ens.attitude.heading_deg == 75.2
    ts = ens.timescale
    assert ens.time_ns == T_EXAMPLE
    assert (ts.salinity_ppt, ts.temperature_c, ts.sound_speed_mps, ts.bit) == (35.0, 21.0, 1524.0, 0)
    assert ens.ranges.range_m == (7.131, 7.132, 7.132, 7.131)
    assert all(math.isnan(x) for x in ens.velocities["WI"].values_mps)
    assert ens.velocities["BS"].values_mps == (-0.013, 0.021, -0.02)
    assert ens.distances["BD"].range_m == 7.13
    # BS: transverse -13, longitudinal +21, normal -20 mm/s -> FRD (0.021, -0.013, +0.02)
    assert pd6.vehicle_velocity(ens) == ("BODY_FRD", 0.021, -0.013, 0.02, -0.004, True)
    assert pd6.vehicle_velocity(ens, "EARTH_NED")[:4] == ("EARTH_NED", 0.018, 0.017, 0.02)
    assert pd6.vehicle_velocity(ens, "INSTRUMENT")[:5] == ("INSTRUMENT", 0.024, -0.006, -0.02, -0.004)


def test_two_cycles_prefix_crlf_and_noise() -> None:
    a = pd6.encode_ensemble(1476259201_000_000_000, 1.0, 0.1, 0.0, 9.0)
    b = pd6.encode_ensemble(1476259202_000_000_000, 1.1, 0.2, 0.0, 9.5)
    text = "[2016-10-12T08:00:01.100Z] " + a.replace("\r\n", "\r\n[2016-10-12T08:00:01.100Z] ", 5)
    data = text.encode() + b"\x00\xff garbage\n" + b.replace("\r\n", "\n").encode()
    out = list(pd6.ensembles(data))
    ens = [e for e in out if isinstance(e, pd6.Pd6Ensemble)]
    assert len(ens) == 2 and ens[0].where.host_time_ns == 1476259201_100_000_000
    assert [r.reason for r in out if isinstance(r, Reject)] == ["not a PD6 line"]
    assert pd6.vehicle_velocity(ens[1])[1:3] == (1.1, 0.2)


def test_short_and_bad_fields() -> None:
    out = list(pd6.decode(b":BS,+1,+2,V\n:BI,+1,x2,+3,+4,A\n:TS,991399,1,1,1,1,1\n:BE,,,,V\n"))
    assert isinstance(out[0], Reject) and "needs 4" in out[0].reason
    assert isinstance(out[1], Reject) and "not a number" in out[1].reason
    assert isinstance(out[2], pd6.TimeScale) and out[2].time_ns is None
    assert isinstance(out[3], pd6.Velocity) and not out[3].good


def test_missing_ts_uses_host_time_else_none() -> None:
    line = pd6.encode_velocity("BS", (0.1, 1.0, 0.0))
    (ens,) = list(pd6.ensembles(("1476259201.5 " + line).encode()))
    assert ens.time_ns == 1476259201_500_000_000
    (ens,) = list(pd6.ensembles(line.encode()))
    assert ens.time_ns is None


speed = st.floats(-20, 20)


@settings(max_examples=100, deadline=None)
@given(st.integers(946_684_800, 4_102_444_799), speed, speed, speed, st.floats(0.5, 500))
def test_round_trip(sec, fwd, stbd, down, alt) -> None:
    t = sec * 1_000_000_000 + 370_000_000
    (ens,) = list(pd6.ensembles(pd6.encode_ensemble(t, fwd, stbd, down, alt).encode()))
    frame, x, y, z, _, good = pd6.vehicle_velocity(ens)
    assert ens.time_ns == t and frame == "BODY_FRD" and good
    # the format's resolution is 1 mm/s and 1 cm: half a step of rounding, plus the float error of the step itself
    assert abs(x - fwd) <= 5e-4 + 1e-12 and abs(y - stbd) <= 5e-4 + 1e-12 and abs(z - down) <= 5e-4 + 1e-12
    assert abs(ens.distances["BD"].range_m - alt) <= 0.005 + 1e-12


@settings(max_examples=200, deadline=None)
@given(st.text(alphabet=":SATBIWEDRV,+-0123456789. \n\r\x00", max_size=300))
def test_no_input_raises(text: str) -> None:
    for rec in pd6.ensembles(text.encode("latin-1", "replace")):
        assert isinstance(rec, (pd6.Pd6Ensemble, Reject))
