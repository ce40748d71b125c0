"""CSV logs of any sensor family, mapped to archive messages by the manifest's `columns` table.

Manifest keys of a csv log:

    format = "csv"
    columns = { time = "t_unix", range_m = "range", source = "from" }   # message field = column
    time_format = "unix"        # unix (seconds), unix_ms, iso8601, or tod (HH:MM:SS[.f], with the trial date)
    delimiter = ","             # optional; sniffed from the header otherwise

Fields are those of the family's message (`auvreplay formats` lists them);
`time` is required. Empty cells stay NaN / empty.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from datetime import UTC, datetime
from typing import Any

from google.protobuf.descriptor import FieldDescriptor

from formats import csv_table
from formats import schemas as S
from formats.log_blocks import LogText
from formats.numbers import finite, integer, optional, optional_integer
from formats.records import FormatError, Reject
from formats.units import NS, archivable_ns

from .base import LogContext, Output, output
from .clock import DayClock

# family -> (message class, topic suffix)
FAMILY_MESSAGES: dict[str, tuple[Any, str]] = {
    "gps": (S.LocationFix, "gps"),
    "ins": (S.InsState, "ins"),
    "dvl": (S.DvlVelocity, "dvl"),
    "modem": (S.AcousticRange, "modem/range"),
    "usbl": (S.UsblObservation, "usbl"),
}


def _time_parser(kind: str, ctx: LogContext) -> Callable[[str], int | None]:
    if kind == "unix":
        return lambda s: round(finite(s, "time") * NS)
    if kind == "unix_ms":
        return lambda s: round(finite(s, "time") * 1_000_000)
    if kind == "iso8601":
        def iso(s: str) -> int:
            dt = datetime.fromisoformat(s.replace("Z", "+00:00"))
            dt = dt if dt.tzinfo else dt.replace(tzinfo=UTC)
            return round(dt.timestamp() * NS)
        return iso
    if kind == "tod":
        clock = DayClock(ctx.trial_date)

        def tod(s: str) -> int | None:
            h, m, sec = s.split(":")
            return clock.resolve(integer(h, "hours") * 3600 + integer(m, "minutes") * 60 + finite(sec, "seconds"))
        return tod
    raise FormatError(f"{ctx.path}: time_format {kind!r} unknown; use unix, unix_ms, iso8601 or tod")


def _setter(cls: Any, name: str, path: str) -> Callable[[Any, str], None]:
    field = cls.DESCRIPTOR.fields_by_name.get(name)
    if field is None or field.type == FieldDescriptor.TYPE_MESSAGE:
        known = sorted(f.name for f in cls.DESCRIPTOR.fields if f.type != FieldDescriptor.TYPE_MESSAGE)
        raise FormatError(f"{path}: column mapping names {name!r}, not a field of {cls.DESCRIPTOR.full_name} "
                          f"(fields: time, {', '.join(known)})")
    if field.type in (FieldDescriptor.TYPE_DOUBLE, FieldDescriptor.TYPE_FLOAT):
        return lambda msg, v: setattr(msg, name, optional(v, name))
    if field.type == FieldDescriptor.TYPE_BOOL:
        return lambda msg, v: setattr(msg, name, v.strip().lower() in ("1", "true", "yes", "y"))
    if field.type == FieldDescriptor.TYPE_STRING:
        return lambda msg, v: setattr(msg, name, v)
    if field.type == FieldDescriptor.TYPE_ENUM:
        return lambda msg, v: setattr(msg, name, field.enum_type.values_by_name[v].number if v else 0)
    return lambda msg, v: setattr(msg, name, optional_integer(v, name))


def _new_message(cls: Any, ctx: LogContext) -> Any:
    """A message with every number missing (NaN, or -1 for counts and addresses)."""
    msg = cls()
    for f in cls.DESCRIPTOR.fields:
        if _repeated(f):
            continue
        if f.type in (FieldDescriptor.TYPE_DOUBLE, FieldDescriptor.TYPE_FLOAT):
            setattr(msg, f.name, math.nan)
        elif f.type == FieldDescriptor.TYPE_INT32:
            setattr(msg, f.name, -1)
    if cls is S.LocationFix:
        msg.position_covariance.extend([math.nan] * 9)
    for name in ("frame_id", "destination", "node"):
        if name in cls.DESCRIPTOR.fields_by_name:
            setattr(msg, name, ctx.vehicle)
    return msg


def _repeated(f: FieldDescriptor) -> bool:
    rep = getattr(f, "is_repeated", None)
    return bool(rep) if rep is not None else f.label == FieldDescriptor.LABEL_REPEATED


def _complete(msg: Any, ctx: LogContext) -> None:
    """Fill what follows from what was given: sound speed, and range from travel time or back."""
    if not hasattr(msg, "travel_time_s"):
        return
    if hasattr(msg, "sound_speed_mps") and math.isnan(msg.sound_speed_mps):
        msg.sound_speed_mps = ctx.sound_speed_mps
    c = getattr(msg, "sound_speed_mps", ctx.sound_speed_mps)
    if math.isnan(msg.range_m) and not math.isnan(msg.travel_time_s):
        msg.range_m = msg.travel_time_s * c
    elif math.isnan(msg.travel_time_s) and not math.isnan(msg.range_m):
        msg.travel_time_s = msg.range_m / c


def converter_for(family: str) -> Callable[[LogText, LogContext], Iterator[Output | Reject]]:
    """The CSV converter of one sensor family."""
    cls, suffix = FAMILY_MESSAGES[family]

    def convert(data: LogText, ctx: LogContext) -> Iterator[Output | Reject]:
        """CSV with a column mapping given in the manifest."""
        columns = ctx.options.get("columns")
        if not isinstance(columns, dict) or "time" not in columns:
            raise FormatError(f"{ctx.path}: a csv log needs columns = {{ time = \"<column>\", ... }}")
        parse_time = _time_parser(str(ctx.options.get("time_format", "unix")), ctx)
        setters = {field: _setter(cls, field, ctx.path) for field in columns if field != "time"}
        for row in csv_table.decode(data, ctx.options.get("delimiter")):
            if isinstance(row, Reject):
                yield row
                continue
            try:
                missing = [c for c in columns.values() if c not in row.values]
                if missing:
                    raise KeyError(f"column {missing[0]!r} not in the header")
                t = parse_time(row.values[columns["time"]])
                if t is None:
                    raise ValueError("time of day without a date (set [trial] date)")
                if not archivable_ns(t + ctx.clock_offset_ns):
                    raise ValueError(f"time {row.values[columns['time']][:40]!r} is outside 1970-2200")
                msg = _new_message(cls, ctx)
                for field, set_value in setters.items():
                    set_value(msg, row.values[columns[field]])
            except (ValueError, KeyError, OverflowError) as exc:
                yield Reject(row.where, f"bad row: {exc}")
                continue
            _complete(msg, ctx)
            t += ctx.clock_offset_ns
            S.set_timestamp(msg.timestamp if "timestamp" in cls.DESCRIPTOR.fields_by_name else msg.time, t)
            yield output(ctx, suffix, msg, t, row.where)

    return convert
