"""formats.wire: every field run's bytes are protobuf's own serialization of the same values."""

from __future__ import annotations

import math

import pytest
from google.protobuf.descriptor import FieldDescriptor
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import wire

_DOUBLE = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.just(-0.0), st.just(0.0))


def _value(run: wire.FieldRun, name: str, count: int) -> st.SearchStrategy:
    fd = run.message_type.DESCRIPTOR.fields_by_name[name]
    if count != 1:
        return st.lists(_DOUBLE, min_size=count, max_size=count)
    if fd.type == FieldDescriptor.TYPE_BOOL:
        return st.booleans()
    if fd.type == FieldDescriptor.TYPE_ENUM:
        return st.sampled_from([v.number for v in fd.enum_type.values if 0 <= v.number < 128])
    return _DOUBLE


def _values(run: wire.FieldRun) -> st.SearchStrategy:
    return st.tuples(*(_value(run, n, c) for n, c in zip(run.names, run.counts)))


def _is_default(v: object) -> bool:
    """True for a value proto3 leaves out of the bytes: +0.0, False, 0 (a packed list is always written)."""
    if isinstance(v, list):
        return not v
    if isinstance(v, float):
        return v == 0.0 and math.copysign(1.0, v) > 0
    return not v


@pytest.mark.parametrize("name", sorted(wire.RUNS))
@settings(max_examples=80, deadline=None)
@given(data=st.data())
def test_run_bytes_are_protobufs_serialization(name, data) -> None:
    run = wire.RUNS[name]
    values = data.draw(_values(run))
    packed = run.pack(*values)
    reference = run.message_type(**dict(zip(run.names, values))).SerializeToString()
    # field by field, as protobuf writes them: equal bytes, except where proto3 leaves a default value out
    if not any(_is_default(v) for v in values):
        assert packed == reference
    assert run.message_type.FromString(packed).SerializeToString() == reference


def test_keys_follow_the_descriptors() -> None:
    run = wire.DVL_VELOCITY
    fields = run.message_type.DESCRIPTOR.fields_by_name
    assert run.keys[0] == wire.varint(fields["velocity_x_mps"].number << 3 | 1)
    assert run.keys[4] == wire.varint(fields["beam_range_m"].number << 3 | 2) + wire.varint(32)
    assert wire.varint(300) == b"\xac\x02" and wire.varint(0) == b"\x00"


def test_a_field_the_run_cannot_pack_fails_at_once() -> None:
    with pytest.raises(TypeError):
        wire.field_run(wire.pb.DvlVelocity, "source_format")
    with pytest.raises(TypeError):
        wire.field_run(wire.pb.DvlVelocity, "beam_range_m")  # a repeated field needs its count


@settings(max_examples=150, deadline=None)
@given(t_ns=st.one_of(st.integers(0, 1 << 64), st.integers(1_700_000_000 * 10**9, 1_700_000_100 * 10**9)),
       frame=st.text(max_size=12), lat=_DOUBLE, lon=_DOUBLE, alt=_DOUBLE,
       cov=st.lists(_DOUBLE, min_size=9, max_size=9), kind=st.sampled_from([0, 1, 2, 3]))
def test_location_fix_bytes_are_the_messages(t_ns, frame, lat, lon, alt, cov, kind) -> None:
    from formats import schemas as S

    tail = S.location_fix_tail(t_ns, frame)
    got = S.location_fix_bytes(tail, t_ns, frame, lat, lon, alt, tuple(cov), kind)
    assert got == S.location_fix(t_ns, frame, lat, lon, alt, tuple(cov), kind).SerializeToString()


_NAMES = st.text(max_size=10)
_NONZERO = st.floats(allow_nan=True, allow_infinity=True).filter(lambda v: v != 0.0)   # the packed path's
_N_EXTRA = len(wire.DETECTION_EXTRA.names)    # every Detection field from 13 on


@settings(max_examples=200, deadline=None)
@given(t_ns=st.one_of(st.integers(-1, 1 << 64), st.integers(1_700_000_000 * 10**9, 1_700_000_100 * 10**9)),
       follower=_NAMES, leader=_NAMES, method=_NAMES, flagged=st.booleans(), capped=st.booleans(),
       scores=st.lists(_NONZERO, min_size=5, max_size=5) | st.lists(_DOUBLE, min_size=5, max_size=5),
       label=st.sampled_from([-1, 0, 1]) | st.integers(-(1 << 31), (1 << 31) - 1),
       extra=st.lists(_NONZERO, min_size=_N_EXTRA, max_size=_N_EXTRA)
       | st.lists(_DOUBLE, min_size=_N_EXTRA, max_size=_N_EXTRA))
def test_detection_bytes_are_the_messages(t_ns, follower, leader, method, flagged, capped, scores, label,
                                          extra) -> None:
    from formats import schemas as S

    got = S.detection_bytes(S.detection_stamp(t_ns), t_ns, follower, leader, method, flagged, tuple(scores), label,
                            capped, tuple(extra))
    assert got == S.detection(t_ns, follower, leader, method, flagged, tuple(scores), label, capped,
                              tuple(extra)).SerializeToString()


def test_detection_bytes_take_the_packed_path_for_every_extra_field(monkeypatch) -> None:
    """A field added to Detection joins the packed path: with nonzero doubles the message is never built."""
    from formats import schemas as S

    want = S.detection(5_000_000_000, "f", "l1", "chi_square", True, (1.5,) * 5, 1, False,
                       tuple(float(i + 1) for i in range(_N_EXTRA))).SerializeToString()

    def no_message(*args, **kwargs):
        raise AssertionError("the message path was taken")

    monkeypatch.setattr(S, "detection", no_message)
    got = S.detection_bytes(S.detection_stamp(5_000_000_000), 5_000_000_000, "f", "l1", "chi_square", True,
                            (1.5,) * 5, 1, False, tuple(float(i + 1) for i in range(_N_EXTRA)))
    assert got == want
