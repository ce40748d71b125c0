"""udp://HOST:PORT: listen for datagrams (every datagram's bytes, in arrival order)."""

from __future__ import annotations

import socket

from .base import READ_SIZE, SocketSource

# datagrams drained per read: one archive message for a burst, without starving the other sources. A turn of
# the capture loop may decode for ~0.2 s (DECODE_TURN_S plus a slice): at 7 MB/s that is ~1.4 MB of datagrams,
# which one read must take, or the socket's buffer overflows and the kernel drops the rest
MAX_DATAGRAMS = 2048


class UdpSource(SocketSource):
    """A bound UDP socket; a read is every datagram waiting, concatenated."""


    def open(self) -> None:
        """Bind the port (raises OSError when it is taken)."""
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)  # rides out a busy moment
            sock.bind(self.address)
        except OSError:
            sock.close()
            raise
        sock.setblocking(False)
        self._sock = sock

    def read(self) -> bytes:
        """Every waiting datagram, concatenated (UDP never ends: no SourceClosed)."""
        assert self._sock is not None
        parts = []
        for _ in range(MAX_DATAGRAMS):
            try:
                parts.append(self._sock.recv(READ_SIZE))
            except (BlockingIOError, InterruptedError):
                break
        return b"".join(parts)
