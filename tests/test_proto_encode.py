"""`formats.proto_encode`: messages encoded from columns are upb's `SerializeToString` bytes, byte for byte."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import schemas as S
from formats.proto_encode import encode_columns, split, varints
from formats.units import TIME_MAX_NS

# per field kind: values with every edge the encoder must match (zeros, -0.0, NaN, infinities, negatives)
DOUBLES = st.one_of(st.sampled_from([0.0, -0.0, math.nan, -math.nan, math.inf, -math.inf, 5e-324, 1e308]),
                    st.floats(allow_nan=True, allow_infinity=True))
INT32 = st.one_of(st.sampled_from([0, -1, 1, 127, 128, -(2 ** 31), 2 ** 31 - 1]), st.integers(-(2 ** 31), 2 ** 31 - 1))
ENUM = st.integers(0, 3)
TEXT = st.one_of(st.sampled_from(["", "nmea:GGA", "ä€😀"]), st.text(max_size=20))
TIMES = st.one_of(st.sampled_from([0, -1, 1, 999_999_999, 10 ** 9, TIME_MAX_NS - 1, TIME_MAX_NS, -(2 ** 63)]),
                  st.integers(-(2 ** 63), 2 ** 63 - 1))

CLASSES = [S.LocationFix, S.GnssStatus, S.GnssVelocity, S.InsState, S.DvlVelocity, S.AcousticRange,
           S.UsblObservation]


def _strategy(cls: type, name: str) -> st.SearchStrategy:
    f = cls.DESCRIPTOR.fields_by_name[name]
    if f.type == f.TYPE_DOUBLE:
        return st.lists(DOUBLES, min_size=4, max_size=4) if f.is_repeated else DOUBLES
    if f.type == f.TYPE_ENUM:
        return ENUM
    if f.type == f.TYPE_BOOL:
        return st.booleans()
    if f.type in (f.TYPE_INT32, f.TYPE_INT64):
        return INT32
    if f.type == f.TYPE_STRING:
        return TEXT
    return TIMES  # the Timestamp


def _encodable(cls: type) -> list[str]:
    """The fields the recorder gives as columns: scalars without explicit presence, strings, packed doubles,
    Timestamps (not DvlVelocity's device_time, which the block paths never set)."""
    out = []
    for f in cls.DESCRIPTOR.fields:
        if f.type == f.TYPE_MESSAGE and (f.message_type.full_name != "google.protobuf.Timestamp"
                                         or f.name == "device_time"):
            continue
        if not f.is_repeated and f.has_presence and f.type != f.TYPE_MESSAGE:
            continue  # proto3 `optional`: set means written, even at 0
        if f.is_repeated and f.type != f.TYPE_DOUBLE:
            continue
        out.append(f.name)
    return out


def _reference(cls: type, row: dict) -> bytes:
    """The row's message built through upb (the Timestamp as `set_timestamp` sets it) and serialized."""
    msg = cls()
    for name, value in row.items():
        if name == "timestamp":
            S.set_timestamp(msg.timestamp, value)
        elif isinstance(value, list):
            getattr(msg, name).extend(value)
        else:
            setattr(msg, name, value)
    return msg.SerializeToString()


@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: c.DESCRIPTOR.name)
@settings(max_examples=80, deadline=None)
@given(data=st.data(), n=st.integers(1, 6))
def test_encoded_columns_are_upbs_bytes(cls, data, n):
    names = [name for name in _encodable(cls) if data.draw(st.booleans(), label=f"give {name}")]
    rows = [{name: data.draw(_strategy(cls, name), label=name) for name in names} for _ in range(n)]
    columns = {}
    for name in names:
        values = [row[name] for row in rows]
        f = cls.DESCRIPTOR.fields_by_name[name]
        if f.type == f.TYPE_STRING:
            columns[name] = values if data.draw(st.booleans(), label="as list") or len(set(values)) > 1 \
                else values[0]  # one string for every row, as a constant column
        elif f.type == f.TYPE_DOUBLE:
            columns[name] = np.array(values, dtype=np.float64)
        else:
            columns[name] = np.array(values, dtype=np.int64)
    blob, ends = encode_columns(cls, n, columns)
    assert [bytes(b) for b in split(blob, ends)] == [_reference(cls, row) for row in rows]


def test_a_scalar_column_is_every_rows_value():
    blob, ends = encode_columns(S.GnssStatus, 3, {"timestamp": np.array([1, 2, 3]) * 10 ** 9, "frame_id": "v",
                                                  "hdop": 1.5, "fix_quality": -1})
    expected = [S.gnss_status(t * 10 ** 9, "v", -1, 0, 1.5, "", 0.0, 0.0, 0.0).SerializeToString() for t in (1, 2, 3)]
    assert split(blob, ends) == expected


def test_nan_payloads_keep_their_bits():
    quiet_negative = np.array([0x7FF8000000000001, 0xFFF8000000000000], dtype=np.uint64).view(np.float64)
    blob, ends = encode_columns(S.GnssVelocity, 2, {"velocity_up_mps": quiet_negative})
    for value, data in zip(quiet_negative.tolist(), split(blob, ends)):
        msg = S.GnssVelocity()
        msg.velocity_up_mps = value
        assert data == msg.SerializeToString()


@given(st.lists(st.integers(0, 2 ** 64 - 1), min_size=1, max_size=20))
def test_varints_are_base_128(values):
    mat, lens = varints(np.array(values, dtype=np.uint64))
    for row, n, v in zip(mat, lens, values):
        out, x = bytearray(), v
        while True:
            out.append((x & 0x7F) | (0x80 if x > 0x7F else 0))
            x >>= 7
            if not x:
                break
        assert bytes(row[:n]) == bytes(out)


def test_unsupported_fields_are_refused():
    with pytest.raises(TypeError, match="color"):
        encode_columns(S.LocationFix, 1, {"color": [None]})
    assert encode_columns(S.GnssStatus, 0, {"hdop": np.zeros(0)})[0] == b""


OPTIONAL = ("angular_velocity_x_radps", "angular_velocity_y_radps", "angular_velocity_z_radps",
            "linear_acceleration_x_mps2", "linear_acceleration_y_mps2", "linear_acceleration_z_mps2")


@settings(max_examples=80, deadline=None)
@given(data=st.data(), n=st.integers(1, 6))
def test_optional_doubles_are_written_where_set(data, n):
    """A proto3 `optional` double (InsState's body rates): written where set, 0.0 too; a masked row leaves it unset,
    as upb does for a field never assigned."""
    rows = [{"timestamp": data.draw(TIMES), "heading_deg": data.draw(DOUBLES)} for _ in range(n)]
    columns: dict = {"timestamp": np.array([r["timestamp"] for r in rows], dtype=np.int64),
                     "heading_deg": np.array([r["heading_deg"] for r in rows])}
    for name in OPTIONAL:
        how = data.draw(st.sampled_from(["absent", "array", "masked", "scalar"]), label=name)
        if how == "absent":
            continue
        values = [data.draw(DOUBLES, label=name) for _ in range(n)]
        if how == "scalar":
            values = [values[0]] * n
            columns[name] = values[0]
        elif how == "array":
            columns[name] = np.array(values)
        else:
            mask = [data.draw(st.booleans(), label="masked") for _ in range(n)]
            columns[name] = np.ma.masked_array(values, mask=mask)
            values = [None if m else v for v, m in zip(values, mask)]
        for row, v in zip(rows, values):
            if v is not None:
                row[name] = v
    blob, ends = encode_columns(S.InsState, n, columns)
    assert [bytes(b) for b in split(blob, ends)] == [_reference(S.InsState, row) for row in rows]


@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: c.DESCRIPTOR.name)
@settings(max_examples=60, deadline=None)
@given(data=st.data(), n=st.integers(1, 5))
def test_one_value_for_every_row_is_each_rows_value(cls, data, n):
    """A column given as one Python or numpy value (written once, then side by side with the others) gives each row
    what an array of that value does, and upb's bytes."""
    names = [name for name in _encodable(cls) if name != "timestamp" and not cls.DESCRIPTOR.fields_by_name[name].is_repeated
             and data.draw(st.booleans(), label=f"give {name}")]
    row = {name: data.draw(_strategy(cls, name), label=name) for name in names}
    columns: dict = {"timestamp": np.arange(n, dtype=np.int64) * 10 ** 9 + 1_476_237_600 * 10 ** 9}
    for name, value in row.items():
        f = cls.DESCRIPTOR.fields_by_name[name]
        if f.type == f.TYPE_DOUBLE:
            columns[name] = data.draw(st.sampled_from([float, np.float64]), label="as")(value)
        elif f.type == f.TYPE_STRING:
            columns[name] = value
        else:
            columns[name] = data.draw(st.sampled_from([int, np.int64]), label="as")(value)
    blob, ends = encode_columns(cls, n, columns)
    expected = [_reference(cls, {**row, "timestamp": int(t)}) for t in columns["timestamp"]]
    assert [bytes(b) for b in split(blob, ends)] == expected
    arrays = {k: (v if isinstance(v, (str, np.ndarray)) else np.full(n, v)) for k, v in columns.items()}
    assert encode_columns(cls, n, arrays)[0] == blob
