"""tail:PATH: a file another logger is still writing, read from its start as it grows (or a named pipe).

The file is opened without blocking: a FIFO with no writer yet would hold a
plain `open()` forever, deaf to --duration and to signals. A FIFO opened so
reads nothing until a writer comes, and is never taken for a truncated file.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator

from .base import Source, SourceClosed, SourceError

# a read of a growing file: large, so that the poll keeps up with a fast writer (the loop reads several per turn)
TAIL_READ = 1 << 20


class TailSource(Source):
    """Polled (a regular file is always readable); a replaced or truncated file is read again from its start."""

    selectable = False

    def __init__(self, url: str):
        super().__init__(url)
        self.path = url.partition(":")[2]
        if not self.path:
            raise SourceError(f"{url}: expected tail:PATH")
        self._fd = -1
        self._inode = -1
        self._pos = 0
        self._fifo = False

    def open(self) -> None:
        """Open the file without blocking (raises OSError while it does not exist, or when it is a folder)."""
        fd = os.open(self.path, os.O_RDONLY | os.O_NONBLOCK)
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            os.close(fd)
            raise IsADirectoryError(f"{self.path} is a folder")
        self._fd, self._inode, self._pos = fd, st.st_ino, 0
        self._fifo = stat.S_ISFIFO(st.st_mode)

    def fileno(self) -> int:
        """The file's descriptor."""
        return self._fd

    def read(self) -> bytes:
        """New bytes; SourceClosed when the file was rotated, truncated or removed."""
        try:
            data = os.read(self._fd, TAIL_READ)
        except BlockingIOError:
            return b""   # a pipe whose writer has nothing for us now
        except OSError as exc:
            raise SourceClosed(f"{self.path}: {exc.strerror or exc}") from exc
        if data:
            self._pos += len(data)
            return data
        if self._fifo:
            return b""   # no writer (yet, or any more): one may come
        try:
            st = os.stat(self.path)
        except OSError as exc:
            raise SourceClosed(f"{self.path} is gone") from exc
        if st.st_ino != self._inode or st.st_size < self._pos:
            raise SourceClosed(f"{self.path} was replaced or truncated")
        return b""

    def drain(self) -> Iterator[tuple[int, bytes]]:
        """Everything written to the file before the stop (up to its size now, not a writer's later bytes)."""
        if self._fifo:
            yield from super().drain()
            return
        try:
            size = os.fstat(self._fd).st_size
        except OSError:
            return
        while self._pos < size:
            try:
                data = self.read()
            except SourceClosed:
                return
            if not data:
                return
            yield 0, data

    def close(self) -> None:
        """Close the file."""
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1
