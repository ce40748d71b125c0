"""The whole-log columnar NMEA path gives what the per-line path gives, on clean logs and on any other."""

from __future__ import annotations

from datetime import date

from hypothesis import given, settings
from hypothesis import strategies as st

from formats import nmea, nmea_columns
from formats.sentence import build
from recorders import gps
from recorders.base import LogContext, Output

DAY = date(2016, 10, 12)
T0 = 1476230400 * 10**9 + 23 * 3600 * 10**9 + 3599 * 10**9  # 23:59:59: epochs roll over midnight
S1 = 10**9

_CLEAN = st.sampled_from([
    lambda t: nmea.encode_gga(t, 45.7, 126.6, hdop=0.9, geoid_separation_m=-8.0),
    lambda t: nmea.encode_gga(t, -45.7, -126.6, quality=4, satellites=12, hdop=float("nan")),
    lambda t: nmea.encode_gga(t, float("nan"), float("nan"), quality=0),
    lambda t: nmea.encode_gga(t, 1.0, 2.0, quality=9, talker="GN"),
    lambda t: nmea.encode_rmc(t, 45.7, -126.6, speed_knots=2.0, course_deg=10.0),
    lambda t: nmea.encode_rmc(t, 45.7, 126.6, valid=False),
    lambda t: nmea.encode_gst(t, lat_std_m=1.0, lon_std_m=2.0, alt_std_m=3.0),
    lambda t: nmea.encode_gst(t, lat_std_m=float("nan"), lon_std_m=2.0),
    lambda t: "$GPGSV,3,1,11,03,03,111,00*4B\r\n", lambda t: "$PASHR,1,2*00\r\n",
    lambda t: build("GPGGA", ["080001.00", "4542.1", "N", "12635.8", "E", "1", "8", "1.0", "", "M", "", "M", "", ""]),
    lambda t: build("GPGGA", ["080001.00", "37.352", "N", "12635.8", "E", "1", "8", "1.0", "", "M", "", "M", "", ""]),
    lambda t: build("GPGGA", ["250001.00", "4542.1", "N", "12635.8", "E", "1", "8", "1.0", "", "M", "", "M", "", ""]),
    lambda t: build("GPGGA", ["080001.00", "4542.1", "X", "12635.8", "NE", "1", "8", "x", "", "M", "", "M", "", ""]),
    lambda t: build("GPRMC", ["080001.00", "A", "4542.1", "S", "12635.8", "W", "1", "2", "320916", "3", "W", "A"]),
    lambda t: build("GPRMC", ["080001.00", "A", "4542.1", "S", "12635.8", "W", "1", "2", "", "", "", "A"]),
    lambda t: build("GPGST", ["", "1", "", "", "", "1", "2", "3"]), lambda t: build("GPZDA", ["080001.00", "12", "10", "2016", "", ""]),
    lambda t: "\r\n", lambda t: "\n",
])


def _comparable(items: list) -> list:
    return [(o.topic, o.log_time_ns, o.publish_time_ns, o.where, o.message.SerializeToString())
            if isinstance(o, Output) else o for o in items]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(_CLEAN, st.integers(0, 3), st.booleans()), max_size=30),
       st.sampled_from([None, DAY]), st.integers(-2, 2), st.sampled_from([{}, {"uere_m": 2.0}]), st.binary(max_size=3))
def test_columns_equal_the_per_line_path(parts, day, offset_s, options, tail) -> None:
    lines, t = [], T0 - 2 * S1
    for make, step, crlf in parts:
        t += step * S1 // 2
        line = make(t)
        lines.append(line if crlf else line.replace("\r\n", "\n"))
    data = "".join(lines).encode("latin-1")
    ctx = LogContext("boat", trial_date=day, clock_offset_ns=offset_s * S1, options=options)
    for blob in (data, data + tail):
        fast, ref = list(gps.convert_nmea(blob, ctx)), list(gps.convert_nmea_reference(blob, ctx))
        assert _comparable(fast) == _comparable(ref)


def test_a_clean_receiver_log_takes_the_columnar_path() -> None:
    data = "".join(nmea.encode_gga(T0 + k * S1, 45.7, 126.6) + nmea.encode_rmc(T0 + k * S1, 45.7, 126.6)
                   for k in range(5)).encode()
    assert nmea_columns.decode_columns(data) is not None
    assert nmea_columns.decode_columns(data.replace(b"*", b"*0", 1)) is None  # damage: the per-line path
