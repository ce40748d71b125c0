"""MAVLink telemetry logs (`.tlog`) and ArduPilot dataflash logs (`.BIN`) as messages, through `pymavlink`.

`pymavlink` is imported lazily, in `read_mavlink`: it is a heavy optional
dependency (it builds its dialect modules at import) that only ArduSub
trials need. A tlog is a stream of (big-endian u64 Unix microseconds,
MAVLink packet); a dataflash log describes its own messages with FMT
records. pymavlink reads both from a path. Bytes it cannot frame come back
as BAD_DATA runs: each run is one `MavMessage` with its `problem`; a packet
whose CRC fails is one `MavMessage` of its own, `bad_crc` set. Every message
carries the byte offset in the file where its record starts. Its
readers raise on some damaged inputs, so they are guarded broadly (other
people's logs must not stop a recording with a traceback). pymavlink prints its complaints about
damaged records ("bad header 0x..."): they are kept off our output, since each such record is
counted and reported here instead.
"""

from __future__ import annotations

import contextlib
import functools
import io
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .records import FormatError, library_error

DATAFLASH_MAGIC = b"\xa3\x95"


@dataclass(frozen=True, slots=True)
class MavMessage:
    """One message: type ("GPS_RAW_INT", or a dataflash name like "GPS"), time (ns), fields, 0-based index,
    byte offset of its record in the file."""

    type: str
    time_ns: int
    index: int
    fields: dict[str, Any] = field(default_factory=dict)
    problem: str = ""        # set for BAD_DATA runs, packets failing their CRC and an unreadable rest of file
    offset: int = 0
    bad_crc: bool = False


def is_dataflash(head: bytes) -> bool:
    """Whether a file's first bytes are an ArduPilot dataflash log's (a FMT record header)."""
    return head.startswith(DATAFLASH_MAGIC)


def read_mavlink(path: Path) -> Iterator[MavMessage]:
    """Every message of a tlog or dataflash log in file order; FormatError when it cannot be opened at all."""
    try:
        with path.open("rb") as fh:
            head = fh.read(4)
    except OSError as exc:
        raise FormatError(f"cannot read {path.name} ({exc.strerror or exc})") from exc
    try:
        from pymavlink import mavutil

        with _quiet():
            conn = _connect(path, head, mavutil)
    except FormatError:
        raise
    except Exception as exc:  # noqa: BLE001 - pymavlink's many ways of refusing a file: one line
        raise FormatError(f"pymavlink cannot open {path.name}: {library_error(exc)}") from None
    yield from _read(conn)


class _Discard(io.TextIOBase):
    """A text sink for pymavlink's prints."""

    def write(self, text: str) -> int:
        """Discard `text`."""
        return len(text)


_DISCARD = _Discard()


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """pymavlink's prints (to stdout and stderr) discarded."""
    with contextlib.redirect_stdout(_DISCARD), contextlib.redirect_stderr(_DISCARD):
        yield


def _connect(path: Path, head: bytes, mavutil: Any) -> Any:
    if is_dataflash(head):
        from pymavlink import DFReader

        # pymavlink's C indexer prints a line per damaged byte straight to the process's stderr, where no
        # redirection of sys.stderr reaches: its Python indexer (same records) prints through sys.stderr
        before = os.environ.get("PYMAVLINK_FAST_INDEX")
        os.environ["PYMAVLINK_FAST_INDEX"] = "0"
        try:
            return _checked_dataflash(DFReader.DFReader_binary)(str(path), zero_time_base=False)
        finally:
            if before is None:
                del os.environ["PYMAVLINK_FAST_INDEX"]
            else:
                os.environ["PYMAVLINK_FAST_INDEX"] = before
    # the log reader itself, not mavlink_connection: that one picks a reader by the name ("tcp:...", "*.bin")
    mavutil.set_dialect("ardupilotmega")
    return mavutil.mavlogfile(str(path), notimestamps=False)


class _Formats(dict):
    """A dataflash reader's table of formats (type -> DFFormat) that refuses a FMT record declaring a record
    shorter than its own 3-byte header: pymavlink's indexer steps on by that length, and never ends on 0."""

    def __setitem__(self, key: Any, value: Any) -> None:
        length = getattr(value, "len", 3)
        if not isinstance(length, int) or length < 3:
            raise FormatError(f"a FMT record declares {getattr(value, 'name', '?')!r} (type {key}) "
                              f"{length!r} bytes long, less than a record's 3-byte header")
        super().__setitem__(key, value)


@functools.cache
def _checked_dataflash(reader: type) -> type:
    """pymavlink's DFReader_binary whose table of formats is a `_Formats`."""

    class Checked(reader):
        @property
        def formats(self) -> _Formats:
            return self._checked_formats

        @formats.setter
        def formats(self, table: dict) -> None:
            self._checked_formats = table if isinstance(table, _Formats) else _Formats(table)

    return Checked


def _position(conn: Any) -> int:
    """The reader's byte offset in its file: where its next record starts."""
    try:
        return int(conn.offset) if hasattr(conn, "offset") else int(conn.f.tell())  # dataflash, tlog
    except (AttributeError, OSError, TypeError, ValueError):
        return 0


def _read(conn: Any) -> Iterator[MavMessage]:
    """The messages of an open pymavlink reader, runs of unframed bytes joined, dataflash FMT records included."""
    index = 0
    bad: list[int] = []  # a run of BAD_DATA: bytes, time, offset
    while True:
        at = _position(conn)
        try:
            with _quiet():
                msg = conn.recv_match()
        except Exception as exc:  # noqa: BLE001 - a damaged record stops what can be read of the file
            yield MavMessage("", 0, index, {}, f"the rest of the log cannot be read ({library_error(exc)})",
                             at)
            return
        if msg is None:
            break
        kind = msg.get_type()
        t_ns = round(float(getattr(msg, "_timestamp", 0.0) or 0.0) * 1e6) * 1000
        reason = str(getattr(msg, "reason", "") or "")
        if kind == "BAD_DATA" and "CRC" not in reason:
            data = getattr(msg, "data", b"")
            if not bad:
                bad = [0, t_ns, at]
            bad[0] += len(data) if data else 1
            continue
        if bad:
            yield MavMessage("BAD_DATA", bad[1], index, {}, f"{bad[0]} bytes that are no MAVLink packet (BAD_DATA)",
                             bad[2])
            index += 1
            bad = []
        if kind == "BAD_DATA":  # a whole packet whose CRC fails: pymavlink's "invalid MAVLink CRC in msgID ..."
            yield MavMessage("BAD_DATA", t_ns, index, {}, f"bad crc at byte {at}: {reason}", at, bad_crc=True)
            index += 1
            continue
        try:
            fields = msg.to_dict()
        except Exception as exc:  # noqa: BLE001 - a record whose fields do not unpack
            yield MavMessage(kind, t_ns, index, {}, f"{kind} fields cannot be read ({type(exc).__name__})", at)
            index += 1
            continue
        fields.pop("mavpackettype", None)  # the type, which the topic names
        yield MavMessage(kind, t_ns, index, fields, "", at)
        index += 1
    if bad:
        yield MavMessage("BAD_DATA", bad[1], index, {}, f"{bad[0]} bytes that are no MAVLink packet (BAD_DATA)",
                         bad[2])
