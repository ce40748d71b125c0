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
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .records import FormatError

ROS1_MAGIC = b"#ROSBAG V2.0\n"
MCAP_MAGIC = b"\x89MCAP0\r\n"
SQLITE_MAGIC = b"SQLite format 3\x00"


@dataclass(frozen=True, slots=True)
class BagMessage:
    """One bag message: topic, type ("sensor_msgs/NavSatFix"), bag time, index, and the message or why not."""

    topic: str
    msgtype: str
    bag_time_ns: int
    index: int                 # 0-based, in bag time order within its file
    message: Any = None        # the decoded message (rosbags dataclass), None when `problem` says why
    problem: str = ""


def ros_type(msgtype: str) -> str:
    """A message type name the same for ROS 1 and ROS 2: "sensor_msgs/msg/NavSatFix" -> "sensor_msgs/NavSatFix"."""
    return msgtype.replace("/msg/", "/")


def storage_kind(head: bytes) -> str:
    """"ros1", "mcap" or "sqlite3" from a file's first bytes; "" for none of them."""
    if head.startswith(ROS1_MAGIC):
        return "ros1"
    if head.startswith(MCAP_MAGIC):
        return "mcap"
    if head.startswith(SQLITE_MAGIC):
        return "sqlite3"
    return ""


def _typestore(connections: list[Any], ros1: bool) -> tuple[Any, dict[str, str]]:
    """A type store with the bag's own definitions, then rosbags' common types; unusable definitions by type."""
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
            broken[conn.msgtype] = f"its message definition cannot be used ({type(exc).__name__}: {exc})"
    if all(c.msgtype in store.fielddefs or c.msgtype in broken for c in connections):
        return store, broken  # the bag defines every type it uses: no need to build the common ones (~0.2 s)
    default = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    missing = {k: v for k, v in default.fielddefs.items() if k not in store.fielddefs}
    try:
        store.register(missing)
    except Exception:  # noqa: BLE001 - a bag type clashing with a common one: keep the bag's, add them one by one
        for name, definition in missing.items():
            # a common type that fails stays unknown; its messages say so
            with contextlib.suppress(Exception):
                store.register({name: definition})
    return store, broken


def _open(path: Path, kind: str) -> Any:
    from rosbags.rosbag1 import Reader as Reader1
    from rosbags.rosbag2 import Reader as Reader2

    if kind == "ros1":
        return Reader1(path)
    if kind == "folder":
        return Reader2(path.parent)
    if path.suffix != {"mcap": ".mcap", "sqlite3": ".db3"}[kind]:
        raise FormatError(f"a ROS 2 {kind} bag must be named *.{'mcap' if kind == 'mcap' else 'db3'} to be read")
    return Reader2(path)


def read_bag(path: Path) -> Iterator[BagMessage]:
    """Every message of one bag file, in bag time order; FormatError when rosbags cannot open it.

    `path` may be a ROS 2 bag's ``metadata.yaml``: the whole bag folder is read then (its storage files,
    split or compressed, as the metadata lists them).
    """
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
        raise FormatError(f"rosbags cannot open {path.name}: {type(exc).__name__}: {exc}") from None
    try:
        yield from _messages(reader, kind == "ros1")
    finally:
        with contextlib.suppress(Exception):  # closing a damaged bag may fail again; nothing is left to lose
            reader.close()


def _messages(reader: Any, ros1: bool) -> Iterator[BagMessage]:
    connections = list(reader.connections)
    store, broken = _typestore(connections, ros1)
    index = 0
    stream = reader.messages()
    while True:
        try:
            conn, t_ns, raw = next(stream)
        except StopIteration:
            return
        except Exception as exc:  # noqa: BLE001 - a damaged chunk ends what can be read of the file
            yield BagMessage("", "", 0, index, None, f"the rest of the bag cannot be read ({type(exc).__name__}: "
                                                     f"{exc})")
            return
        msgtype = ros_type(conn.msgtype)
        problem = broken.get(conn.msgtype, "")
        message = None
        if not problem:
            fmt = getattr(conn.ext, "serialization_format", "cdr")
            try:
                if ros1:
                    message = store.deserialize_ros1(raw, conn.msgtype)
                elif fmt == "cdr":
                    message = store.deserialize_cdr(raw, conn.msgtype)
                else:
                    problem = f"serialization {fmt!r} is not CDR"
            except Exception as exc:  # noqa: BLE001 - unknown type, short or garbled payload: this message only
                problem = f"does not decode as {msgtype} ({type(exc).__name__}: {exc})"
        yield BagMessage(conn.topic, msgtype, int(t_ns), index, message, problem)
        index += 1
