"""formats.pashr: the published $PASHR example, quirks, round trips, no-raise."""

from __future__ import annotations

import math

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from formats import pashr
from formats.nmea.framing import build

# The example of the RT300/Applanix $PASHR description (its own checksum).
EXAMPLE = b"$PASHR,085335.000,224.19,T,-01.26,+00.83,+00.00,0.101,0.113,0.267,1,0*06\r\n"


def test_published_example() -> None:
    (r,) = pashr.decode(EXAMPLE)
    assert isinstance(r, pashr.Pashr)
    assert r.time_s == 8 * 3600 + 53 * 60 + 35
    assert (r.heading_deg, r.heading_true, r.roll_deg, r.pitch_deg, r.heave_m) == (224.19, True, -1.26, 0.83, 0.0)
    assert (r.roll_std_deg, r.pitch_std_deg, r.heading_std_deg) == (0.101, 0.113, 0.267)
    assert (r.gnss_quality, r.ins_status) == (1, 0)


def test_quirks() -> None:
    data = (
        EXAMPLE.replace(b"*06", b"*07")  # bad checksum
        + EXAMPLE[:40] + b"\r\n"  # truncated
        + build("PASHR", ["POS", "0", "12", "123519.00"]).encode()  # Ashtech reply: skipped
        + build("PASHR", ["", "10.0", "T", "", "", "", "", "", ""]).encode()  # empty fields, no flags
        + b"\xff\xfe\x00junk\r\n"
        + build("GPHDT", ["1.0", "T"]).encode()  # another family: skipped
    )
    out = list(pashr.decode(data))
    assert [type(r).__name__ for r in out] == ["Reject", "Reject", "Pashr", "Reject"]
    assert out[0].bad_checksum and "truncated" in out[1].reason
    e = out[2]
    assert math.isnan(e.time_s) and math.isnan(e.roll_deg) and e.heading_deg == 10.0
    assert (e.gnss_quality, e.ins_status) == (-1, -1)


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 86_399_999) , st.floats(0, 359.99), st.floats(-90, 90), st.floats(-90, 90),
       st.floats(0, 9.9), st.integers(0, 2), st.integers(0, 1))
@example(0, 0.0, 0.0, 0.875, 0.0, 0, 0)   # on a rounding boundary: 0.88, off by 0.005 plus float error
def test_round_trip(ms: int, hdg: float, roll: float, pitch: float, std: float, q: int, s: int) -> None:
    line = pashr.encode_pashr(ms * 1_000_000, hdg, roll, pitch, roll_std_deg=std, gnss_quality=q, ins_status=s)
    (r,) = pashr.decode(line.encode())
    assert r.time_s == pytest.approx(ms / 1000, abs=1e-6)
    # two decimals: within half a step, plus the float error of a value on a rounding boundary (0.875 -> 0.88)
    assert abs(r.roll_deg - roll) <= 0.005 + 1e-9 and abs(r.pitch_deg - pitch) <= 0.005 + 1e-9
    assert (r.gnss_quality, r.ins_status) == (q, s)
    again = pashr.encode_pashr(round(r.time_s * 1e9), r.heading_deg, r.roll_deg, r.pitch_deg, heave_m=r.heave_m,
                               roll_std_deg=r.roll_std_deg, pitch_std_deg=r.pitch_std_deg,
                               heading_std_deg=r.heading_std_deg, gnss_quality=r.gnss_quality, ins_status=r.ins_status)
    assert again == line


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_no_bytes_make_decode_raise(data: bytes) -> None:
    list(pashr.decode(data))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.text(alphabet="0123456789.+-TP", max_size=12), max_size=12))
def test_no_sentence_like_text_makes_decode_raise(parts: list[str]) -> None:
    list(pashr.decode(build("PASHR", parts).encode()))
