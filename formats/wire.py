"""Protobuf wire bytes of fixed runs of numeric fields, for the recording hot path's message builders.

upb sets a field through a keyword constructor at ~0.1 us an element; one
`FromString` of the numeric fields packed by one `struct.Struct` costs a
third to a half of that (bench/bench_pd0.py, bench/bench_nmea.py). The tags
and wire types here are never written by hand: each `FieldRun` reads them
from the generated modules' descriptors (`formats.auvreplay_pb2`,
foxglove's LocationFix) once, at import, so renumbering or retyping a field
changes the bytes with it, and a field the run cannot pack fails the import.
tests/test_wire.py checks every run's bytes are `SerializeToString()`'s.

A run packs, per field, its key bytes (tag, plus the length of a packed
repeated field) then its value: doubles and floats as such, bools and small
enums as one varint byte (the callers keep enums below 128). A hot caller
unpacks `keys` into locals and calls `struct.pack` with keys and values
interleaved; `pack` does the interleaving for anyone else.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, cast

from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix
from google.protobuf.descriptor import FieldDescriptor

from . import auvreplay_pb2 as pb

# field type -> (struct code of its value, protobuf wire type)
_SCALARS = {
    FieldDescriptor.TYPE_DOUBLE: ("d", 1),
    FieldDescriptor.TYPE_FLOAT: ("f", 5),
    FieldDescriptor.TYPE_BOOL: ("B", 0),  # one varint byte: 0 or 1
    FieldDescriptor.TYPE_ENUM: ("B", 0),  # one varint byte: the caller keeps the value in 0..127
}
_SIZES = {"d": 8, "f": 4}


def varint(n: int) -> bytes:
    """Base-128 varint of a non-negative integer (protobuf's encoding of tags, lengths and ints)."""
    out = bytearray()
    while True:
        low, n = n & 0x7F, n >> 7
        if n:
            out.append(low | 0x80)
        else:
            out.append(low)
            return bytes(out)


@dataclass(frozen=True)
class FieldRun:
    """Keys and struct of a run of one message type's fields, in the order given."""

    message_type: Any  # a generated message class
    names: tuple[str, ...]
    keys: tuple[bytes, ...]  # per field: tag bytes, plus the byte length of a packed repeated field
    counts: tuple[int, ...]  # per field: 1, or the number of values of a packed repeated field
    struct: struct.Struct

    def pack(self, *values: object) -> bytes:
        """Wire bytes of the run's fields: one value per field, a sequence for a packed repeated one."""
        if len(values) != len(self.names):
            raise TypeError(f"{len(self.names)} values expected, {len(values)} given")
        args: list[object] = []
        for key, count, value in zip(self.keys, self.counts, values):
            args.append(key)
            if count == 1:
                args.append(value)
            else:
                args.extend(cast(Sequence[float], value))  # a packed field's values
        return self.struct.pack(*args)


def field_run(message_type: Any, *fields: str | tuple[str, int]) -> FieldRun:
    """The run of `fields` of a generated message class: a name, or (name, count) for a packed repeated double."""
    names, keys, counts, codes = [], [], [], ["<"]
    by_name = message_type.DESCRIPTOR.fields_by_name
    for spec in fields:
        name, count = (spec, 1) if isinstance(spec, str) else spec
        fd = by_name[name]
        if fd.type not in _SCALARS:
            raise TypeError(f"{message_type.DESCRIPTOR.full_name}.{name}: no fixed-width packing for type {fd.type}")
        code, wire = _SCALARS[fd.type]
        repeated = fd.is_repeated
        if repeated != (count != 1) or (repeated and (code not in _SIZES or not fd.is_packed)):
            raise TypeError(f"{message_type.DESCRIPTOR.full_name}.{name}: (name, count) is for packed repeated doubles")
        if repeated:
            key = varint(fd.number << 3 | 2) + varint(_SIZES[code] * count)
        else:
            key = varint(fd.number << 3 | wire)
        names.append(name)
        keys.append(key)
        counts.append(count)
        codes.append(f"{len(key)}s{count if repeated else ''}{code}")
    return FieldRun(message_type, tuple(names), tuple(keys), tuple(counts), struct.Struct("".join(codes)))


# foxglove.LocationFix: position, covariance (row-major 3x3) and its type
LOCATION_FIX = field_run(LocationFix, "latitude", "longitude", "altitude", ("position_covariance", 9),
                         "position_covariance_type")
INS_STATE = field_run(
    pb.InsState, "latitude", "longitude", "depth_m", "roll_deg", "pitch_deg", "heading_deg", "velocity_north_mps",
    "velocity_east_mps", "velocity_down_mps", "heading_std_deg", "position_std_north_m", "position_std_east_m",
    "roll_std_deg", "pitch_std_deg", "altitude_m",
)
GNSS_STATUS = field_run(pb.GnssStatus, "hdop", "speed_over_ground_mps", "course_over_ground_deg", "heading_deg")
GNSS_VELOCITY = field_run(pb.GnssVelocity, "velocity_north_mps", "velocity_east_mps", "velocity_up_mps",
                          "speed_over_ground_mps", "course_over_ground_deg", "speed_std_mps")
DVL_VELOCITY = field_run(
    pb.DvlVelocity, "velocity_x_mps", "velocity_y_mps", "velocity_z_mps", "error_velocity_mps", ("beam_range_m", 4),
    "altitude_m", "valid", "sound_speed_mps", "temperature_c",
)
ACOUSTIC_RANGE = field_run(pb.AcousticRange, "travel_time_s", "range_m", "sound_speed_mps")
USBL_OBSERVATION = field_run(
    pb.UsblObservation, "travel_time_s", "range_m", "bearing_deg", "elevation_deg", "phase_x_rad", "phase_y_rad",
    "relative_east_m", "relative_north_m", "relative_up_m", "integrity", "rssi_db",
)
RUNS: dict[str, FieldRun] = {
    "location_fix": LOCATION_FIX, "ins_state": INS_STATE, "gnss_status": GNSS_STATUS, "gnss_velocity": GNSS_VELOCITY,
    "dvl_velocity": DVL_VELOCITY,
    "acoustic_range": ACOUSTIC_RANGE, "usbl_observation": USBL_OBSERVATION,
}
# auvreplay.Detection's doubles: the scores and paper A's features, then the filter-independent features
# (field numbers 13-22, in number order)
DETECTION_SCORES = field_run(pb.Detection, "score", "threshold", "feature_innovation_m", "feature_mahalanobis2",
                             "feature_r_adapted_m2")
DETECTION_EXTRA = field_run(pb.Detection, *(f.name for f in sorted(pb.Detection.DESCRIPTOR.fields,
                                                                   key=lambda f: f.number) if f.number >= 13))
