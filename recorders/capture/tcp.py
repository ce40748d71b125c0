"""tcp://HOST:PORT: connect to a sensor's (or a logger's) TCP server, reconnecting when it drops."""

from __future__ import annotations

import socket

from .base import READ_SIZE, SocketSource, SourceClosed

CONNECT_TIMEOUT_S = 0.5


def read_stream(sock: socket.socket) -> bytes:
    """What a non-blocking stream socket holds; SourceClosed at the peer's end or a reset."""
    try:
        data = sock.recv(READ_SIZE)
    except (BlockingIOError, InterruptedError):
        return b""
    except OSError as exc:
        raise SourceClosed(str(exc)) from exc
    if not data:
        raise SourceClosed("connection closed by the peer")
    return data


class TcpSource(SocketSource):
    """A TCP client; the loop calls `open` again after SourceClosed or a refused connection."""


    def open(self) -> None:
        """Connect (raises OSError when refused or unreachable)."""
        sock = socket.create_connection(self.address, timeout=CONNECT_TIMEOUT_S)
        sock.setblocking(False)
        self._sock = sock

    def read(self) -> bytes:
        """The bytes waiting; SourceClosed when the server hung up."""
        assert self._sock is not None
        return read_stream(self._sock)
