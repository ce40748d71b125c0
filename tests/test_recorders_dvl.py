"""recorders.dvl: every converter end to end, frames, times, ranges, rejects."""

from __future__ import annotations

import math
from datetime import date

import pytest

from formats import nortek, pd4, pd6
from formats import waterlinked as wl
from formats.pd0 import ensembles as pd0
from formats.pd0 import frames
from formats.records import FormatError, Reject
from formats.schemas import DvlVelocity, to_ns
from recorders.base import LogContext, Output
from recorders.dvl import CONVERTERS

T0 = 1476259201_250_000_000  # 2016-10-12T08:00:01.25Z
OFFSET = 2_000_000_000


def _ctx(**options) -> LogContext:
    return LogContext("follower", trial_date=date(2016, 10, 12), clock_offset_ns=OFFSET,
                      options=options)


def _run(fmt: str, data: bytes | str, ctx: LogContext | None = None) -> tuple[list[Output], list[Reject]]:
    out = list(CONVERTERS[fmt](data.encode() if isinstance(data, str) else data, ctx or _ctx()))
    return [o for o in out if isinstance(o, Output)], [r for r in out if isinstance(r, Reject)]


def test_registry_names() -> None:
    assert set(CONVERTERS) == {"pd0", "pd4", "pd5", "pd6", "nortek", "waterlinked"}


def test_pd0_ship_to_body_frd_ranges_and_altitude() -> None:
    bt = frames.bottom_velocity_from_frd(1.5, -0.2, 0.05, 0.01)
    data = pd0.encode_ensemble(T0, 1, bt, (10.0, 10.0, 10.3, math.nan), temperature_c=8.5,
                               sound_speed_mps=1481)
    (o,), rejects = _run("pd0", data)
    m = o.message
    assert not rejects and o.topic == "/follower/dvl" and o.log_time_ns == T0 + OFFSET
    assert to_ns(m.timestamp) == T0 + OFFSET and m.frame_id == "follower"
    assert m.frame == DvlVelocity.BODY_FRD
    assert (m.velocity_x_mps, m.velocity_y_mps, m.velocity_z_mps) == (1.5, -0.2, 0.05)
    assert m.error_velocity_mps == 0.01 and m.valid
    c30 = math.cos(math.radians(30))
    assert m.beam_range_m[0] == pytest.approx(10.0 / c30) and math.isnan(m.beam_range_m[3])
    assert m.altitude_m == pytest.approx((10 + 10 + 10.3) / 3)
    assert (m.sound_speed_mps, m.temperature_c, m.source_format) == (1481, 8.5, "pd0")
    assert math.isnan(m.figure_of_merit)


def test_pd0_earth_bad_velocity_and_fixed_leader_carry_over() -> None:
    first = pd0.encode_ensemble(T0, 1, (0.3, -1.0, 0.0, 0.0), (5,) * 4, coordinates="earth")
    second = pd0.encode_ensemble(T0 - 10**9, 2, (math.nan,) * 4, (5,) * 4, include_fixed=False)
    orphan = pd0.encode_ensemble(T0, 3, (0,) * 4, (5,) * 4, include_fixed=False)
    outs, rejects = _run("pd0", orphan + first + second)
    assert len(rejects) == 1 and "no fixed leader" in rejects[0].reason
    a, b = (o.message for o in outs)
    assert a.frame == DvlVelocity.EARTH_NED  # bottom east 0.3, north -1.0 -> vehicle N +1.0, E -0.3
    assert (a.velocity_x_mps, a.velocity_y_mps) == (1.0, -0.3)
    assert b.frame == DvlVelocity.EARTH_NED and not b.valid and math.isnan(b.velocity_x_mps)
    assert outs[1].log_time_ns < outs[0].log_time_ns  # out of order kept as is


def test_pd4_needs_a_date_and_uses_the_clock() -> None:
    data = pd4.encode(8 * 3600 + 1.25, (-0.2, 1.5, -0.05, 0.0), (10,) * 4)  # ship coords
    (o,), _ = _run("pd4", data)
    assert o.log_time_ns == T0 + OFFSET and o.message.frame == DvlVelocity.BODY_FRD
    assert (o.message.velocity_x_mps, o.message.velocity_y_mps, o.message.velocity_z_mps) == (1.5, -0.2, 0.05)
    outs, (rej,) = _run("pd5", data, LogContext("follower"))
    assert not outs and "trial date" in rej.reason


def test_pd6_frame_choice_and_host_time_fallback() -> None:
    data = pd6.encode_ensemble(T0, 1.5, -0.2, 0.05, 7.0, heading_deg=90.0)
    (o,), _ = _run("pd6", data)
    assert o.message.frame == DvlVelocity.BODY_FRD and o.message.altitude_m == 7.0
    assert o.log_time_ns == T0 + OFFSET
    (o,), _ = _run("pd6", data, _ctx(dvl_frame="earth_ned"))
    assert o.message.frame == DvlVelocity.EARTH_NED
    assert o.message.velocity_x_mps == pytest.approx(0.2, abs=1e-3)  # heading 90: north = -starboard
    line = pd6.encode_velocity("BS", (0.1, 1.0, 0.0))
    (o,), _ = _run("pd6", "1476259300.0 " + line)
    assert o.log_time_ns == 1476259300 * 10**9 + OFFSET and o.publish_time_ns == o.log_time_ns
    outs, (rej,) = _run("pd6", line)
    assert not outs and "time" in rej.reason


def test_nortek_velocity_speed_and_beams() -> None:
    bt7 = nortek.encode_pnorbt7(T0, (1.0, 0.1, 0.0), (10.0, 10.0, 10.0, math.nan), 0.004)
    (o,), _ = _run("nortek", bt7, _ctx(dvl_frame="BODY_FRD"))
    m = o.message
    assert o.log_time_ns == T0 + OFFSET and m.frame == DvlVelocity.BODY_FRD
    assert m.figure_of_merit == 0.004 and m.altitude_m == 10.0 and m.valid
    (o,), _ = _run("nortek", bt7)
    assert o.message.frame == DvlVelocity.INSTRUMENT
    bt4 = f"$PNORBT4,0,0,2.0,90.0,0.01,12.3*{_xor('PNORBT4,0,0,2.0,90.0,0.01,12.3'):02X}"
    outs, (rej,) = _run("nortek", bt4 + "\n2016-10-12T08:00:05Z " + bt4 + "\n")
    assert "no time" in rej.reason
    (o,) = outs
    assert o.message.frame == DvlVelocity.EARTH_NED and o.message.velocity_y_mps == pytest.approx(2.0)
    assert o.message.valid and math.isnan(o.message.velocity_z_mps) and o.message.altitude_m == 12.3
    beams = "".join(f"$PNORBT,{b},101216,080001.25,0,0,0.1,1.0,{9 + b},0,00*" +
                    f"{_xor(f'PNORBT,{b},101216,080001.25,0,0,0.1,1.0,{9 + b},0,00'):02X}\n"
                    for b in (1, 2, 3, 4))
    (o,), _ = _run("nortek", beams)
    assert o.log_time_ns == T0 + OFFSET and not o.message.valid
    assert o.message.altitude_m == pytest.approx(11.5) and len(o.message.beam_range_m) == 4


def _xor(s: str) -> int:
    x = 0
    for c in s.encode():
        x ^= c
    return x


def test_waterlinked_serial_json_and_unset_clock() -> None:
    tov = T0 // 1000
    serial = wl.encode_wrz((1.2, 0.1, 0.0), True, 4.0, 0.003, tov) + "".join(
        wl.encode_wru(i, 0.1, 4.5 + i / 10) for i in range(4))
    unset = "2016-10-12T08:00:09Z " + wl.encode_wrz((0.0,) * 3, False, math.nan, 2.7, 7)
    outs, rejects = _run("waterlinked", serial + unset + wl.encode_wrz((0,) * 3, True, 1.0, 1.0, 9))
    assert len(outs) == 2 and len(rejects) == 1 and "no time" in rejects[0].reason
    a, b = outs
    assert a.log_time_ns == T0 + OFFSET and a.message.frame == DvlVelocity.BODY_FRD
    assert a.message.altitude_m == 4.0 and list(a.message.beam_range_m) == pytest.approx([4.5, 4.6, 4.7, 4.8])
    assert a.message.figure_of_merit == 0.003 and a.message.valid
    assert b.log_time_ns == 1476259209 * 10**9 + OFFSET and not b.message.valid
    assert math.isnan(b.message.altitude_m)


def test_bad_frame_option_is_a_clear_error() -> None:
    with pytest.raises(FormatError, match="dvl_frame"):
        _run("waterlinked", b"", _ctx(dvl_frame="sideways"))


def test_garbage_never_raises() -> None:
    junk = bytes(range(256)) * 3
    for fmt in CONVERTERS:
        outs, rejects = _run(fmt, junk)
        assert not outs and rejects


@pytest.mark.parametrize("altitude", [-1.0, -0.5])
def test_no_altitude_keeps_the_ping_not_valid(altitude: float) -> None:
    """A DVL's "no altitude" (Water Linked's -1, as its ROS driver passes it on) keeps the ping: altitude NaN,
    not valid; the record-time range check then has nothing to refuse."""
    from recorders.dvl import message
    from recorders.value_checks import ValueChecks

    msg = message(LogContext("auv"), T0, "BODY_FRD", (0.25, -0.1, 0.02), altitude=altitude, valid=True,
                  fom=0.004, source="waterlinked:velocity")
    assert math.isnan(msg.altitude_m) and not msg.valid and msg.velocity_x_mps == 0.25
    assert ValueChecks().problem(msg, T0) is None
    kept = message(LogContext("auv"), T0, "BODY_FRD", (0.25, -0.1, 0.02), altitude=0.0, valid=True)
    assert kept.altitude_m == 0.0 and kept.valid  # 0 m is an altitude (sitting on the bottom)
