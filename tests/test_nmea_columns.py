"""The whole-log columnar NMEA path gives what the per-line path gives, on clean logs and on any other."""

from __future__ import annotations

import math
from datetime import date

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.nmea import columns as nmea_columns
from formats.nmea import sentences as nmea
from formats.nmea.framing import build
from formats.units import NS as S1
from recorders import gps, gps_columns
from recorders.base import LogContext, Output
from recorders.gnss_covariance import fix_covariance, fix_covariance_columns
from tests import reference_converters as reference

DAY = date(2016, 10, 12)
T0 = 1476230400 * 10**9 + 23 * 3600 * 10**9 + 3599 * 10**9  # 23:59:59: epochs roll over midnight

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
    lambda t: nmea.encode_vtg(45.0, 3.1), lambda t: nmea.encode_gll(t, 45.7, -126.6),
    lambda t: nmea.encode_zda(t), lambda t: nmea.encode_hdt(271.5), lambda t: nmea.encode_ths(12.0, "V"),
    lambda t: "\r\n", lambda t: "\n",
])

# Per sentence type, clean variants and nearly clean ones (odd layouts, empty or bad values) that the
# columnar path must either decode exactly as the per-line path or hand back to it.
_KINDS = {
    "GGA": [lambda t: nmea.encode_gga(t, 45.7, 126.6, hdop=0.9, geoid_separation_m=-8.0),
            lambda t: nmea.encode_gga(t, 45.7, 126.6, quality=0),
            lambda t: nmea.encode_gga(t, float("nan"), float("nan"), quality=2, hdop=float("nan"))],
    "GST": [lambda t: nmea.encode_gst(t, lat_std_m=1.0, lon_std_m=2.0, alt_std_m=3.0),
            lambda t: nmea.encode_gst(t, lat_std_m=float("nan"), lon_std_m=2.0)],
    "RMC": [lambda t: nmea.encode_rmc(t, 45.7, -126.6, speed_knots=2.0, course_deg=10.0),
            lambda t: nmea.encode_rmc(t, 45.7, 126.6, valid=False, speed_knots=1.0)],
    "VTG": [lambda t: nmea.encode_vtg(45.0, 3.1), lambda t: nmea.encode_vtg(float("nan"), float("nan")),
            lambda t: build("GPVTG", ["10.0", "", "", "", "3.0", "N", "5.5", "K", "A"]),
            lambda t: build("GPVTG", ["10.0", "X", "11.0", "Y", "3.0", "N", "5.5", "K", "A"]),  # 1.x reading
            lambda t: build("GPVTG", ["10.0", "T", "", "M", "3.0", "N"]),  # stops after the knots
            lambda t: build("GPVTG", ["10.0", "T", "", "M", "x", "N", "", "K", "A"])],
    "GLL": [lambda t: nmea.encode_gll(t, -45.7, 126.6), lambda t: nmea.encode_gll(t, 45.7, 126.6, valid=False),
            lambda t: nmea.encode_gll(t, float("nan"), float("nan")),
            lambda t: build("GPGLL", ["4542.1", "N", "12635.8", "E", nmea._hhmmss(t), "A"]),  # no mode
            lambda t: build("GPGLL", ["4542.1", "N", "12635.8", "E", "", "A", "A"]),  # no time
            lambda t: build("GPGLL", ["45.1", "N", "12635.8", "E", nmea._hhmmss(t), "A", "A"])],
    "ZDA": [lambda t: nmea.encode_zda(t), lambda t: build("GPZDA", [nmea._hhmmss(t), "", "", "", "", ""]),
            lambda t: build("GPZDA", [nmea._hhmmss(t), "31", "02", "2016", "00", "00"]),  # no such day
            lambda t: build("GPZDA", [nmea._hhmmss(t), "01", "01", "2017", "x", "00"]),
            lambda t: build("GPZDA", [nmea._hhmmss(t), "01", "01", "2017"])],
    "HDT": [lambda t: nmea.encode_hdt(271.5), lambda t: nmea.encode_hdt(float("nan")),
            lambda t: build("GPHDT", ["x", "T"]), lambda t: build("GPHDT", ["12.5"])],
    "THS": [lambda t: nmea.encode_ths(12.0), lambda t: nmea.encode_ths(13.0, "V"), lambda t: build("GPTHS", ["14.0"])],
}
_CLEAN_SHARE = 0.93  # most sentences are a type's first, clean variant: most logs take the columnar path


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
        fast, ref = list(gps.convert_nmea(blob, ctx)), list(reference.convert_nmea_reference(blob, ctx))
        assert _comparable(fast) == _comparable(ref)


@st.composite
def _epoch_log(draw: st.DrawFn) -> bytes:
    """Epochs of distinct types in any order, as receivers write them, now and then a nearly clean sentence."""
    lines, t = [], T0 - 3 * S1
    for _ in range(draw(st.integers(0, 8))):
        t += draw(st.sampled_from([0, S1 // 2, 2 * S1] + [S1] * 9))
        for kind in draw(st.permutations(list(_KINDS)))[: draw(st.integers(1, len(_KINDS)))]:
            odd = draw(st.floats(0, 1)) > _CLEAN_SHARE
            lines.append(draw(st.sampled_from(_KINDS[kind][1:])) if odd else _KINDS[kind][0])
            if draw(st.integers(0, 9)) == 0:
                lines.append(build("GPGSV", ["3", "1", "11", "03", "03", "111", "00"]))
        lines = [make if isinstance(make, str) else make(t) for make in lines]
    return "".join(lines).encode("latin-1")


@settings(max_examples=300, deadline=None)
@given(_epoch_log(), st.sampled_from([None, DAY]), st.integers(-2, 2), st.sampled_from([{}, {"uere_m": 2.0}]))
def test_columns_equal_the_reference_on_receiver_logs(data, day, offset_s, options) -> None:
    ctx = LogContext("boat", trial_date=day, clock_offset_ns=offset_s * S1, options=options)
    ref = _comparable(list(reference.convert_nmea_reference(data, ctx)))
    cols = nmea_columns.decode_columns(data)
    outputs = gps_columns.convert_columns(cols, ctx, gps.NO_DATE) if cols is not None else None
    if outputs is not None:  # the columnar path itself, not only `convert_nmea` (which may have fallen back)
        assert _comparable(list(outputs)) == ref
    assert _comparable(list(gps.convert_nmea(data, ctx))) == ref


def test_a_receiver_mix_takes_the_columnar_path() -> None:
    kinds = [variants[0] for variants in _KINDS.values()]
    data = "".join(make(T0 + k * S1) for k in range(5) for make in kinds).encode()
    cols = nmea_columns.decode_columns(data)
    assert cols is not None and gps_columns.convert_columns(cols, LogContext("boat"), gps.NO_DATE) is not None


def test_a_clean_receiver_log_takes_the_columnar_path() -> None:
    data = "".join(nmea.encode_gga(T0 + k * S1, 45.7, 126.6) + nmea.encode_rmc(T0 + k * S1, 45.7, 126.6)
                   for k in range(5)).encode()
    assert nmea_columns.decode_columns(data) is not None
    assert nmea_columns.decode_columns(data.replace(b"*", b"*0", 1)) is None  # damage: the per-line path


_SIGMA = st.one_of(st.just(math.nan), st.floats(0.0, 1e3), st.floats(allow_nan=True, allow_infinity=True))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(_SIGMA, _SIGMA, _SIGMA, _SIGMA, st.integers(-1, 10)), max_size=20),
       st.sampled_from([{}, {"uere_m": 2.0}, {"uere_m": "0.5"}]))
def test_covariance_columns_are_the_rule_per_epoch(rows, options) -> None:
    """`fix_covariance_columns` against `fix_covariance` epoch by epoch: the same doubles (bits), types and None."""
    lat, lon, alt, hdop, quality = (np.array(c, dtype=t) for c, t in zip(
        zip(*rows) if rows else ([],) * 5, (np.float64,) * 4 + (np.int64,)))
    matrix, kinds, known = fix_covariance_columns(lat, lon, alt, hdop, quality, options)
    for k, row in enumerate(rows):
        cov, kind = fix_covariance(*row, options)
        assert (kinds[k], bool(known[k])) == (kind, cov is not None)
        if cov is None:
            assert np.isnan(matrix[k]).all()
        else:
            assert np.array(cov, dtype=np.float64).tobytes() == matrix[k].tobytes()
