"""Flattening protobuf messages into pandas columns: one per scalar field."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
import pandas as pd
from google.protobuf.descriptor import FieldDescriptor

from .units import NS

_TIMESTAMP = "google.protobuf.Timestamp"


def _is_repeated(field: FieldDescriptor) -> bool:
    # protobuf >= 5 has is_repeated; older ones only label
    rep = getattr(field, "is_repeated", None)
    return bool(rep) if rep is not None else field.label == FieldDescriptor.LABEL_REPEATED


def flatten(message: Any) -> dict[str, Any]:
    """A dict of scalar fields; timestamps as UTC ns, enums by name, repeated numbers indexed.

    Repeated numeric fields become ``name_0, name_1, ...``; nested messages
    become ``parent.child`` columns. Repeated messages are left out.
    """
    row: dict[str, Any] = {}
    for field in message.DESCRIPTOR.fields:
        value = getattr(message, field.name)
        if field.type == FieldDescriptor.TYPE_MESSAGE:
            if _is_repeated(field):
                continue
            if field.message_type.full_name == _TIMESTAMP:
                row[field.name] = pd.Timestamp(value.seconds * NS + value.nanos, tz="UTC")
            else:
                for k, v in flatten(value).items():
                    row[f"{field.name}.{k}"] = v
        elif _is_repeated(field):
            for i, v in enumerate(value):
                row[f"{field.name}_{i}"] = v
        elif field.type == FieldDescriptor.TYPE_ENUM:
            names = field.enum_type.values_by_number
            row[field.name] = names[value].name if value in names else value
        else:
            row[field.name] = value
    return row


def messages_to_dataframe(messages: Iterable[Any]) -> pd.DataFrame:
    """DataFrame from ArchiveMessage items, indexed by log time (UTC)."""
    rows: list[dict[str, Any]] = []
    times: list[int] = []
    for item in messages:
        msg = item.message
        rows.append(flatten(msg) if hasattr(msg, "DESCRIPTOR") else {"data": msg})
        times.append(item.log_time_ns)
    index = pd.DatetimeIndex(pd.to_datetime(np.asarray(times, dtype="int64"), unit="ns", utc=True), name="log_time")
    return pd.DataFrame(rows, index=index)


def with_mission_seconds(df: pd.DataFrame, start_ns: int) -> pd.DataFrame:
    """A copy of a log-time-indexed frame with a first column `mission_s`: seconds from `start_ns`."""
    out = df.copy()
    ns = out.index.asi8 if isinstance(out.index, pd.DatetimeIndex) else np.asarray(out.index, dtype="int64")
    out.insert(0, "mission_s", (ns - np.int64(start_ns)) / 1e9)
    return out
