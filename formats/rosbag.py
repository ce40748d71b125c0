"""ROS 1 bags and ROS 2 bags (sqlite3 or MCAP storage) as decoded messages, through `rosbags`.

`rosbags` is pure Python and reads both generations without a ROS install.
It is imported lazily, in `read_bag`: it is a heavy optional dependency
(its type system generates code at import) that only bag trials need.

Message types come first from the definitions the bag carries (every ROS 1
bag, most ROS 2 MCAP bags, sqlite3 bags from Iron on), else from rosbags'
own store of the common ROS 1 Noetic / ROS 2 Humble types. A definition
that cannot be used, or a message that does not decode with it, is reported
per message (`BagMessage.problem`); a file rosbags cannot open at all is a
`FormatError`. rosbags raises many kinds of exceptions on damaged input
(struct errors, index errors, its own reader errors), so its calls are
guarded broadly: other labs' bags must never stop a recording with a
traceback.

A ROS 1 bag's chunks are inflated here, not by rosbags (which inflates a
chunk whole, whatever it holds, and again for each message when chunks
interleave in time): each chunk once, only when the size its header
declares is under the readers' cap (`mcap_chunks.MAX_CHUNK_BYTES`) and
never past that size. Chunks whose times overlap are merged in time order
while they fit in MERGE_BYTES together; a chunk refused, or whose data is
damaged, gives each of its indexed messages as a problem (a counted skip).
Every value of a ROS 2 database row is checked the same way: a NULL or
non-integer timestamp, or data that is not bytes, is that message's problem.
A ROS 2 bag in MCAP storage is read through our bounded MCAP reader
(`formats.rosbag_mcap`): a refused or damaged chunk is one problem row.

A ROS 2 bag folder (``metadata.yaml`` beside its storage files) is one bag
(`bag_folder`); custom types a bag does not define come from ``.msg`` /
``.idl`` files (`definitions`), and a type defined nowhere makes each of its
messages a problem that says so.
"""

from __future__ import annotations

import bz2
import contextlib
import heapq
import struct
from collections import defaultdict
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .mcap_chunks import MAX_CHUNK_BYTES, lz4_bounded, mib
from .records import FormatError, library_error
from .ros_messages import RosSchema, ros_schema
from .rosbag_mcap import bounded_reader, inflate_message, storage_problems

ROS1_MAGIC = b"#ROSBAG V2.0\n"
MCAP_MAGIC = b"\x89MCAP0\r\n"
SQLITE_MAGIC = b"SQLite format 3\x00"
# inflated chunks held at once to merge chunks whose times overlap; past it the open ones are given first
MERGE_BYTES = 2 * MAX_CHUNK_BYTES
# compressed bytes of a chunk that may inflate to MAX_CHUNK_BYTES or less (bz2 and lz4 add little to random data)
MAX_COMPRESSED = MAX_CHUNK_BYTES + (MAX_CHUNK_BYTES >> 4) + 4096
# msg_paths: definition files are small text; more or larger is a path that went wrong
MAX_DEFINITION_FILES = 10_000
MAX_DEFINITION_BYTES = 1 << 20
_U32 = struct.Struct("<I")
_TIME = struct.Struct("<II")
OP_MSGDATA, OP_CHUNK, OP_CONNECTION = 2, 5, 7
# (connection, bag time ns, serialized message or None, problem): one message as the storage gives it
RawRow = tuple[Any, int, bytes | None, str]
# a type the caller reads from the bytes itself: rosbags' MD5 of the definition it reads, by ROS version, and its
# reader (bytes, ROS 1?) -> what it read, or None for bytes it does not read (rosbags decodes those)
OwnReader = tuple[dict[int, str], Callable[[bytes, bool], Any]]


@dataclass(slots=True)  # not frozen: one per bag message, and frozen's __setattr__ path costs
class BagMessage:
    """One bag message: topic, type ("sensor_msgs/NavSatFix"), bag time, index, and the message or why not;
    with the message's bytes as the bag stores them and its type's schema (`formats.ros_messages`)."""

    topic: str
    msgtype: str
    bag_time_ns: int
    index: int                 # 0-based, in read order within its file (bag time order, chunk by chunk)
    message: Any = None        # the decoded message (rosbags dataclass), None when `problem` says why
    problem: str = ""
    data: bytes = b""          # the serialized message (ROS 1 or CDR), when `message` decoded from it
    schema: RosSchema | None = None   # its type's schema, one object per connection type, when `message` is set
    undecoded: bool = False    # a type the caller reads itself (read_bag's `own`): `message` is what its reader gave


def ros_type(msgtype: str) -> str:
    """A message type name the same for ROS 1 and ROS 2: "sensor_msgs/msg/NavSatFix" -> "sensor_msgs/NavSatFix"."""
    return msgtype.replace("/msg/", "/")


def bag_folder(path: Path) -> Path | None:
    """The ROS 2 bag folder `path` names, or None: the folder itself, its ``metadata.yaml``, or a storage file
    (``.db3``, ``.mcap``) beside a ``metadata.yaml``. A bag folder is one bag: its storage files are read as the
    metadata lists them, and a storage file alone leaves out what only the metadata says (split files, types)."""
    if path.is_dir():
        return path if (path / "metadata.yaml").is_file() else None
    if path.name == "metadata.yaml" or (path.suffix in (".db3", ".mcap") and (path.parent / "metadata.yaml").is_file()):
        return path.parent
    return None


def storage_kind(head: bytes) -> str:
    """"ros1", "mcap" or "sqlite3" from a file's first bytes; "" for none of them."""
    if head.startswith(ROS1_MAGIC):
        return "ros1"
    if head.startswith(MCAP_MAGIC):
        return "mcap"
    if head.startswith(SQLITE_MAGIC):
        return "sqlite3"
    return ""


def definitions(paths: list[Path]) -> dict[str, Any]:
    """Message definitions from ``.msg`` and ``.idl`` files (a folder: every one under it), for custom types a
    bag does not define; FormatError naming the file that cannot be used.

    A ``.msg`` file's type is named by where it lies, as in a ROS package: ``<package>/msg/<Type>.msg``.
    """
    from rosbags.typesys import get_types_from_idl, get_types_from_msg

    files: list[Path] = []
    for path in paths:
        if path.is_dir():
            files += sorted(p for p in path.rglob("*") if p.suffix in (".msg", ".idl") and p.is_file())
        elif path.suffix in (".msg", ".idl"):
            files.append(path)
        else:
            raise FormatError(f"msg_paths: {path.name} is neither a .msg nor an .idl file, nor a folder of them")
    if len(files) > MAX_DEFINITION_FILES:
        raise FormatError(f"msg_paths: more than {MAX_DEFINITION_FILES} definition files")
    types: dict[str, Any] = {}
    for path in files:
        try:
            with path.open("rb") as fh:
                text = fh.read(MAX_DEFINITION_BYTES + 1).decode("utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise FormatError(f"msg_paths: cannot read {path} ({getattr(exc, 'strerror', None) or exc})") from None
        if len(text) > MAX_DEFINITION_BYTES:
            raise FormatError(f"msg_paths: {path} is larger than {MAX_DEFINITION_BYTES >> 10} KiB, not a definition")
        if path.suffix == ".msg" and path.parent.name != "msg":
            raise FormatError(f"msg_paths: {path} must lie in its package's msg folder (<package>/msg/<Type>.msg) "
                              "to name its type")
        try:
            if path.suffix == ".msg":
                types.update(get_types_from_msg(text, f"{path.parent.parent.name}/msg/{path.stem}"))
            else:
                types.update(get_types_from_idl(text))
        except Exception as exc:  # noqa: BLE001 - rosbags' parser errors are of many kinds: one line naming the file
            raise FormatError(f"msg_paths: {path} cannot be used ({library_error(exc)})") from None
    return types


def _register(store: Any, types: dict[str, Any]) -> None:
    """Add types to a store; when some clash with ones it holds, the others one by one (a clash stays out)."""
    try:
        store.register(types)
    except Exception:  # noqa: BLE001 - a type clashing with one held: keep the held one, add the rest one by one
        for name, definition in types.items():
            # a type that fails stays unknown; its messages say so
            with contextlib.suppress(Exception):
                store.register({name: definition})


def _typestore(connections: list[Any], ros1: bool, extra: dict[str, Any]) -> tuple[Any, dict[str, str]]:
    """A type store with the bag's own definitions, then `extra` (msg_paths), then rosbags' common types;
    unusable definitions by type."""
    from rosbags.typesys import (
        Stores,
        get_types_from_idl,
        get_types_from_msg,
        get_typestore,
    )

    store = get_typestore(Stores.EMPTY)
    broken: dict[str, str] = {}
    for conn in connections:
        fmt = getattr(conn.msgdef.format, "name", "NONE")
        data = conn.msgdef.data
        if fmt == "NONE" or not data:
            continue
        try:
            if fmt == "MSG":
                types = get_types_from_msg(data, conn.msgtype)
            else:
                sep = "=" * 80 + "\n"
                types = {}
                for chunk in (data.split(sep)[1:] if data.startswith(sep + "IDL: ") else [data]):
                    types.update(get_types_from_idl(chunk.split("\n", 1)[1] if chunk.startswith("IDL: ") else chunk))
            store.register(types)
        except Exception as exc:  # noqa: BLE001 - any parse or conflict error only spoils this connection's type
            broken[conn.msgtype] = f"its message definition cannot be used ({library_error(exc)})"
    if extra:
        _register(store, {k: v for k, v in extra.items() if k not in store.fielddefs})
    if all(c.msgtype in store.fielddefs or c.msgtype in broken for c in connections):
        return store, broken  # the bag defines every type it uses: no need to build the common ones (~0.2 s)
    default = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    _register(store, {k: v for k, v in default.fielddefs.items() if k not in store.fielddefs})
    return store, broken


def _open(path: Path, kind: str) -> Any:
    from rosbags.rosbag1 import Reader as Reader1

    if kind == "ros1":
        return Reader1(path)
    if kind == "folder":
        return bounded_reader(path.parent)
    if path.suffix != {"mcap": ".mcap", "sqlite3": ".db3"}[kind]:
        raise FormatError(f"a ROS 2 {kind} bag must be named *.{'mcap' if kind == 'mcap' else 'db3'} to be read")
    return bounded_reader(path)


def read_bag(path: Path, types: dict[str, Any] | None = None,
             own: dict[str, OwnReader] | None = None, opened: OpenBag | None = None) -> Iterator[BagMessage]:
    """Every message of one bag file, in bag time order; FormatError when rosbags cannot open it.

    `path` may be a ROS 2 bag's ``metadata.yaml``: the whole bag folder is read then (its storage files,
    split or compressed, as the metadata lists them). `types` (from `definitions`) define custom types the
    bag does not. `own` names types (rosbags' names) the caller reads from the bytes itself, with rosbags' MD5
    of the definition it reads by ROS version and its reader: where the bag's definition is that one, their
    messages come `undecoded`, with what the reader gave; a message the reader does not read (None: damaged, or
    a layout it leaves to rosbags) is decoded by rosbags as any other, which decides and says why. `opened`:
    the bag as `open_bag` opened it (read, then closed, here), not opened again.
    """
    reader, kind = opened if opened is not None else _opened(path)
    try:
        yield from _messages(reader, kind == "ros1", types or {}, own or {})
    finally:
        with contextlib.suppress(Exception):  # closing a damaged bag may fail again; nothing is left to lose
            reader.close()


def bag_topics(path: Path) -> list[tuple[str, str]]:
    """(topic, type as `ros_type` gives it) of every connection of a bag, from its index or metadata alone;
    FormatError when rosbags cannot open it."""
    opened = open_bag(path)
    try:
        return opened_topics(opened)
    finally:
        close_bag(opened)


# an open rosbags reader of a bag and its storage kind ("ros1", "mcap", "sqlite3" or "folder")
OpenBag = tuple[Any, str]


def open_bag(path: Path) -> OpenBag:
    """A bag opened once for its topics (`opened_topics`) and its messages (`read_bag`'s `opened`): opening a ROS 1
    bag reads its whole index, a ROS 2 folder parses its metadata (twice, with the compression check); FormatError
    when rosbags cannot open it."""
    return _opened(path)


def opened_topics(opened: OpenBag) -> list[tuple[str, str]]:
    """`bag_topics` of an open bag."""
    return [(c.topic, ros_type(c.msgtype)) for c in opened[0].connections
            if isinstance(c.topic, str) and isinstance(c.msgtype, str)]


def close_bag(opened: OpenBag) -> None:
    """Close an open bag (a damaged one may fail to close: nothing is left to lose)."""
    with contextlib.suppress(Exception):
        opened[0].close()


def _opened(path: Path) -> tuple[Any, str]:
    """An open rosbags reader of a bag file (or of the folder of a ``metadata.yaml``), and its storage kind."""
    if path.name == "metadata.yaml":
        kind = "folder"
    else:
        try:
            with path.open("rb") as fh:
                kind = storage_kind(fh.read(16))
        except OSError as exc:
            raise FormatError(f"cannot read {path.name} ({exc.strerror or exc})") from exc
    if not kind:
        raise FormatError(f"{path.name} is not a ROS 1 bag, nor a ROS 2 bag in MCAP or sqlite3 storage")
    try:
        reader = _open(path, kind)
        reader.open()
    except FormatError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags' many ways of refusing a damaged file: one line each
        raise FormatError(f"rosbags cannot open {path.name}: {library_error(exc)}") from None
    return reader, kind


def _messages(reader: Any, ros1: bool, types: dict[str, Any], own: dict[str, OwnReader]) -> Iterator[BagMessage]:
    connections = list(reader.connections)
    store, broken = _typestore(connections, ros1, types)
    for conn in connections:   # (a type that is not text is its rows' problem: _ros2_rows says so)
        if isinstance(conn.msgtype, str) and conn.msgtype not in store.fielddefs and conn.msgtype not in broken:
            broken[conn.msgtype] = (f"no definition of {ros_type(conn.msgtype)}: the bag carries none and rosbags "
                                    "knows none (give its .msg or .idl in the log's msg_paths)")
    schemas: dict[str, RosSchema] = {}
    for conn in connections:   # a type whose definition rosbags cannot write out is its messages' problem
        if isinstance(conn.msgtype, str) and conn.msgtype not in broken and conn.msgtype not in schemas:
            try:
                schemas[conn.msgtype] = ros_schema(conn.msgtype, getattr(conn.msgdef, "data", "") or "",
                                                   getattr(conn.msgdef.format, "name", "NONE"), store, ros1)
            except Exception as exc:  # noqa: BLE001 - rosbags' type errors are of many kinds: this type only
                broken[conn.msgtype] = f"no message definition to archive it by ({library_error(exc)})"
    undecoded = {t: own[t][1] for t in schemas if t in own and _md5(store, t, ros1) == own[t][0].get(1 if ros1 else 2)}
    deserialize = store.deserialize_ros1 if ros1 else store.deserialize_cdr
    index = 0
    stream = _ros1_rows(reader) if ros1 else _ros2_rows(reader)
    # per connection (by identity: the storage gives the same object for each of its messages), what every one of
    # its messages shares: our type name, the reason none decodes ("" when they may), its type's own reader, schema
    facts: dict[int, tuple[Any, str, str, Callable[[bytes, bool], Any] | None, RosSchema | None]] = {}
    while True:
        try:
            conn, t_ns, raw, problem = next(stream)
        except StopIteration:
            return
        except Exception as exc:  # noqa: BLE001 - a damaged chunk ends what can be read of the file
            yield BagMessage("", "", 0, index, None, f"the rest of the bag cannot be read ({library_error(exc)})")
            return
        if conn is None:
            yield BagMessage("", "", t_ns, index, None, problem or "a message of no connection the bag defines")
            index += 1
            continue
        known = facts.get(id(conn))
        if known is None or known[0] is not conn:
            known = facts[id(conn)] = _facts(conn, ros1, broken, undecoded, schemas)
        _, msgtype, refused, read_own, schema = known
        problem = problem or refused
        if not problem:
            data = raw if raw is not None else b""   # (a row without a problem carries its bytes)
            if read_own is not None:
                read = read_own(data, ros1)
                if read is not None:
                    yield BagMessage(conn.topic, msgtype, t_ns, index, read, "", data, schema, True)
                    index += 1
                    continue
            try:
                message = deserialize(data, conn.msgtype)
            except Exception as exc:  # noqa: BLE001 - unknown type, short or garbled payload: this message only
                problem = f"does not decode as {msgtype} ({library_error(exc)})"
            else:
                yield BagMessage(conn.topic, msgtype, t_ns, index, message, "", data, schema)
                index += 1
                continue
        yield BagMessage(conn.topic, msgtype, t_ns, index, None, problem)
        index += 1


def _facts(conn: Any, ros1: bool, broken: dict[str, str], undecoded: dict[str, Callable[[bytes, bool], Any]],
           schemas: dict[str, RosSchema]) -> tuple[Any, str, str, Callable[[bytes, bool], Any] | None,
                                                   RosSchema | None]:
    """(conn, our type name, why none of its messages decodes or "", its type's own reader, its schema) of a
    connection whose topic and type are text."""
    refused = broken.get(conn.msgtype, "")
    fmt = getattr(conn.ext, "serialization_format", "cdr")
    if not refused and not ros1 and fmt != "cdr":
        refused = f"serialization {fmt!r} is not CDR"
    read_own = undecoded.get(conn.msgtype) if fmt == "cdr" else None
    return conn, ros_type(conn.msgtype), refused, read_own, schemas.get(conn.msgtype)


def _md5(store: Any, msgtype: str, ros1: bool) -> str:
    """rosbags' MD5 of a type's definition as the store holds it ("" when it cannot write one)."""
    try:
        return str(store.generate_msgdef(msgtype, ros_version=1 if ros1 else 2)[1])
    except Exception:  # noqa: BLE001 - such a type is decoded by rosbags, which says what is wrong
        return ""


def _ros2_rows(reader: Any) -> Iterator[RawRow]:
    """A ROS 2 bag's rows, each value checked (a database row may hold anything: a NULL, text, a float); each MCAP
    chunk the bounded storage refused or found damaged as one row of its own (its messages are not read)."""
    problems = storage_problems(reader)
    if not problems:   # sqlite3 storage: the rows alone
        return _ros2_checked(reader)
    return _with_storage_rows(_ros2_checked(reader), problems)


def _with_storage_rows(rows: Iterator[RawRow], problems: list[list[str]]) -> Iterator[RawRow]:
    for row in rows:
        yield from _storage_rows(problems)
        yield row
    yield from _storage_rows(problems)


def _storage_rows(problems: list[list[str]]) -> Iterator[RawRow]:
    for found in problems:
        while found:
            yield None, 0, None, f"MCAP storage, {found.pop(0)}"


def _ros2_checked(reader: Any) -> Iterator[RawRow]:
    compressed = getattr(getattr(reader, "storage", None), "message_compressed", False)
    text: dict[int, tuple[Any, bool]] = {}   # per connection (by identity): whether its topic and type are text
    for conn, t_ns, raw in reader.messages():
        known = text.get(id(conn))
        if known is None or known[0] is not conn:
            known = text[id(conn)] = (conn, isinstance(conn.topic, str) and isinstance(conn.msgtype, str))
        if not known[1]:   # the topics table's row
            yield None, 0, None, f"topic {conn.topic!r} of type {conn.msgtype!r}: not text"
            continue
        if type(t_ns) is not int or not 0 <= t_ns < 1 << 63:
            yield conn, 0, None, f"timestamp {t_ns!r} is not a time in ns"
        elif type(raw) is not bytes and not isinstance(raw, (bytes, bytearray, memoryview)):
            yield conn, t_ns, None, f"data {type(raw).__name__} is not bytes"
        elif compressed:   # compression mode "message": each message inflated here, bounded
            data, problem = inflate_message(bytes(raw))
            yield conn, t_ns, data if not problem else None, problem
        else:
            yield conn, t_ns, raw if type(raw) is bytes else bytes(raw), ""


def _ros1_rows(reader: Any) -> Iterator[RawRow]:
    """A ROS 1 bag's messages, each chunk inflated once and bounded; overlapping chunks merged in time."""
    connmap = {c.id: c for c in reader.connections}
    by_chunk: dict[int, list[tuple[int, int, int]]] = defaultdict(list)  # chunk pos -> (time, offset, conn)
    for cid, entries in reader.indexes.items():
        for e in entries:
            by_chunk[e.chunk_pos].append((e.time, e.offset, cid))
    chunks = sorted(reader.chunk_infos, key=lambda ci: (ci.start_time, ci.pos))
    # (time, chunk order, index in chunk, entries, inflated data) of every chunk open for the merge
    heap: list[tuple[int, int, int, list[tuple[int, int, int]], bytes]] = []
    held = 0
    for order, info in enumerate(chunks):
        entries = sorted(by_chunk.get(info.pos, ()))
        if not entries:
            continue
        # every open message before this chunk's first comes first (the chunks' usual case: one open at a time)
        while heap and (heap[0][0] <= entries[0][0] or held + MAX_CHUNK_BYTES > MERGE_BYTES):
            row, freed = _next_row(heap, connmap)
            held -= freed
            yield row
        data, problem = _ros1_chunk(reader.bio, info.pos)
        if problem:
            for t, _, cid in entries:
                yield connmap.get(cid), t, None, problem
            continue
        assert data is not None
        held += len(data)
        heapq.heappush(heap, (entries[0][0], order, 0, entries, data))
    while heap:
        row, _ = _next_row(heap, connmap)
        yield row


def _next_row(heap: list[tuple[int, int, int, list[tuple[int, int, int]], bytes]],
              connmap: dict[int, Any]) -> tuple[RawRow, int]:
    """The earliest open message, and the bytes freed when its chunk has no more."""
    _, order, i, entries, data = heap[0]
    t, offset, cid = entries[i]
    if i + 1 < len(entries):
        heapq.heapreplace(heap, (entries[i + 1][0], order, i + 1, entries, data))
        freed = 0
    else:
        heapq.heappop(heap)
        freed = len(data)
    raw, problem = _ros1_record(data, offset)
    return (connmap.get(cid), t, raw, problem), freed


def _ros1_chunk(bio: Any, pos: int) -> tuple[bytes | None, str]:
    """(inflated records, "") of the chunk record at `pos`, or (None, why not): over the cap, or damaged."""
    from rosbags.rosbag1.reader import Header, RecordType, read_uint32

    where = f"chunk at byte {pos}"
    try:
        bio.seek(pos)
        header = Header.read(bio, RecordType.CHUNK)
        compression = header.get_string("compression")
        size = header.get_uint32("size")
        datasize = read_uint32(bio)
    except Exception as exc:  # noqa: BLE001 - rosbags' ways of refusing a damaged header: this chunk only
        return None, f"{where}: unreadable header ({library_error(exc)})"
    if size > MAX_CHUNK_BYTES or datasize > MAX_COMPRESSED:
        return None, f"{where} declares {mib(max(size, datasize))}, over the {mib(MAX_CHUNK_BYTES)} limit: skipped"
    body = bio.read(datasize)
    if len(body) != datasize:
        return None, f"{where}: the file ends inside it"
    try:
        data = _inflate(compression, body, size)
    except (ValueError, OSError, RuntimeError, EOFError) as exc:
        return None, f"{where}: {compression} data {exc}"
    if len(data) != size:
        return None, f"{where}: {compression} data inflates to {mib(len(data))}, not the {mib(size)} declared"
    return data, ""


def _inflate(compression: str, body: bytes, size: int) -> bytes:
    """At most `size` bytes out of a chunk's data; ValueError when it holds more, or is no such data."""
    if compression == "none":
        return body
    if compression == "bz2":   # one stream or several in a row (bz2.decompress reads them all, so do we)
        parts, left, rest = [], size, body
        while rest:
            bz = bz2.BZ2Decompressor()
            parts.append(bz.decompress(rest, max_length=left))
            left -= len(parts[-1])
            if not bz.eof and not bz.needs_input and bz.decompress(b"", max_length=1):
                raise ValueError(f"inflates past the {mib(size)} declared")
            if not bz.eof:
                raise ValueError("ends inside a bz2 stream")
            rest = bz.unused_data
        return b"".join(parts)
    if compression == "lz4":
        return lz4_bounded(body, size)
    raise ValueError(f"compression {compression!r} is not supported")


def _ros1_record(data: bytes, offset: int) -> tuple[bytes | None, str]:
    """(message bytes, "") of the message data record at `offset` of a chunk (connection records skipped)."""
    pos = offset
    try:
        while True:
            (hlen,) = _U32.unpack_from(data, pos)
            op = _header_op(data, pos + 4, pos + 4 + hlen)
            pos += 4 + hlen
            (dlen,) = _U32.unpack_from(data, pos)
            pos += 4
            if pos + dlen > len(data):
                return None, f"a record of {dlen} bytes overruns its chunk"
            if op == bytes([OP_MSGDATA]):
                return data[pos:pos + dlen], ""
            if op != bytes([OP_CONNECTION]):
                return None, "the bag's index points at no message"
            pos += dlen
    except (struct.error, ValueError) as exc:
        return None, f"damaged record in its chunk ({exc})"


def _header_op(data: bytes, start: int, end: int) -> bytes:
    """The op field of a ROS 1 record header (b"" without one), every field checked to lie inside it and hold a
    '='; ValueError when one does not. Only op is read: it is all a message's record needs, once per message."""
    if end > len(data):
        raise ValueError("a record header overruns its chunk")
    op, pos = b"", start
    while pos < end:
        (n,) = _U32.unpack_from(data, pos)
        pos += 4
        if pos + n > end:
            raise ValueError("a header field overruns its header")
        if data.startswith(b"op=", pos, pos + n):
            op = data[pos + 3:pos + n]
        elif data.find(b"=", pos, pos + n) < 0:
            raise ValueError("a header field without '='")
        pos += n
    return op
