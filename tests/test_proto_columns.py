"""formats.proto_columns against the protobuf runtime: the same values, and every other message left to it."""

from __future__ import annotations

import math

import numpy as np
from google.protobuf.message import DecodeError
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import schemas as S
from formats.mcap_blocks import COLUMN_FIELDS
from formats.proto_columns import decode_columns

CLASSES = {name: S.MESSAGE_CLASSES[name] for name in COLUMN_FIELDS}
doubles = st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from([0.0, -0.0, math.nan])
text = st.text(max_size=12)     # non-ASCII too: the runtime's to check


@st.composite
def messages(draw: st.DrawFn, schema: str) -> bytes:
    cls = CLASSES[schema]
    kw: dict[str, object] = {"frame_id": draw(text)}
    if draw(st.booleans()):
        kw["timestamp"] = S.timestamp(draw(st.integers(0, 2**62)))
    for f in cls.DESCRIPTOR.fields:
        if f.type == 1 and not getattr(f, "is_repeated", False) and draw(st.booleans()):
            kw[f.name] = draw(doubles)
    if schema == "auvreplay.DvlVelocity":
        kw["valid"] = draw(st.booleans())
        kw["frame"] = draw(st.integers(-3, 5))
        kw["beam_range_m"] = draw(st.lists(doubles, max_size=4))
    if schema == "auvreplay.InsState":
        kw["status"] = draw(text)
    return cls(**kw).SerializeToString()


@st.composite
def damaged(draw: st.DrawFn, schema: str) -> bytes:
    data = bytearray(draw(messages(schema)))
    for _ in range(draw(st.integers(0, 3))):
        what = draw(st.sampled_from(["flip", "cut", "append"]))
        if what == "flip" and data:
            i = draw(st.integers(0, len(data) - 1))
            data[i] = draw(st.integers(0, 255))
        elif what == "cut" and data:
            del data[draw(st.integers(0, len(data) - 1)):]
        else:
            data += draw(st.binary(max_size=12))
    return bytes(data)


def same(a: float, b: float) -> bool:
    return np.float64(a).tobytes() == np.float64(b).tobytes() or (math.isnan(a) and math.isnan(b))


@settings(max_examples=150, deadline=None)
@given(st.sampled_from(sorted(CLASSES)).flatmap(lambda s: st.tuples(st.just(s), st.lists(
    damaged(s) | messages(s), min_size=1, max_size=25))))
def test_columns_equal_the_runtime_or_are_left_to_it(case: tuple[str, list[bytes]]) -> None:
    schema, datas = case
    cls, names = CLASSES[schema], COLUMN_FIELDS[schema]
    cols, ok = decode_columns(datas, cls, names)
    for i, data in enumerate(datas):
        try:
            m = cls.FromString(data)
        except DecodeError:
            assert not ok[i], "the walk vouched for a message the runtime refuses"
            continue
        if ok[i]:
            for name in names:
                assert same(cols[name][i], float(getattr(m, name))), name


def test_our_writers_messages_take_the_fast_walk() -> None:
    ins = [S.InsState(timestamp=S.timestamp(10**18 + i), frame_id="follower", latitude=47.1 + i, longitude=8.2,
                      depth_m=2.0, heading_deg=float(i)).SerializeToString() for i in range(50)]
    cols, ok = decode_columns(ins, S.InsState, COLUMN_FIELDS["auvreplay.InsState"])
    assert ok.all() and cols["latitude"].tolist() == [47.1 + i for i in range(50)]
    assert cols["heading_deg"].tolist() == [float(i) for i in range(50)] and (cols["depth_m"] == 2.0).all()


def test_a_message_of_very_many_fields_is_left_to_the_runtime() -> None:
    """A crafted message repeating one double field 5000 times: the runtime decodes it (the last one wins)."""
    one = S.InsState(latitude=1.0).SerializeToString()
    many = one * 4999 + S.InsState(latitude=2.5).SerializeToString()
    cols, ok = decode_columns([many, one], S.InsState, ("latitude",))
    assert ok.tolist() == [False, True] and cols["latitude"][1] == 1.0
    assert S.InsState.FromString(many).latitude == 2.5


def test_long_strings_ascii_or_not() -> None:
    """Strings past the word-wise ASCII check (over 64 bytes) go by the prefix count: ASCII ones are walked, others
    left to the runtime, beside short ones in the same block."""
    texts = ["a" * 70, "é" * 40, "follower", "ü", "b" * 64, "c" * 63 + "é"]
    ins = [S.InsState(frame_id=t, latitude=float(i) + 0.5).SerializeToString() for i, t in enumerate(texts)]
    cols, ok = decode_columns(ins, S.InsState, ("latitude",))
    assert ok.tolist() == [t.isascii() for t in texts]
    assert [c for c, k in zip(cols["latitude"].tolist(), ok.tolist()) if k] == \
        [i + 0.5 for i, t in enumerate(texts) if t.isascii()]
    words = ["follower", "ü", "b" * 64, "c" * 60 + "é", "d" * 9 + "é"]      # at most 64 bytes: word by word
    short = [S.InsState(frame_id=t, latitude=1.0).SerializeToString() for t in words]
    assert decode_columns(short, S.InsState, ("latitude",))[1].tolist() == [t.isascii() for t in words]
