"""Playing a recorded trial's logs out as live streams (`auvreplay feed`): for tests, demos and dry runs.

Each log goes to its own target (a UDP port, a TCP connection or listener,
or a pseudo-terminal) at real time times `rate`. A log is cut into
segments at its records' byte offsets, as its converter reports them, and
each segment is sent at its record's time: the bytes on the wire are the
file's bytes, in order, none added. A target that cannot take a segment
now (a full pty, a slow TCP reader, no client yet) keeps it and sends it
when it can, so a stream is never reordered or cut.
"""

from __future__ import annotations

import heapq
import os
import pty
import re
import socket
import time
import tty
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from urllib.parse import urlsplit

from .base import Output
from .manifest import LogSpec, Manifest, ManifestError
from .record import check_formats, log_context
from .registry import converters

MAX_DATAGRAM = 60000  # under the UDP limit of 65507 bytes


class FeedError(ValueError):
    """A target that cannot be used, with a message naming the problem."""


def segments(manifest: Manifest, log: LogSpec, data: bytes, table: dict) -> list[tuple[int, int, int]]:
    """(time ns, start, end) byte ranges of one log, cut at its records; times never go backwards.

    A log without a timed record is one segment at time -1: it goes out when the trial starts.
    """
    starts: list[tuple[int, int]] = []
    for item in table[(log.sensor, log.format)](data, log_context(manifest, log)):
        if type(item) is Output and item.where is not None:
            starts.append((item.where.offset, item.log_time_ns))
    if not starts:
        return [(-1, 0, len(data))] if data else []
    starts.sort()
    out = []
    t_max = starts[0][1]
    bounds = [0] + [s for s, _ in starts[1:]] + [len(data)]
    times = [t for _, t in starts]
    for i, t in enumerate(times):
        t_max = max(t_max, t)
        if bounds[i + 1] > bounds[i]:
            out.append((t_max, bounds[i], bounds[i + 1]))
    return out


class Target:
    """Where one log goes; `send` never blocks: what cannot go now waits for `pump`."""

    source = ""  # the address `capture` reads it from

    def __init__(self) -> None:
        self._pending = bytearray()

    def send(self, data: bytes) -> None:
        """Queue bytes and send what can go now."""
        self._pending += data
        self.pump()

    def pump(self) -> None:
        """Send what waits, as far as the target takes it."""
        while self._pending:
            n = self._write(bytes(self._pending[:MAX_DATAGRAM]))
            if n <= 0:
                return
            del self._pending[:n]

    @property
    def waiting(self) -> int:
        """Bytes not sent yet."""
        return len(self._pending)

    def _write(self, data: bytes) -> int:
        raise NotImplementedError

    def close(self) -> None:
        """Release the target."""


class UdpTarget(Target):
    """Datagrams to HOST:PORT, each at most MAX_DATAGRAM bytes, cut at line ends where possible."""

    def __init__(self, host: str, port: int):
        super().__init__()
        self.address = (host, port)
        self.source = f"udp://{host}:{port}"
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def pump(self) -> None:
        """Every waiting byte goes (a datagram nobody reads is lost, as on a real network)."""
        while self._pending:
            piece = bytes(self._pending[:MAX_DATAGRAM])
            if len(piece) == MAX_DATAGRAM and b"\n" in piece:
                piece = piece[:piece.rfind(b"\n") + 1]
            try:
                self._sock.sendto(piece, self.address)
            except BlockingIOError:
                return
            except OSError:  # nobody listening (ICMP refused): dropped, as UDP does
                pass
            del self._pending[:len(piece)]

    def close(self) -> None:
        """Close the socket."""
        self._sock.close()


class TcpListenTarget(Target):
    """A listener the capture connects to (its source tcp://); bytes wait until a client is there."""

    def __init__(self, host: str, port: int):
        super().__init__()
        self.source = f"tcp://{host}:{port}"
        self._server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._server.bind((host, port))
        self._server.listen(1)
        self._server.setblocking(False)
        self._client: socket.socket | None = None

    def _write(self, data: bytes) -> int:
        if self._client is None:
            try:
                self._client, _ = self._server.accept()
            except BlockingIOError:
                return 0
            self._client.setblocking(False)
        try:
            return self._client.send(data)
        except BlockingIOError:
            return 0
        except OSError:  # the reader went away: wait for it to come back
            self._client.close()
            self._client = None
            return 0

    def close(self) -> None:
        """Close the client and the listener."""
        if self._client is not None:
            self._client.close()
        self._server.close()


class TcpConnectTarget(Target):
    """A connection to the capture's listener (its source tcp-listen://), made again when it drops."""

    def __init__(self, host: str, port: int):
        super().__init__()
        self.address = (host, port)
        self.source = f"tcp-listen://{host}:{port}"
        self._sock: socket.socket | None = None

    def _write(self, data: bytes) -> int:
        if self._sock is None:
            try:
                self._sock = socket.create_connection(self.address, timeout=0.2)
            except OSError:
                return 0
            self._sock.setblocking(False)
        try:
            return self._sock.send(data)
        except BlockingIOError:
            return 0
        except OSError:
            self._sock.close()
            self._sock = None
            return 0

    def close(self) -> None:
        """Close the connection."""
        if self._sock is not None:
            self._sock.close()


class PtyTarget(Target):
    """A pseudo-terminal in raw mode; the capture opens its device (source serial://) as a serial port."""

    def __init__(self) -> None:
        super().__init__()
        self._master, self._slave = pty.openpty()
        tty.setraw(self._slave)  # no echo, no line editing, no CR/LF translation: the bytes as they are
        os.set_blocking(self._master, False)
        self.device = os.ttyname(self._slave)
        self.source = f"serial://{self.device}?baud=115200"

    def _write(self, data: bytes) -> int:
        try:
            return os.write(self._master, data)
        except BlockingIOError:
            return 0

    def close(self) -> None:
        """Close both ends."""
        os.close(self._master)
        os.close(self._slave)


def make_targets(to: str, count: int) -> list[Target]:
    """`count` targets for --to: udp://, tcp-listen:// or tcp://HOST:PORT (PORT, PORT+1, ...), or pty."""
    if to == "pty":
        return [PtyTarget() for _ in range(count)]
    parts = urlsplit(to)
    kinds: dict[str, Callable[[str, int], Target]] = {"udp": UdpTarget, "tcp-listen": TcpListenTarget,
                                                      "tcp": TcpConnectTarget}
    kind = kinds.get(parts.scheme)
    try:
        port = parts.port
    except ValueError:
        port = None
    if kind is None or not parts.hostname or port is None:
        raise FeedError(f"--to {to}: expected udp://HOST:PORT, tcp-listen://HOST:PORT, tcp://HOST:PORT or pty")
    if port + count - 1 > 65535:
        raise FeedError(f"--to {to}: {count} logs need ports {port}..{port + count - 1}")
    targets: list[Target] = []
    try:
        for i in range(count):
            targets.append(kind(parts.hostname, port + i))
    except OSError as exc:
        for t in targets:
            t.close()
        raise FeedError(f"--to {to}: {exc}") from None
    return targets


def live_manifest(manifest: Manifest, targets: list[Target]) -> str:
    """The manifest's text with each log given `source = ...` of its target (its path stays as its name)."""
    text = manifest.text
    for log, target in zip(manifest.logs(), targets):
        pattern = re.compile(r"^(\s*path\s*=\s*)([\"'])" + re.escape(log.path) + r"\2[^\n]*$", re.MULTILINE)
        line = f"\nsource = \"{target.source}\""
        text, n = pattern.subn("\\g<0>" + line.replace("\\", "\\\\"), text, count=1)
        if n != 1:
            raise ManifestError(f"{manifest.path}: cannot find the path line of log {log.path} to add its source")
    return text


@dataclass
class FeedStats:
    """What a feed sent."""

    segments: int = 0
    bytes: int = 0
    seconds: float = 0.0


def _schedule(manifest: Manifest, seconds: float | None) -> Iterator[tuple[int, int, bytes]]:
    """(time ns, log index, bytes) of every segment of every log, merged in time order."""
    table = converters()
    check_formats(manifest, table)
    per_log = []
    for i, log in enumerate(manifest.logs()):
        data = (manifest.root / log.path).read_bytes()
        per_log.append([(t, i, data[a:b]) for t, a, b in segments(manifest, log, data, table)])
    starts = [segs[0][0] for segs in per_log if segs and segs[0][0] >= 0]
    if not any(per_log):
        return
    first = min(starts, default=0)
    end = first + round(seconds * 1e9) if seconds is not None else None
    for t, i, data in heapq.merge(*per_log, key=lambda s: (s[0], s[1])):
        if end is not None and t > end:
            return
        yield max(t, first), i, data


def play(manifest: Manifest, targets: list[Target], rate: float = 1.0, seconds: float | None = None,
         should_stop: Callable[[], bool] = lambda: False, drain_s: float = 5.0) -> FeedStats:
    """Send every log to its target at real time x `rate` (the first `seconds` of the trial if given)."""
    if rate <= 0:
        raise FeedError(f"--rate must be positive, not {rate}")
    stats = FeedStats()
    begin = time.monotonic()
    t0 = None
    for t, i, data in _schedule(manifest, seconds):
        t0 = t if t0 is None else t0
        due = begin + (t - t0) / 1e9 / rate
        while not should_stop():
            wait = due - time.monotonic()
            if wait <= 0:
                break
            time.sleep(min(wait, 0.05))
            for target in targets:
                target.pump()
        if should_stop():
            break
        targets[i].send(data)
        stats.segments += 1
        stats.bytes += len(data)
    deadline = time.monotonic() + drain_s
    while any(t.waiting for t in targets) and time.monotonic() < deadline and not should_stop():
        for target in targets:
            target.pump()
        time.sleep(0.01)
    stats.seconds = time.monotonic() - begin
    return stats

