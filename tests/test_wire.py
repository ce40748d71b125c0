"""formats.wire: message bytes built directly equal protobuf's own serialization."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from formats import schemas as S
from formats.wire import location_fix_bytes, varint

DOUBLES = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -0.0, 1e-300]))


@settings(max_examples=300, deadline=None)
@given(st.integers(-(2**62), 2**62), st.text(max_size=20), DOUBLES, DOUBLES, DOUBLES,
       st.lists(DOUBLES, min_size=9, max_size=9), st.integers(0, 3))
def test_location_fix_bytes_equal_protobuf(t_ns, frame_id, lat, lon, alt, cov, kind) -> None:
    want = S.location_fix(t_ns, frame_id, lat, lon, alt, tuple(cov), kind).SerializeToString()
    assert location_fix_bytes(t_ns, frame_id, lat, lon, alt, tuple(cov), kind) == want


def test_varint_known_values() -> None:
    assert varint(0) == b"\x00" and varint(1) == b"\x01" and varint(300) == b"\xac\x02"
    assert varint(-1) == b"\xff" * 9 + b"\x01"
