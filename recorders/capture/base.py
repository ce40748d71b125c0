"""What every live source offers the capture loop: open, a file descriptor to wait on, read, close."""

from __future__ import annotations

import socket
from abc import ABC, abstractmethod
from collections.abc import Iterator
from urllib.parse import urlsplit


class SourceClosed(Exception):
    """The peer or device went away: the loop closes the source and opens it again later."""


class PeerClosed(Exception):
    """One of a listener's clients hung up: its connection ends, the source and its other clients go on."""

    def __init__(self, peer: int, why: str):
        super().__init__(why)
        self.peer = peer


class SourceError(ValueError):
    """A source address that cannot be used, with a message naming the problem."""


READ_SIZE = 1 << 16
DRAIN_READS = 256  # at most this many reads of what a socket still holds at the stop (16 MiB)


class Source(ABC):
    """One live stream of bytes; `read` never blocks (the loop waits on `fileno`, or polls)."""

    #: False for sources the loop polls (a growing file is always "readable")
    selectable = True

    def __init__(self, url: str):
        self.url = url

    @abstractmethod
    def open(self) -> None:
        """Open, bind or connect; raises OSError when it cannot (the loop retries)."""

    @abstractmethod
    def fileno(self) -> int:
        """The descriptor to wait on while open."""

    @abstractmethod
    def read(self) -> bytes:
        """The bytes available now (b"" if none); raises SourceClosed when the stream ended."""

    @abstractmethod
    def close(self) -> None:
        """Release the descriptor; `open` may be called again."""

    def descriptors(self) -> list[int]:
        """Every descriptor to wait on while open (a listener's own and each client's)."""
        return [self.fileno()]

    def read_from(self, fd: int) -> tuple[int, bytes]:
        """(peer, bytes) waiting on descriptor `fd`; peer 0 is the source's one stream.

        A listener names each client by its own peer number, so that one
        stalled client never holds back the bytes of the others; its hang-up
        is PeerClosed.
        """
        return 0, self.read()

    def drain(self) -> Iterator[tuple[int, bytes]]:
        """At the stop: (peer, bytes) still waiting, bounded, so that nothing sent before the stop is missing."""
        for _ in range(DRAIN_READS):
            try:
                data = self.read()
            except (SourceClosed, OSError):
                return
            if not data:
                return
            yield 0, data

    def shutdown(self) -> None:
        """Release everything at the end of the capture (a listener its port too)."""
        self.close()

    @property
    def streaming(self) -> bool:
        """True when bytes can arrive (a listener without a client is open but not streaming)."""
        return True


class SocketSource(Source):
    """A source on one socket of our own (UDP bound, TCP connected): its descriptor and its closing."""

    def __init__(self, url: str):
        super().__init__(url)
        self.address = host_port(url)
        self._sock: socket.socket | None = None

    def fileno(self) -> int:
        """The socket's descriptor."""
        assert self._sock is not None
        return self._sock.fileno()

    def close(self) -> None:
        """Unbind or disconnect; `open` may be called again."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None


def host_port(url: str) -> tuple[str, int]:
    """(host, port) of scheme://HOST:PORT, a SourceError when either is missing or bad."""
    parts = urlsplit(url)
    try:
        port = parts.port
    except ValueError:
        port = None
    if not parts.hostname or port is None:
        raise SourceError(f"{url}: expected {parts.scheme}://HOST:PORT")
    return parts.hostname, port
