"""tcp-listen://HOST:PORT: a TCP server loggers connect to (a logger pushing its stream), many at once.

Every client is accepted at once and waited on by the capture loop beside
the others: one that connects and stalls never holds back the bytes of
another, and a burst of clients all reach the archive. Each client is a peer
of its own (`Source.read_from`), so a text line is never spliced from two
senders.
"""

from __future__ import annotations

import errno
import socket
from collections.abc import Iterator

from .base import DRAIN_READS, PeerClosed, Source, SourceClosed, host_port
from .tcp import read_stream

BACKLOG = 512           # connections the kernel holds until the loop accepts them
ACCEPT_PER_READ = 256   # accepted per readiness of the listener: a flood cannot starve the clients' reads
MAX_CLIENTS = 1024      # more at once are refused (closed at once), so that descriptors do not run out


class TcpListenSource(Source):
    """Listens; every connected client's bytes are read as they come, each client a peer of its own."""

    def __init__(self, url: str):
        super().__init__(url)
        self.address = host_port(url)
        self._server: socket.socket | None = None
        self._clients: dict[int, tuple[int, socket.socket]] = {}  # fd -> (peer, socket)
        self._peers = 0
        self.refused = 0

    def open(self) -> None:
        """Bind and listen (raises OSError when the port is taken)."""
        if self._server is None:
            server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            try:
                server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                server.bind(self.address)
                server.listen(BACKLOG)
            except OSError:
                server.close()
                raise
            server.setblocking(False)
            self._server = server

    def fileno(self) -> int:
        """The listener's descriptor."""
        assert self._server is not None
        return self._server.fileno()

    def descriptors(self) -> list[int]:
        """The listener's descriptor and every client's."""
        return ([self._server.fileno()] if self._server is not None else []) + list(self._clients)

    @property
    def streaming(self) -> bool:
        """True while a client is connected."""
        return bool(self._clients)

    def read(self) -> bytes:
        """Accept the clients waiting (their bytes come through `read_from`)."""
        self._accept()
        return b""

    def _accept(self) -> None:
        assert self._server is not None
        for _ in range(ACCEPT_PER_READ):
            try:
                client, _ = self._server.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:   # out of descriptors, a reset before accept: the listener goes on
                if exc.errno in (errno.EMFILE, errno.ENFILE):
                    return
                continue
            if len(self._clients) >= MAX_CLIENTS:
                client.close()
                self.refused += 1
                continue
            client.setblocking(False)
            self._peers += 1
            self._clients[client.fileno()] = (self._peers, client)

    def read_from(self, fd: int) -> tuple[int, bytes]:
        """Accept on the listener's descriptor, else the bytes of that client; PeerClosed when it hangs up."""
        entry = self._clients.get(fd)
        if entry is None:
            if self._server is not None and fd == self._server.fileno():
                self._accept()
            return 0, b""
        peer, sock = entry
        try:
            return peer, read_stream(sock)
        except SourceClosed as exc:
            del self._clients[fd]
            sock.close()
            raise PeerClosed(peer, str(exc)) from None

    def drain(self) -> Iterator[tuple[int, bytes]]:
        """At the stop: what every client still has waiting, (peer, bytes), bounded per client."""
        for fd in list(self._clients):
            for _ in range(DRAIN_READS):
                try:
                    peer, data = self.read_from(fd)
                except PeerClosed:
                    break
                if not data:
                    break
                yield peer, data

    def close(self) -> None:
        """Drop the clients; the listener stays bound so that the senders can come back."""
        for _, sock in self._clients.values():
            sock.close()
        self._clients.clear()

    def shutdown(self) -> None:
        """Close the listener too (end of capture)."""
        self.close()
        if self._server is not None:
            self._server.close()
            self._server = None
