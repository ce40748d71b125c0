"""tcp-listen://HOST:PORT: a TCP server one sender connects to (a logger pushing its stream)."""

from __future__ import annotations

import socket

from .base import Source, SourceClosed, host_port
from .tcp import read_stream


class TcpListenSource(Source):
    """Listens; while a client is connected its bytes are read, a second client waits its turn."""

    def __init__(self, url: str):
        super().__init__(url)
        self.address = host_port(url)
        self._server: socket.socket | None = None
        self._client: socket.socket | None = None

    def open(self) -> None:
        """Bind and listen (raises OSError when the port is taken)."""
        if self._server is None:
            server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            try:
                server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                server.bind(self.address)
                server.listen(1)
            except OSError:
                server.close()
                raise
            server.setblocking(False)
            self._server = server

    def fileno(self) -> int:
        """The client's descriptor when one is connected, else the listener's."""
        sock = self._client or self._server
        assert sock is not None
        return sock.fileno()

    @property
    def streaming(self) -> bool:
        """True while a client is connected."""
        return self._client is not None

    def read(self) -> bytes:
        """Accept a waiting client, or read the connected one; SourceClosed when it hangs up."""
        assert self._server is not None
        if self._client is None:
            try:
                client, _ = self._server.accept()
            except (BlockingIOError, InterruptedError):
                return b""
            client.setblocking(False)
            self._client = client
            return b""
        try:
            return read_stream(self._client)
        except SourceClosed:
            self._client.close()
            self._client = None  # the listener stays: the next connection is the same stream
            raise

    def close(self) -> None:
        """Drop the client; the listener stays bound so that the sender can come back."""
        if self._client is not None:
            self._client.close()
            self._client = None

    def shutdown(self) -> None:
        """Close the listener too (end of capture)."""
        self.close()
        if self._server is not None:
            self._server.close()
            self._server = None
