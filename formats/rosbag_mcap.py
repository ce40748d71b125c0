"""ROS 2 bags in MCAP storage, read in bounded memory: a storage plugin for rosbags' readers.

rosbags' own MCAP storage inflates a chunk whole, whatever it holds (an lz4
or zstd chunk of a few KB may inflate to gigabytes), and inflates every chunk
when opening a file without a summary. Here the file is indexed and read with
our MCAP chunk reader (`mcap_records`, `mcap_chunks`): a chunk inflates only
when it declares at most `MAX_CHUNK_BYTES` and never past what it declares,
chunks are read when their time comes, and a chunk refused or damaged is kept
in `BoundedMcapStorage.problems` ("byte N: why") for the bag reader to
count, while the others are read.

The plugin has rosbags' storage interface (connections, metadata, messages),
so the single-file and bag-folder readers (`bounded_reader`) use it for
``.mcap`` files and their metadata, QoS and definitions as rosbags would.
"""

from __future__ import annotations

from collections.abc import Collection, Generator
from pathlib import Path
from typing import Any

import zstandard

from .mcap_chunks import MAX_CHUNK_BYTES, mib, ordered_messages
from .mcap_records import MAGIC, read_summary, scan
from .records import FormatError

# an MCAP schema's encoding -> rosbags' MessageDefinitionFormat name
_DEFINITION_FORMATS = {"ros2msg": "MSG", "ros2idl": "IDL", "omgidl": "IDL"}


class BoundedMcapStorage:
    """rosbags' storage protocol over one MCAP file, every chunk inflated within its declared size and the cap."""

    def __init__(self, path: Any) -> None:
        from rosbags.rosbag2.metadata import ReaderMetadata

        self.path = Path(path)
        self.connections: list[Any] = []
        self.metadata = ReaderMetadata(0, 2**63 - 1, 0, 0, None, None, None, None)
        self.problems: list[str] = []   # "byte N: why" of each chunk or record not read
        self._file: Any = None
        self._chunks: list[Any] = []
        self._loose: list[tuple[int, int, int, bytes]] = []

    def open(self) -> None:
        """Index the file: its summary, or a bounded scan of its records when it has none (a cut-off write)."""
        from rosbags.interfaces import Connection, ConnectionExtRosbag2, MessageDefinition, MessageDefinitionFormat
        from rosbags.rosbag2.metadata import ReaderMetadata, parse_qos

        self._file = self.path.open("rb")
        size = self.path.stat().st_size
        if self._file.read(len(MAGIC)) != MAGIC:
            raise FormatError(f"{self.path.name}: no MCAP magic at its start")
        summary, _ = read_summary(self._file, size, True)
        if summary is None or summary.statistics is None:
            found = scan(self._file, size, True, MAX_CHUNK_BYTES, self._report)
            if summary is None:
                summary, self._loose = found.summary, found.loose
            else:
                summary.statistics = found.summary.statistics
        stats = summary.statistics
        counts = dict(stats.channel_message_counts) if stats is not None else {}
        for cid, channel in sorted(summary.channels.items()):
            schema = summary.schemas.get(channel.schema_id)
            fmt = _DEFINITION_FORMATS.get(schema.encoding, "NONE") if schema is not None else "NONE"
            text = schema.data.decode("utf-8", "replace") if schema is not None and fmt != "NONE" else ""
            self.connections.append(Connection(
                cid, channel.topic, schema.name if schema is not None else "__schemaless__",
                MessageDefinition(MessageDefinitionFormat[fmt], text), "", counts.get(cid, 0),
                ConnectionExtRosbag2(channel.message_encoding,
                                     parse_qos(channel.metadata.get("offered_qos_profiles", ""))), self))
        self._chunks = list(summary.chunk_indexes)
        count = sum(counts.values())
        start = stats.message_start_time if stats is not None and count else 2**63 - 1
        end = stats.message_end_time + 1 if stats is not None and count else 0
        self.metadata = ReaderMetadata(max(end - start, 0), start, end, count, None, None, None, None)

    def _report(self, where: str, what: str) -> None:
        self.problems.append(f"{where}: {what}")

    def close(self) -> None:
        """Close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None

    def messages(self, connections: Collection[Any], start: int | None = None,
                 stop: int | None = None) -> Generator[tuple[Any, int, bytes], None, None]:
        """(connection, log time ns, serialized message) in log-time order, one chunk (or the few that overlap
        in time) in memory at a time; a chunk that cannot be read goes to `problems` and is skipped."""
        wanted = {c.id: c for c in connections}
        loose = [m for m in self._loose if m[2] in wanted]
        for log_time, _, cid, data in ordered_messages(self._file, self._chunks, set(wanted), True, start, stop,
                                                       on_damage=lambda _, why: self.problems.append(why),
                                                       loose=loose):
            yield wanted[cid], log_time, data


def inflate_message(data: bytes) -> tuple[bytes | None, str]:
    """(the message, "") of a zstd-compressed message (a bag of compression mode "message"), or (None, why not):
    inflated to at most `MAX_CHUNK_BYTES`, whatever its frame declares."""
    try:
        with zstandard.ZstdDecompressor().stream_reader(data) as reader:
            out = reader.read(MAX_CHUNK_BYTES + 1)
    except zstandard.ZstdError as exc:
        return None, f"its zstd data does not decompress ({exc})"
    if len(out) > MAX_CHUNK_BYTES:
        return None, f"its zstd data inflates past the {mib(MAX_CHUNK_BYTES)} limit: skipped"
    return out, ""


def check_file_compression(folder: Path) -> None:
    """FormatError (one line) when a bag folder of compression mode "file" holds a storage file that inflates past
    `MAX_CHUNK_BYTES`: rosbags inflates such files whole onto disk before reading them. Counted here first, in a
    bounded stream that keeps nothing; a metadata file that does not parse is left to rosbags to refuse."""
    try:
        from ruamel.yaml import YAML
        info = YAML(typ="safe").load((folder / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        if str(info.get("compression_mode", "")).lower() != "file":
            return
        names = [Path(str(x)).name for x in info["relative_file_paths"]]
    except Exception:  # noqa: BLE001 - rosbags reads the metadata next and says what is wrong with it
        return
    for name in names:
        try:
            with (folder / name).open("rb") as fh, zstandard.ZstdDecompressor().stream_reader(fh) as reader:
                total = 0
                while piece := reader.read(1 << 20):
                    total += len(piece)
                    if total > MAX_CHUNK_BYTES:
                        raise FormatError(f"{name} (compression mode file) inflates past the "
                                          f"{mib(MAX_CHUNK_BYTES)} limit; decompress it first (zstd -d)")
        except (OSError, zstandard.ZstdError) as exc:
            raise FormatError(f"{name} (compression mode file) does not decompress ({exc})") from None


def bounded_reader(path: Path) -> Any:
    """rosbags' ROS 2 reader of a bag folder or a storage file, with `BoundedMcapStorage` for MCAP storage; a bag
    compressed per file is checked to inflate within the cap first, one compressed per message is inflated by the
    bag reader (`inflate_message`, when `message_compressed` is set), not by rosbags."""
    from rosbags.rosbag2 import Reader
    from rosbags.rosbag2.reader import DirectoryReader

    class _Directory(DirectoryReader):
        STORAGE_PLUGINS = {**DirectoryReader.STORAGE_PLUGINS, "mcap": BoundedMcapStorage}
        message_compressed = False

        def open(self) -> None:
            check_file_compression(Path(str(self.path)))
            super().open()
            if self.metadata.compression_mode == "message":   # rosbags' own inflation has no bound
                self.message_compressed = True
                self.metadata = self.metadata._replace(compression_mode=None)

    class _Reader(Reader):
        STORAGE_PLUGINS = {**Reader.STORAGE_PLUGINS, "dir": _Directory, ".mcap": BoundedMcapStorage}

    return _Reader(path)


def storage_problems(reader: Any) -> list[list[str]]:
    """The `problems` lists of a bounded reader's MCAP storages (drained by the caller as it reads)."""
    storage = getattr(reader, "storage", None)
    storages = getattr(storage, "storages", None) or [storage]
    return [s.problems for s in storages if isinstance(s, BoundedMcapStorage)]
