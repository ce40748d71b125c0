"""Writing archives: chunked, indexed, zstd-compressed MCAP with protobuf messages.

The file is written under a temporary name next to the target and renamed
only when `close()` finishes, so an interrupted write never leaves a file
that looks complete.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Mapping

from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, IndexType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

PROFILE = ""  # protobuf-encoded MCAP has no well-known profile
CHUNK_SIZE = 1024 * 1024


def _library() -> str:
    try:
        from importlib.metadata import version

        return f"auvreplay/{version('auvreplay')}"
    except Exception:  # noqa: BLE001 - running from a source tree
        return "auvreplay"


class ArchiveWriter:
    """Writes protobuf messages, metadata and attachments to an MCAP archive.

    Use as a context manager; on an exception the partial file is removed.
    Times are integer nanoseconds (UTC); there is no wall-clock default.
    """

    def __init__(self, path: str | os.PathLike[str], chunk_size: int = CHUNK_SIZE):
        self.path = Path(path)
        self.temp_path = self.path.with_name(f".{self.path.name}.part-{os.getpid()}")
        self._stream = open(self.temp_path, "wb")
        self._writer = Writer(
            self._stream,
            chunk_size=chunk_size,
            compression=CompressionType.ZSTD,
            index_types=IndexType.ALL,
            enable_crcs=True,
            enable_data_crcs=True,
        )
        self._writer.start(profile=PROFILE, library=_library())
        self._channels: dict[str, tuple[int, type]] = {}
        self._schemas: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self._closed = False

    def channel(self, topic: str, message_class: type) -> int:
        """The channel id for a topic, registering it (and its schema) on first use."""
        known = self._channels.get(topic)
        if known is not None:
            if known[1] is not message_class:
                raise TypeError(
                    f"topic {topic} carries {known[1].DESCRIPTOR.full_name}, "
                    f"not {message_class.DESCRIPTOR.full_name}"
                )
            return known[0]
        name = message_class.DESCRIPTOR.full_name
        schema_id = self._schemas.get(name)
        if schema_id is None:
            data = build_file_descriptor_set(message_class).SerializeToString()
            schema_id = self._writer.register_schema(name, SchemaEncoding.Protobuf, data)
            self._schemas[name] = schema_id
        channel_id = self._writer.register_channel(topic, MessageEncoding.Protobuf, schema_id)
        self._channels[topic] = (channel_id, message_class)
        self._sequence[channel_id] = 0
        return channel_id

    def write(self, topic: str, message: Any, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Append one message; publish time defaults to the log time (never the wall clock)."""
        channel_id = self.channel(topic, type(message))
        seq = self._sequence[channel_id]
        self._sequence[channel_id] = seq + 1
        self._writer.add_message(
            channel_id,
            log_time_ns,
            message.SerializeToString(),
            log_time_ns if publish_time_ns is None else publish_time_ns,
            seq,
        )

    def add_metadata(self, name: str, data: Mapping[str, Any]) -> None:
        """A metadata record; non-string values are stored as JSON text."""
        text = {k: v if isinstance(v, str) else json.dumps(v, sort_keys=True) for k, v in data.items()}
        self._writer.add_metadata(name, text)

    def add_attachment(
        self, name: str, data: bytes, media_type: str = "application/octet-stream",
        log_time_ns: int = 0, create_time_ns: int = 0,
    ) -> None:
        """An attachment, byte for byte (the record carries its own CRC)."""
        self._writer.add_attachment(create_time_ns, log_time_ns, name, media_type, data)

    def close(self) -> Path:
        """Finish the file (summary, indexes, footer) and move it to its final name."""
        if not self._closed:
            self._writer.finish()
            self._stream.flush()
            os.fsync(self._stream.fileno())
            self._stream.close()
            os.replace(self.temp_path, self.path)
            self._closed = True
        return self.path

    def abort(self) -> None:
        """Drop the partial file; the target name is never created."""
        if not self._closed:
            self._stream.close()
            self.temp_path.unlink(missing_ok=True)
            self._closed = True

    def __enter__(self) -> "ArchiveWriter":
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
