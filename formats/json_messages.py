"""Source records kept as they are: JSON messages with a JSON Schema, on MCAP `json` channels.

A log's records that have no schema of ours (a MAVLink HEARTBEAT, a MOOS
variable) are archived as JSON objects, as the MCAP specification's
well-known encodings define them (mcap.dev/spec/registry): the channel's
message encoding is `json` and its schema's encoding `jsonschema`, whose data
is a JSON Schema document. Foxglove, Rerun and the `mcap` library read them
without our code.

JSON has no NaN or infinity, so a float that is none is written as null
(and the schema allows null for every number); bytes are written as an array
of integers, so that nothing of the record is lost and the text stays JSON.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, ClassVar

MESSAGE_ENCODING = "json"
SCHEMA_ENCODING = "jsonschema"
_NUMBER = {"type": ["number", "null"]}


@dataclass(frozen=True, slots=True)
class JsonMessage:
    """One JSON message: its schema's name and JSON Schema text (shared by a topic's messages), its JSON bytes."""

    schema_name: str
    schema: str
    data: bytes
    # a channel's encodings, as `formats.ros_messages.RosMessage` gives them (the writer reads either)
    schema_encoding: ClassVar[str] = SCHEMA_ENCODING
    message_encoding: ClassVar[str] = MESSAGE_ENCODING

    def SerializeToString(self) -> bytes:  # the protobuf message method the writers call
        """The message's bytes on the wire: its JSON text."""
        return self.data

    @property
    def value(self) -> Any:
        """The decoded JSON value."""
        return json.loads(self.data)


def topic_level(name: str) -> str:
    """A source's name (a message type, a variable) as one topic level: letters, digits and underscores kept,
    anything else an underscore."""
    return "".join(c if c.isalnum() or c == "_" else "_" for c in name) or "UNNAMED"


def plain(value: Any) -> Any:
    """`value` as JSON holds it: NaN and infinities None, bytes a list of integers, tuples lists, other objects
    their text."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return str(value)


def _schema_of(value: Any) -> dict[str, Any]:
    if isinstance(value, bool):
        return {"type": "boolean"}
    if isinstance(value, (int, float)) or value is None:
        return dict(_NUMBER)
    if isinstance(value, str):
        return {"type": "string"}
    if isinstance(value, list):
        kinds = {json.dumps(_schema_of(v), sort_keys=True) for v in value}
        if len(kinds) == 1:
            return {"type": "array", "items": json.loads(kinds.pop())}
        return {"type": "array"}
    if isinstance(value, dict):
        return object_schema("", value)
    return {}


def object_schema(title: str, example: dict[str, Any], descriptions: dict[str, str] | None = None) -> dict[str, Any]:
    """A JSON Schema for objects shaped like `example` (plain values): its keys and their types, none required,
    so that a record with a field missing still validates."""
    props = {}
    for key, v in example.items():
        prop = _schema_of(v)
        if descriptions and key in descriptions:
            prop["description"] = descriptions[key]
        props[key] = prop
    out: dict[str, Any] = {"type": "object", "properties": props}
    if title:
        out = {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": title, **out}
    return out


def schema_text(schema: dict[str, Any]) -> str:
    """A JSON Schema as the schema record's data: compact, keys in a fixed order (same schema, same bytes)."""
    return json.dumps(schema, sort_keys=True, separators=(",", ":"))


def encode(value: dict[str, Any]) -> bytes:
    """A plain value's JSON bytes (no NaN tokens: `plain` first)."""
    return json.dumps(value, separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode("utf-8")


def message(schema_name: str, schema: str, value: dict[str, Any]) -> JsonMessage:
    """A JsonMessage of `value` (made plain here)."""
    return JsonMessage(schema_name, schema, encode(plain(value)))
